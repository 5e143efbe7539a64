"""DetectorConfig: which backend, its settings, and how to build it.

Defaults: the ``hog`` backend (no model file); Basso/Munaro's values for ``depth``. Every
backend setting's default is the core's (its ``*Params`` dataclass), written there only;
each section's ``params()`` builds those params. Model paths are plain settings, nothing
is downloaded. :func:`build_detector` turns the config into a core detector and fails
with :class:`DetectorError` naming the setting to fix (missing/truncated model,
unavailable onnxruntime provider).
"""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path
from typing import Literal

from pydantic import BaseModel, ConfigDict, Field, model_validator

from common.messages.keys import validate_chunk
from services.detector.core import Detector
from services.detector.core.boxes import DetectorError
from services.detector.core.darknet import DarknetDetector, DarknetParams
from services.detector.core.depth_params import DepthParams
from services.detector.core.ground import GroundParams
from services.detector.core.hog import HogDetector, HogParams
from services.detector.core.yolo_onnx import YoloOnnxDetector, YoloParams

__all__ = ["BACKENDS", "DarknetConfig", "DepthConfig", "DetectorConfig", "HogConfig", "YoloOnnxConfig", "build_detector"]

BACKENDS = ("hog", "depth", "yolo-onnx", "darknet")
Backend = Literal["hog", "depth", "yolo-onnx", "darknet"]

# The core's defaults, read by the sections below so each is written once, in the core
# (tests/unit/test_config_defaults.py checks they agree). Model files are required in the core
# and None here until configured: the placeholders are unused. ``providers`` None is
# "not given" in both (a list here, a tuple there).
_HOG = HogParams()
_DEPTH = DepthParams()
_GROUND = _DEPTH.ground
_YOLO = YoloParams(model=Path())
_DARKNET = DarknetParams(cfg=Path(), weights=Path())


class _Section(BaseModel):
    model_config = ConfigDict(extra="forbid")


class HogConfig(_Section):
    """OpenCV HOG people detector. ``upsample`` > 1 finds people smaller than ~96 px."""

    upsample: float = Field(default=_HOG.upsample, ge=0.25, le=8.0,
                            description="image scale before HOG: about 1.1 x 96 / the smallest person's "
                                        "height in px (2.25 for ~50 px people, 1.0 from ~105 px)")
    hit_threshold: float = Field(default=_HOG.hit_threshold, ge=-2.0, le=5.0,
                                 description="minimum SVM margin of a window")
    win_stride: int = Field(default=_HOG.win_stride, ge=8, le=64, multiple_of=8)
    scale: float = Field(default=_HOG.scale, gt=1.0, le=2.0, description="pyramid step")
    nms_iou: float = Field(default=_HOG.nms_iou, gt=0.0, le=1.0)
    box_scale_x: float = Field(default=_HOG.box_scale_x, gt=0.0, le=1.0, description="person width / window width")
    box_scale_y: float = Field(default=_HOG.box_scale_y, gt=0.0, le=1.0, description="person height / window height")
    vote_iou: float = Field(default=_HOG.vote_iou, ge=0.0, le=1.0,
                            description="box voting: mean of the windows overlapping a kept box this much; 0 = off")
    max_detections: int = Field(default=_HOG.max_detections, ge=1)

    def params(self) -> HogParams:
        """The core's parameters."""
        return HogParams(**self.model_dump())


class DepthConfig(_Section):
    """Basso/Munaro's depth-cluster detector; needs depth registered to the colour image."""

    camera_height_m: float = Field(default=_DEPTH.camera_height_m, gt=0.0, le=5.0,
                                   description="initial plane: camera height over the floor")
    tilt_deg: float = Field(default=_DEPTH.tilt_deg, ge=-45.0, le=89.0,
                            description="initial plane: downward pitch of the camera")
    voxel_m: float = Field(default=_DEPTH.voxel_m, gt=0.0, le=0.5)
    pixel_step: int = Field(default=_DEPTH.pixel_step, ge=1, le=8,
                            description="use every n-th depth pixel in rows and columns")
    min_depth_m: float = Field(default=_DEPTH.min_depth_m, ge=0.0)
    max_depth_m: float = Field(default=_DEPTH.max_depth_m, gt=0.0)
    floor_clearance_m: float = Field(default=_DEPTH.floor_clearance_m, ge=0.0, le=0.5,
                                     description="points lower than this are floor")
    cluster_tolerance_m: float = Field(default=_DEPTH.cluster_tolerance_m, gt=0.0, le=1.0)
    min_cluster_points: int = Field(default=_DEPTH.min_cluster_points, ge=1)
    min_height_m: float = Field(default=_DEPTH.min_height_m, gt=0.0,
                                description="a standing person's top (seated people: seated_*)")
    max_height_m: float = Field(default=_DEPTH.max_height_m, gt=0.0)
    max_width_m: float = Field(default=_DEPTH.max_width_m, gt=0.0)
    min_thickness_m: float = Field(default=_DEPTH.min_thickness_m, ge=0.0, le=0.5,
                                   description="std of a cluster's floor footprint across its main direction must "
                                               "reach this: walls and door frames seen edge-on are flat (0: off)")
    max_bottom_m: float = Field(default=_DEPTH.max_bottom_m, ge=0.0,
                                description="a cluster must reach this close to the floor")
    occluded_max_bottom_m: float = Field(default=_DEPTH.occluded_max_bottom_m, ge=0.0, le=2.0,
                                         description="a cluster whose lowest points are hidden by something "
                                                     "nearer (a sofa, a table) need only come down to this, e.g. 1.05 "
                                                     "(0: off, the default)")
    head_separation_m: float = Field(default=_DEPTH.head_separation_m, ge=0.0, le=2.0,
                                     description="a cluster's highest points (above min_height_m) this far apart are "
                                                 "separate heads, one person each (0: off)")
    head_dip_m: float = Field(default=_DEPTH.head_dip_m, ge=0.0, le=1.0,
                              description="... if the cluster dips this much between them (a neck and shoulders)")
    head_max_width_m: float = Field(default=_DEPTH.head_max_width_m, ge=0.0, le=2.0,
                                    description="a standing cluster whose top, seen whole, is a flat slab wider than "
                                                "this is furniture or a wall piece, not a head (0: off)")
    occluder_gap_m: float = Field(default=_DEPTH.occluder_gap_m, gt=0.0, le=2.0,
                                  description="how much nearer the depth just below a point must be to hide it")
    plane_window_m: float = Field(default=_GROUND.window_m, gt=0.0,
                                  description="floor candidates: distance from the last plane")
    plane_inlier_m: float = Field(default=_GROUND.inlier_m, gt=0.0)
    plane_max_step_deg: float = Field(default=_GROUND.max_step_deg, gt=0.0, le=45.0)
    ransac_iterations: int = Field(default=_GROUND.iterations, ge=1)
    floor_max_deg: float = Field(default=_DEPTH.floor_max_deg, gt=0.0, le=45.0,
                                 description="a floor from the transforms (floor_frame) is refined on the depth this "
                                             "far at most (deg)")
    floor_max_m: float = Field(default=_DEPTH.floor_max_m, gt=0.0, le=1.0,
                               description="... and this far in height (m)")
    seated: bool = Field(default=_DEPTH.seated.enabled,
                         description="also find people sitting on a chair or sofa: a head, a torso and a seat or lap")
    seated_min_height_m: float = Field(default=_DEPTH.seated.min_height_m, gt=0.0,
                                       description="a seated person's head top, lowest (m)")
    seated_max_height_m: float = Field(default=_DEPTH.seated.max_height_m, gt=0.0,
                                       description="... and highest (m)")
    hog_confirm: bool = Field(default=_DEPTH.hog_confirm, description="score each cluster box with HOG and drop weak ones")
    hog_min_score: float = Field(default=_DEPTH.hog_min_score, ge=0.0, le=1.0)

    @model_validator(mode="after")
    def _ranges(self) -> DepthConfig:
        if self.min_height_m >= self.max_height_m:
            raise ValueError(f"min_height_m ({self.min_height_m}) must be below max_height_m ({self.max_height_m})")
        if self.min_depth_m >= self.max_depth_m:
            raise ValueError(f"min_depth_m ({self.min_depth_m}) must be below max_depth_m ({self.max_depth_m})")
        if not _DEPTH.seated.seat_band_m[1] < self.seated_min_height_m < self.seated_max_height_m:
            raise ValueError(f"need {_DEPTH.seated.seat_band_m[1]} < seated_min_height_m ({self.seated_min_height_m}) "
                             f"< seated_max_height_m ({self.seated_max_height_m})")
        return self

    def params(self) -> DepthParams:
        """The core's parameters (the ``plane_*`` and ``ransac_iterations`` settings are its ``ground``,
        the ``seated*`` ones its ``seated``)."""
        ground = GroundParams(window_m=self.plane_window_m, inlier_m=self.plane_inlier_m,
                              iterations=self.ransac_iterations, max_step_deg=self.plane_max_step_deg)
        seated = replace(_DEPTH.seated, enabled=self.seated, min_height_m=self.seated_min_height_m,
                         max_height_m=self.seated_max_height_m)
        skip = {"plane_window_m", "plane_inlier_m", "ransac_iterations", "plane_max_step_deg", "seated",
                "seated_min_height_m", "seated_max_height_m"}
        return DepthParams(ground=ground, seated=seated, **{k: v for k, v in self.model_dump().items() if k not in skip})


class YoloOnnxConfig(_Section):
    """A YOLO export in ONNX (v5 layout (1, N, 5+C) or v8/v11 layout (1, 4+C, N))."""

    model: Path | None = Field(default=None, description="path of the .onnx file")
    layout: Literal["auto", "v5", "v8"] = _YOLO.layout
    input_size: int = Field(default=_YOLO.input_size, ge=32, le=4096, multiple_of=32,
                            description="used when the model's input is dynamic")
    num_classes: int | None = Field(default=_YOLO.num_classes, ge=1, description="helps 'auto' tell v5 from v8")
    person_class: int = Field(default=_YOLO.person_class, ge=0)
    conf_threshold: float = Field(default=_YOLO.conf_threshold, ge=0.0, le=1.0)
    nms_iou: float = Field(default=_YOLO.nms_iou, gt=0.0, le=1.0)
    max_detections: int = Field(default=_YOLO.max_detections, ge=1)
    providers: list[str] | None = Field(default=None, description="onnxruntime providers; default TensorRT, CUDA, CPU as available")
    intra_op_threads: int = Field(default=_YOLO.intra_op_threads, ge=0,
                                  description="CPU threads, 0 = onnxruntime's choice")

    def params(self) -> YoloParams:
        """The core's parameters (``model`` None until the config names a file)."""
        y = self.model_dump()
        y["providers"] = tuple(y["providers"]) if y["providers"] else None
        return YoloParams(**y)


class DarknetConfig(_Section):
    """Darknet YOLOv3 cfg + weights through cv2.dnn."""

    cfg: Path | None = None
    weights: Path | None = None
    input_size: int = Field(default=_DARKNET.input_size, ge=0, le=4096, multiple_of=32,
                            description="0 keeps the cfg's width/height")
    person_class: int = Field(default=_DARKNET.person_class, ge=0)
    conf_threshold: float = Field(default=_DARKNET.conf_threshold, ge=0.0, le=1.0)
    nms_iou: float = Field(default=_DARKNET.nms_iou, gt=0.0, le=1.0)
    max_detections: int = Field(default=_DARKNET.max_detections, ge=1)
    use_cuda: bool = Field(default=_DARKNET.use_cuda, description="cv2.dnn CUDA backend (needs an OpenCV built with CUDA)")

    def params(self) -> DarknetParams:
        """The core's parameters (``cfg`` and ``weights`` None until the config names files)."""
        return DarknetParams(**self.model_dump())


class DetectorConfig(_Section):
    """The detector service's configuration (section ``detector`` of a deploy file)."""

    camera: str = Field(default="head", min_length=1, description="camera name in the frame and detection keys")
    stream: str | None = Field(
        default=None, description="name of its output, detections/{stream}, when another detector on the same camera "
                                  "publishes detections/{camera} (e.g. head-hog); None: the camera's name")
    backend: Backend = "hog"
    max_rate_hz: float | None = Field(
        default=None, gt=0.0, le=1000.0,
        description="process at most this many frames per second of sensor time (a slow second detector, e.g. 3); "
                    "the frames between are skipped and counted; None: every frame it can")
    depth_available: bool = Field(default=True, description="whether the camera publishes registered depth")
    floor_frame: str = Field(
        default="base_link",
        description="depth backend: the frame whose z = 0 plane is the floor (a base on the ground); its transform to "
                    "the camera (tf) gives the detector the floor in every frame, so a pitching head or a floor hidden "
                    "by furniture cannot lead its estimate astray. '' or no transform: it tracks the floor alone")
    floor_height_m: float = Field(default=0.0, ge=-2.0, le=2.0, description="the floor's height in floor_frame")
    floor_tolerance_s: float = Field(
        default=0.2, ge=0.0, le=5.0,
        description="use the newest transform when none is at the frame's stamp yet, if at most this much older")
    hog: HogConfig = Field(default_factory=HogConfig)
    depth: DepthConfig = Field(default_factory=DepthConfig)
    yolo: YoloOnnxConfig = Field(default_factory=YoloOnnxConfig)
    darknet: DarknetConfig = Field(default_factory=DarknetConfig)

    @property
    def output(self) -> str:
        """The name its detections are published under: ``stream``, else the camera's."""
        return self.stream or self.camera

    @model_validator(mode="after")
    def _backend_inputs(self) -> DetectorConfig:
        if self.stream is not None:
            validate_chunk(self.stream, "stream")
        if self.backend == "depth" and not self.depth_available:
            raise ValueError("backend 'depth' needs depth images but depth_available is false; "
                             "choose backend hog, yolo-onnx or darknet, or publish registered depth")
        if self.backend == "yolo-onnx" and self.yolo.model is None:
            raise ValueError("backend 'yolo-onnx' needs yolo.model, the path of the .onnx file")
        if self.backend == "darknet" and (self.darknet.cfg is None or self.darknet.weights is None):
            raise ValueError("backend 'darknet' needs darknet.cfg and darknet.weights")
        return self


def build_detector(config: DetectorConfig) -> Detector:
    """The core detector the config names; :class:`DetectorError` if its model cannot be used."""
    hog_params = config.hog.params()
    if config.backend == "hog":
        return HogDetector(hog_params)
    if config.backend == "depth":
        from services.detector.core.depth import DepthClusterDetector  # imports scipy: only when used

        params = config.depth.params()
        return DepthClusterDetector(params, hog=HogDetector(hog_params) if config.depth.hog_confirm else None)
    if config.backend == "yolo-onnx":
        return YoloOnnxDetector(config.yolo.params())
    if config.backend == "darknet":
        return DarknetDetector(config.darknet.params())
    raise DetectorError(f"unknown backend {config.backend!r}; choose one of {', '.join(BACKENDS)}")
