"""AttentionConfig: the attention node's settings; the controller's defaults are the core's
:class:`ServoParams` (written there only)."""

from __future__ import annotations

from pydantic import BaseModel, ConfigDict, Field, field_validator, model_validator

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


class AttentionConfig(BaseModel):
    """Everything ``perception attention`` can be told."""

    model_config = ConfigDict(extra="forbid")

    # --- whom to look at
    target: str = Field(default="none", description="at start: a track ID, 'nearest', 'lock' (the nearest person now, "
                                                    "then their ID) or 'none' (change it with "
                                                    "perception look or the attention query)")
    hold_s: float = Field(default=2.0, ge=0.0, le=600.0, description="a lost target: hold still this long, then rest (s)")
    switch_margin_m: float = Field(default=1.5, ge=0.0, description="'nearest': another person must be this much nearer")
    reacquire_radius_m: float = Field(default=0.8, ge=0.0, description="'nearest': a person this near where the one "
                                                                       "followed was last seen is taken as them")
    aim_height_m: float | None = Field(
        default=1.15, gt=0.0, le=3.0,
        description="aim at this height in the tracking frame (a standing adult's torso) instead of the track's z, which follows the "
                    "box centre and drifts when the box is clipped by the image; null: the track's z")
    # --- the control law (Ban et al., Eq 19)
    gain: float = Field(default=_S.gain, gt=0.0, le=20.0, description="1/s: the centring error decays as exp(-gain t)")
    feedforward: float = Field(default=_S.feedforward, ge=0.0, le=2.0,
                               description="weight of the target's own motion (its track velocity); 0: feedback only")
    max_pan_rate: float = Field(default=_S.max_pan_rate, gt=0.0, le=10.0, description="rad/s")
    max_tilt_rate: float = Field(default=_S.max_tilt_rate, gt=0.0, le=10.0, description="rad/s")
    dead_zone_px: float = Field(default=_S.dead_zone_px, ge=0.0, description="no correction within this of the centre")
    min_depth_m: float = Field(default=_S.min_depth_m, gt=0.0, description="nearer or behind: turn by bearing")
    pan_limits: tuple[float, float] = Field(default=_S.pan_limits, description="rad (min, max)")
    tilt_limits: tuple[float, float] = Field(default=_S.tilt_limits, description="rad (min, max), positive looks down")
    rest_pan: float = Field(default=_S.rest_pan, description="rest pose's pan (rad)")
    rest_tilt: float = Field(default=_S.rest_tilt, description="rest pose's tilt (rad)")
    rest_gain: float = Field(default=_S.rest_gain, gt=0.0, le=20.0, description="1/s towards the rest pose")
    max_predict_s: float = Field(default=0.5, ge=0.0, le=5.0,
                                 description="targets are predicted to the newest transform, at most this far (s)")
    # --- streams and frames
    camera: str = Field(default="head", min_length=1, description="the camera on the head (its frames give camera info)")
    base_frame: str = Field(default="base_link", min_length=1, description="frame whose z axis is the pan axis")
    pan_frame: str = Field(default="head_link", min_length=1, description="frame on the pan axis (its origin is on it)")
    tilt_frame: str = Field(default="head_link", min_length=1, description="frame whose y axis is the tilt axis")
    camera_frame: str = Field(default="camera", min_length=1,
                              description="the camera's optical frame when its camera info names none")
    command_rate_hz: float = Field(default=10.0, gt=0.0, le=200.0,
                                   description="commands at least this often, tracks or not (hold, rest, keep-alive)")
    command_timeout_s: float = Field(default=0.5, gt=0.0, le=10.0,
                                     description="the head stops if no newer command arrives within this (s)")
    tracks_timeout_s: float = Field(default=1.0, gt=0.0, le=60.0,
                                    description="no tracks for this long: the target counts as lost (s)")
    camera_info_period_s: float = Field(default=1.0, gt=0.0, description="how often camera info is re-read (s)")
    tf_history_s: float = Field(default=5.0, gt=0.0, le=600.0)
    tf_tolerance_s: float = Field(default=0.1, ge=0.0, le=10.0)

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
