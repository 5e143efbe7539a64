"""LocalizerConfig: the localizer's settings, with the thesis's and the sensors' defaults."""

from __future__ import annotations

from pathlib import Path

from pydantic import ConfigDict, field_validator, model_validator

from common.runtime.settings import AdvancedBlock, setting

from common.messages.keys import validate_chunk
from services.localizer.core import DepthNoiseModel, FloorParams, LocalizerParams

__all__ = ["DEFAULT_FOOT_BIAS", "FootBias", "LocalizerConfig", "StaticTransformConfig"]

#: The core's defaults: every default below that the core also has is taken from here,
#: so it is written once, in the core (tests/unit/test_config_defaults.py checks they agree).
_D = LocalizerParams()
_F = FloorParams()


# --------------------------------------------------------------------------------------
# Each detector's foot bias: its boxes' mean foot error as a share of the box's height
# (+: right, down), taken off the foot point on the floor paths; a detector not named here
# has none. THE place to change them; `perception calibrate-localizer` measures yours.
#  * hog: the fitted window's top is on the head, its bottom 3.7 % of the height below the
#    feet (PETS09's 400 frames against the ground truth: 1,760 boxes, top -0.2 %, bottom median
#    +3.7 %, mean +3.8 %; every height band alike).
DEFAULT_FOOT_BIAS: dict[str, dict[str, float]] = {
    "hog": {"u": 0.0, "v": 0.037},
}
# --------------------------------------------------------------------------------------


class FootBias(AdvancedBlock):
    """A detector's mean foot error as a share of the box's height: ``u`` across (+: right),
    ``v`` down (+: the boxes reach below the feet)."""

    model_config = ConfigDict(extra="forbid")

    u: float = setting(0.0, "across, as a share of the box's height (+: right)", gt=-0.5, lt=0.5)
    v: float = setting(0.0, "down, as a share of the box's height (+: the boxes reach below the feet)", gt=-0.5,
                       lt=0.5)


def _default_foot_bias() -> dict[str, FootBias]:
    return {k: FootBias(**v) for k, v in DEFAULT_FOOT_BIAS.items()}


class StaticTransformConfig(AdvancedBlock):
    """A fixed ``parent -> child`` transform given in the config (e.g. the camera mount)."""

    model_config = ConfigDict(extra="forbid")

    parent_frame: str = setting(..., "the frame the transform is from", min_length=1)
    child_frame: str = setting(..., "the frame it places in parent_frame", min_length=1)
    translation: tuple[float, float, float]
    rotation_xyzw: tuple[float, float, float, float] = setting((0.0, 0.0, 0.0, 1.0), "the child's rotation, a "
                                                              "quaternion (x, y, z, w)")


class LocalizerConfig(AdvancedBlock):
    """Everything ``perception localizer`` can be told (file section ``localizer``)."""

    model_config = ConfigDict(extra="forbid")

    camera: str = setting("head", "camera name in the keys (frames/{camera}, detections/{camera})")
    stream: str | None = setting(None, "a second detector's stream on this camera: reads detections/{stream} and "
                                 "publishes localized/{stream} with header.source {stream}; None: the camera's name")
    target_frame: str = setting("map", "frame the positions are published in", min_length=1)
    camera_frame: str = setting("", "camera frame id used when a frame's header and camera_info carry none")
    percentile: float = setting(_D.percentile, "depth percentile inside the box (Pinto's thesis: 25)",
                                ge=0.0, le=100.0, advanced=True)
    min_depth_m: float = setting(_D.min_depth_m, "depth pixels nearer than this are invalid", unit="m", ge=0.0)
    max_depth_m: float = setting(_D.max_depth_m, "depth pixels farther than this are invalid",
                                 unit="m", gt=0.0, le=100.0)
    min_valid_pixels: int = setting(_D.min_valid_pixels, "fewer valid depth pixels in a box rejects it", ge=1, advanced=True)
    depth_unit_m: float = setting(_D.depth_unit_m, "metres per unit of integer (16UC1) depth", unit="m", gt=0.0)
    occluder_gap_m: float = setting(_D.occluder_gap_m, "a detector's own depth of a person (the depth detector's) "
                                    "replaces the box's when farther by more than this: a nearer person in the box "
                                    "filled its low percentiles", unit="m", ge=0.0, le=5.0, advanced=True)
    occluder_max_gap_m: float = setting(_D.occluder_max_gap_m, "... and by at most this: farther behind a near "
                                        "person, a box shows the room past them", unit="m", ge=0.0, le=50.0, advanced=True)
    body_half_depth_m: float = setting(_D.body_half_depth_m, "the depth camera sees the front of a body: its centre "
                                       "is this far farther along the line of sight (half a torso's depth); 0: the "
                                       "surface", unit="m", ge=0.0, le=0.5, advanced=True)
    depth_noise_a_m: float = setting(_D.noise.axial_a_m, "axial depth sigma a + b z^2: a", unit="m", ge=0.0, le=1.0, advanced=True)
    depth_noise_b_per_m: float = setting(_D.noise.axial_b_per_m, "axial depth sigma a + b z^2: b (Khoshelham and "
                                         "Elberink 2012)", unit="1/m", ge=0.0, le=1.0, advanced=True)
    pixel_sigma_px: float = setting(_D.noise.pixel_sigma_px, "sigma of the box-centre pixel",
                                    unit="px", ge=0.0, le=100.0, advanced=True)
    tf_history_s: float = setting(10.0, "history kept per transform edge", unit="s", gt=0.0, le=3600.0, advanced=True)
    tf_tolerance_s: float = setting(0.05, "a lookup this far outside an edge's history uses its end",
                                    unit="s", ge=0.0, le=10.0, advanced=True)
    transform_wait_s: float = setting(0.25, "how long detections wait for their transform before being dropped",
                                      unit="s", ge=0.0, le=10.0, advanced=True)
    frame_wait_s: float = setting(0.5, "how long detections wait for a depth frame not yet received",
                                  unit="s", ge=0.0, le=10.0, advanced=True)
    frame_buffer: int = setting(15, "recent depth frames kept for pairing", ge=1, le=600, advanced=True)
    max_pending: int = setting(64, "detections messages waiting at most", ge=1, le=10000, advanced=True)
    floor_without_depth: bool = setting(True, "a frame without a depth image (an RGB-only camera): put each person on "
                                        "the floor from the box's foot point (True), or drop the frame as "
                                        "frame_without_depth (False)")
    floor_homography: Path | None = setting(None, "a JSON file {\"H\": 3x3, \"image_size\": [w, h]} mapping a foot pixel "
                                            "(u, v, 1) to the floor (x, y, w) of floor_homography_frame (a fixed "
                                            "camera); None: the floor through the camera's pose in target_frame")
    floor_homography_frame: str = setting("", "the frame the homography's floor coordinates are in; empty: "
                                          "target_frame")
    floor_z_m: float = setting(_F.floor_z_m, "height of the floor plane in target_frame (in floor_homography_frame "
                               "with a homography)", unit="m", ge=-100.0, le=100.0)
    centre_height_m: float = setting(_F.centre_height_m, "the floor paths report the point this far above the feet: "
                                     "the body centre, as the depth path", unit="m", ge=0.0, le=3.0)
    centre_height_sigma_m: float = setting(_F.centre_height_sigma_m, "standard deviation of that height (z variance)",
                                           unit="m", gt=0.0, le=2.0, advanced=True)
    max_floor_range_m: float = setting(_F.max_floor_range_m, "feet farther than this from the camera's point on the "
                                       "floor are rejected (beyond_floor_range)", unit="m", gt=0.0, le=1000.0)
    foot_sigma_u_px: float = setting(_F.foot_sigma_u_px, "sigma of the foot point's column (box centre)",
                                     unit="px", gt=0.0, le=100.0, advanced=True)
    foot_sigma_v_px: float = setting(_F.foot_sigma_v_px, "sigma of the foot point's row (box bottom)",
                                     unit="px", gt=0.0, le=100.0, advanced=True)
    foot_sigma_share_u: float = setting(_F.foot_sigma_share_u, "and in proportion to the box: the column's sigma as a "
                                        "share of the box's height", ge=0.0, lt=1.0, advanced=True)
    foot_sigma_share_v: float = setting(_F.foot_sigma_share_v, "the row's sigma as a share of the box's height",
                                        ge=0.0, lt=1.0, advanced=True)
    foot_bias: dict[str, FootBias] = setting(description="per detector (the detections' `detector`: hog, yolo-onnx, "
                                             "...): its boxes' mean foot error as a share of the box's height, {u, "
                                             "v}, taken off the foot point (perception calibrate-localizer)",
                                             default_factory=_default_foot_bias)
    static_transforms: list[StaticTransformConfig] = setting(description="extra static transforms, e.g. the camera "
                                                             "mount", default_factory=list)

    @field_validator("camera")
    @classmethod
    def _chunk(cls, v: str) -> str:
        return validate_chunk(v, "camera")

    @field_validator("stream")
    @classmethod
    def _stream_chunk(cls, v: str | None) -> str | None:
        return None if v is None else validate_chunk(v, "stream")

    @property
    def output(self) -> str:
        """The stream it reads detections of and publishes: ``stream``, else the camera's name."""
        return self.stream or self.camera

    @model_validator(mode="after")
    def _range(self) -> LocalizerConfig:
        if not self.min_depth_m < self.max_depth_m:
            raise ValueError(f"min_depth_m ({self.min_depth_m}) must be below max_depth_m ({self.max_depth_m})")
        if not self.occluder_gap_m <= self.occluder_max_gap_m:
            raise ValueError(f"occluder_gap_m ({self.occluder_gap_m}) must not exceed occluder_max_gap_m "
                             f"({self.occluder_max_gap_m})")
        return self

    @property
    def floor_frame(self) -> str:
        """The frame the floor homography's coordinates are in."""
        return self.floor_homography_frame or self.target_frame

    def floor_params(self, detector: str = "") -> FloorParams:
        """The floor paths' parameters (frames without depth), for boxes of ``detector``."""
        bias = self.foot_bias.get(detector, FootBias())
        return FloorParams(
            floor_z_m=self.floor_z_m,
            centre_height_m=self.centre_height_m,
            centre_height_sigma_m=self.centre_height_sigma_m,
            max_floor_range_m=self.max_floor_range_m,
            foot_sigma_u_px=self.foot_sigma_u_px,
            foot_sigma_v_px=self.foot_sigma_v_px,
            foot_sigma_share_u=self.foot_sigma_share_u,
            foot_sigma_share_v=self.foot_sigma_share_v,
            foot_bias_u=bias.u,
            foot_bias_v=bias.v,
        )

    def params(self) -> LocalizerParams:
        """The core's parameters."""
        return LocalizerParams(
            percentile=self.percentile,
            min_depth_m=self.min_depth_m,
            max_depth_m=self.max_depth_m,
            min_valid_pixels=self.min_valid_pixels,
            depth_unit_m=self.depth_unit_m,
            occluder_gap_m=self.occluder_gap_m,
            occluder_max_gap_m=self.occluder_max_gap_m,
            body_half_depth_m=self.body_half_depth_m,
            noise=DepthNoiseModel(self.depth_noise_a_m, self.depth_noise_b_per_m, self.pixel_sigma_px),
        )
