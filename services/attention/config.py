"""AttentionConfig: the attention node's settings; the controller's defaults are the core's
:class:`ServoParams` (written there only)."""

from __future__ import annotations

from pydantic import ConfigDict, field_validator, model_validator

from common.runtime.settings import AdvancedBlock, setting

from services.attention.core import ServoParams

__all__ = ["AttentionConfig", "parse_target"]

_S = ServoParams()


def parse_target(text: str) -> tuple[str, int]:
    """``'nearest'``, ``'lock'``, ``'none'`` or a track ID as (mode, id); ValueError otherwise."""
    t = text.strip().lower()
    if t in ("nearest", "lock", "none"):
        return t, -1
    if t.isdigit():
        return "id", int(t)
    raise ValueError(f"target {text!r} must be a track ID (0, 1, ...), 'nearest', 'lock' or 'none'")


class AttentionConfig(AdvancedBlock):
    """Everything ``perception attention`` can be told."""

    model_config = ConfigDict(extra="forbid")

    # --- whom to look at
    target: str = setting("none", "at start: a track ID, 'nearest', 'lock' (the nearest person now, then their ID) or "
                          "'none' (change it with perception look or the attention query)")
    hold_s: float = setting(2.0, "a lost target: hold still this long, then rest", unit="s", ge=0.0, le=600.0)
    switch_margin_m: float = setting(1.5, "'nearest': another person must be this much nearer", unit="m", ge=0.0, advanced=True)
    reacquire_radius_m: float = setting(0.8, "'nearest': a person this near where the one followed was last seen is "
                                        "taken as them", unit="m", ge=0.0, advanced=True)
    aim_height_m: float | None = setting(1.15, "aim at this height in the tracking frame (a standing adult's torso) "
                                         "instead of the track's z, which follows the box centre and drifts when the "
                                         "box is clipped by the image; null: the track's z", unit="m", gt=0.0, le=3.0)
    # --- the control law (Ban et al., Eq 19)
    gain: float = setting(_S.gain, "the centring error decays as exp(-gain t)", unit="1/s", gt=0.0, le=20.0)
    feedforward: float = setting(_S.feedforward, "weight of the target's own motion (its track velocity); 0: feedback "
                                 "only", ge=0.0, le=2.0, advanced=True)
    max_pan_rate: float = setting(_S.max_pan_rate, "fastest pan", unit="rad/s", gt=0.0, le=10.0)
    max_tilt_rate: float = setting(_S.max_tilt_rate, "fastest tilt", unit="rad/s", gt=0.0, le=10.0)
    dead_zone_px: float = setting(_S.dead_zone_px, "no correction within this of the centre", unit="px", ge=0.0, advanced=True)
    min_depth_m: float = setting(_S.min_depth_m, "nearer or behind: turn by bearing", unit="m", gt=0.0, advanced=True)
    pan_limits: tuple[float, float] = setting(_S.pan_limits, "the pan's (min, max)", unit="rad")
    tilt_limits: tuple[float, float] = setting(_S.tilt_limits, "the tilt's (min, max); positive looks down", unit="rad")
    rest_pan: float = setting(_S.rest_pan, "the rest pose's pan", unit="rad")
    rest_tilt: float = setting(_S.rest_tilt, "the rest pose's tilt", unit="rad")
    rest_gain: float = setting(_S.rest_gain, "gain towards the rest pose", unit="1/s", gt=0.0, le=20.0, advanced=True)
    max_predict_s: float = setting(0.5, "targets are predicted to the newest transform, at most this far",
                                   unit="s", ge=0.0, le=5.0, advanced=True)
    # --- streams and frames
    camera: str = setting("head", "the camera on the head (its frames give camera info)", min_length=1)
    base_frame: str = setting("base_link", "frame whose z axis is the pan axis", min_length=1)
    pan_frame: str = setting("head_link", "frame on the pan axis (its origin is on it)", min_length=1)
    tilt_frame: str = setting("head_link", "frame whose y axis is the tilt axis", min_length=1)
    camera_frame: str = setting("camera", "the camera's optical frame when its camera info names none", min_length=1)
    command_rate_hz: float = setting(10.0, "commands at least this often, tracks or not (hold, rest, keep-alive)",
                                     unit="Hz", gt=0.0, le=200.0, advanced=True)
    command_timeout_s: float = setting(0.5, "the head stops if no newer command arrives within this",
                                       unit="s", gt=0.0, le=10.0, advanced=True)
    tracks_timeout_s: float = setting(1.0, "no tracks for this long: the target counts as lost",
                                      unit="s", gt=0.0, le=60.0, advanced=True)
    camera_info_period_s: float = setting(1.0, "how often camera info is re-read", unit="s", gt=0.0, advanced=True)
    tf_history_s: float = setting(5.0, "history kept per transform edge", unit="s", gt=0.0, le=600.0,
                                  advanced=True)
    tf_tolerance_s: float = setting(0.1, "a lookup this far outside an edge's history uses its end", unit="s",
                                    ge=0.0, le=10.0, advanced=True)

    @field_validator("target")
    @classmethod
    def _target(cls, v: str) -> str:
        parse_target(v)
        return v.strip().lower()

    @field_validator("pan_limits", "tilt_limits")
    @classmethod
    def _ordered(cls, v: tuple[float, float]) -> tuple[float, float]:
        if not v[0] < v[1]:
            raise ValueError(f"limits must be (min, max) with min < max, got {v}")
        return v

    @model_validator(mode="after")
    def _rest_within_limits(self) -> AttentionConfig:
        if not (self.pan_limits[0] <= self.rest_pan <= self.pan_limits[1]
                and self.tilt_limits[0] <= self.rest_tilt <= self.tilt_limits[1]):
            raise ValueError(f"the rest pose ({self.rest_pan}, {self.rest_tilt}) must lie within pan_limits "
                             f"{self.pan_limits} and tilt_limits {self.tilt_limits}")
        return self

    def servo_params(self) -> ServoParams:
        return ServoParams(
            gain=self.gain, feedforward=self.feedforward, max_pan_rate=self.max_pan_rate,
            max_tilt_rate=self.max_tilt_rate, dead_zone_px=self.dead_zone_px, min_depth_m=self.min_depth_m,
            pan_limits=self.pan_limits, tilt_limits=self.tilt_limits, rest_pan=self.rest_pan,
            rest_tilt=self.rest_tilt, rest_gain=self.rest_gain,
        )
