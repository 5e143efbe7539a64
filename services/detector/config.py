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

from pydantic import ConfigDict, model_validator

from common.messages.keys import validate_chunk
from common.runtime.settings import AdvancedBlock, setting
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


class _Section(AdvancedBlock):
    model_config = ConfigDict(extra="forbid")


class HogConfig(_Section):
    """OpenCV HOG people detector. ``upsample`` > 1 finds people smaller than ~96 px."""

    upsample: float = setting(_HOG.upsample, "image scale before HOG: about 1.1 x 96 / the smallest person's height "
                              "in px (2.25 for ~50 px people, 1.0 from ~105 px); the cost grows with its square",
                              ge=0.25, le=8.0)
    hit_threshold: float = setting(_HOG.hit_threshold, "minimum SVM margin of a window (the score is its logistic: "
                                   "1.0 gives 0.73); lower finds more people and more false ones", ge=-2.0, le=5.0)
    win_stride: int = setting(_HOG.win_stride, "step of the detection window", unit="px", ge=8, le=64, multiple_of=8,
                              advanced=True)
    scale: float = setting(_HOG.scale, "pyramid step between image scales", gt=1.0, le=2.0, advanced=True)
    nms_iou: float = setting(_HOG.nms_iou, "non-maximum suppression: a window overlapping a better one this much "
                             "(IoU) is dropped", gt=0.0, le=1.0, advanced=True)
    box_scale_x: float = setting(_HOG.box_scale_x, "person width / window width", gt=0.0, le=1.0, advanced=True)
    box_scale_y: float = setting(_HOG.box_scale_y, "person height / window height", gt=0.0, le=1.0, advanced=True)
    vote_iou: float = setting(_HOG.vote_iou, "box voting: mean of the windows overlapping a kept box this much (IoU); "
                              "0: off", ge=0.0, le=1.0, advanced=True)
    max_detections: int = setting(_HOG.max_detections, "most boxes kept per frame, best first", ge=1, advanced=True)

    def params(self) -> HogParams:
        """The core's parameters."""
        return HogParams(**self.model_dump())


class DepthConfig(_Section):
    """Basso/Munaro's depth-cluster detector; needs depth registered to the colour image."""

    camera_height_m: float = setting(_DEPTH.camera_height_m, "initial floor plane: the camera's height over the "
                                     "floor", unit="m", gt=0.0, le=5.0)
    tilt_deg: float = setting(_DEPTH.tilt_deg, "initial floor plane: the camera's downward pitch", unit="deg",
                              ge=-45.0, le=89.0)
    voxel_m: float = setting(_DEPTH.voxel_m, "side of the voxel grid the points are thinned to", unit="m", gt=0.0,
                             le=0.5, advanced=True)
    pixel_step: int = setting(_DEPTH.pixel_step, "use every n-th depth pixel in rows and columns", ge=1, le=8,
                              advanced=True)
    min_depth_m: float = setting(_DEPTH.min_depth_m, "depth pixels nearer than this are invalid", unit="m", ge=0.0)
    max_depth_m: float = setting(_DEPTH.max_depth_m, "depth pixels farther than this are invalid", unit="m", gt=0.0)
    floor_clearance_m: float = setting(_DEPTH.floor_clearance_m, "points lower than this over the plane are floor",
                                       unit="m", ge=0.0, le=0.5, advanced=True)
    cluster_tolerance_m: float = setting(_DEPTH.cluster_tolerance_m, "two points at most this far apart are in one "
                                         "cluster", unit="m", gt=0.0, le=1.0, advanced=True)
    min_cluster_points: int = setting(_DEPTH.min_cluster_points, "smaller clusters are dropped", ge=1, advanced=True)
    min_height_m: float = setting(_DEPTH.min_height_m, "a standing person's top, lowest (seated people: seated_*)",
                                  unit="m", gt=0.0)
    max_height_m: float = setting(_DEPTH.max_height_m, "a standing person's top, highest", unit="m", gt=0.0)
    max_width_m: float = setting(_DEPTH.max_width_m, "a wider cluster is split by its parts above the split height",
                                 unit="m", gt=0.0, advanced=True)
    min_thickness_m: float = setting(_DEPTH.min_thickness_m, "std of a cluster's floor footprint across its main "
                                     "direction must reach this: walls and door frames seen edge-on are flat; 0: off",
                                     unit="m", ge=0.0, le=0.5, advanced=True)
    max_bottom_m: float = setting(_DEPTH.max_bottom_m, "a cluster must reach this close to the floor", unit="m",
                                  ge=0.0, advanced=True)
    occluded_max_bottom_m: float = setting(_DEPTH.occluded_max_bottom_m, "a cluster whose lowest points are hidden by "
                                           "something nearer (a sofa, a table) need only come down to this, e.g. "
                                           "1.05; 0: off", unit="m", ge=0.0, le=2.0, advanced=True)
    head_separation_m: float = setting(_DEPTH.head_separation_m, "a cluster's highest points (above min_height_m) "
                                       "this far apart are separate heads, one person each; 0: off", unit="m",
                                       ge=0.0, le=2.0, advanced=True)
    head_dip_m: float = setting(_DEPTH.head_dip_m, "... if the cluster dips this much between them (a neck and "
                                "shoulders)", unit="m", ge=0.0, le=1.0, advanced=True)
    head_max_width_m: float = setting(_DEPTH.head_max_width_m, "a standing cluster whose top, seen whole, is a flat "
                                      "slab wider than this is furniture or a wall piece, not a head; 0: off", unit="m",
                                      ge=0.0, le=2.0, advanced=True)
    occluder_gap_m: float = setting(_DEPTH.occluder_gap_m, "how much nearer the depth just below a point must be to "
                                    "hide it", unit="m", gt=0.0, le=2.0, advanced=True)
    plane_window_m: float = setting(_GROUND.window_m, "floor candidates: distance from the last plane", unit="m",
                                    gt=0.0, advanced=True)
    plane_inlier_m: float = setting(_GROUND.inlier_m, "a point this near a candidate plane is its inlier", unit="m",
                                    gt=0.0, advanced=True)
    plane_max_step_deg: float = setting(_GROUND.max_step_deg, "a new plane's normal is within this of the last one's",
                                        unit="deg", gt=0.0, le=45.0, advanced=True)
    ransac_iterations: int = setting(_GROUND.iterations, "RANSAC draws per frame of the floor plane", ge=1,
                                     advanced=True)
    floor_max_deg: float = setting(_DEPTH.floor_max_deg, "a floor from the transforms (floor_frame) is refined on the "
                                   "depth this far at most", unit="deg", gt=0.0, le=45.0, advanced=True)
    floor_max_m: float = setting(_DEPTH.floor_max_m, "... and this far in height", unit="m", gt=0.0, le=1.0,
                                 advanced=True)
    seated: bool = setting(_DEPTH.seated.enabled, "also find people sitting on a chair or sofa: a head, a torso and "
                           "a seat or lap")
    seated_min_height_m: float = setting(_DEPTH.seated.min_height_m, "a seated person's head top, lowest", unit="m",
                                         gt=0.0, advanced=True)
    seated_max_height_m: float = setting(_DEPTH.seated.max_height_m, "... and highest", unit="m", gt=0.0,
                                         advanced=True)
    hog_confirm: bool = setting(_DEPTH.hog_confirm, "score each cluster box with HOG and drop weak ones")
    hog_min_score: float = setting(_DEPTH.hog_min_score, "hog_confirm: boxes HOG scores lower are dropped", ge=0.0,
                                   le=1.0)

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

    model: Path | None = setting(None, "path of the .onnx file (--model); required by backend yolo-onnx")
    layout: Literal["auto", "v5", "v8"] = setting(_YOLO.layout, "output layout: v5 (1, N, 5+C), v8 (1, 4+C, N), or "
                                                  "auto from the output's shape")
    input_size: int = setting(_YOLO.input_size, "network input side, used when the model's input is dynamic",
                              unit="px", ge=32, le=4096, multiple_of=32)
    num_classes: int | None = setting(_YOLO.num_classes, "the model's classes; helps 'auto' tell v5 from v8", ge=1,
                                      advanced=True)
    person_class: int = setting(_YOLO.person_class, "the person's class index (0 in COCO)", ge=0)
    conf_threshold: float = setting(_YOLO.conf_threshold, "boxes less confident are dropped (--conf)", ge=0.0, le=1.0)
    nms_iou: float = setting(_YOLO.nms_iou, "non-maximum suppression: a box overlapping a better one this much (IoU) "
                             "is dropped", gt=0.0, le=1.0, advanced=True)
    max_detections: int = setting(_YOLO.max_detections, "most boxes kept per frame, best first", ge=1, advanced=True)
    providers: list[str] | None = setting(None, "onnxruntime providers in order (--providers); none: TensorRT, CUDA, "
                                          "CPU as available")
    intra_op_threads: int = setting(_YOLO.intra_op_threads, "CPU threads; 0: onnxruntime's choice", ge=0)

    def params(self) -> YoloParams:
        """The core's parameters (``model`` None until the config names a file)."""
        y = self.model_dump()
        y["providers"] = tuple(y["providers"]) if y["providers"] else None
        return YoloParams(**y)


class DarknetConfig(_Section):
    """Darknet YOLOv3 cfg + weights through cv2.dnn."""

    cfg: Path | None = setting(None, "the network's .cfg file (--darknet-cfg); required by backend darknet")
    weights: Path | None = setting(None, "its .weights file (--darknet-weights); required by backend darknet")
    input_size: int = setting(_DARKNET.input_size, "network input side; 0 keeps the cfg's width and height",
                              unit="px", ge=0, le=4096, multiple_of=32)
    person_class: int = setting(_DARKNET.person_class, "the person's class index (0 in COCO)", ge=0)
    conf_threshold: float = setting(_DARKNET.conf_threshold, "boxes less confident are dropped (--conf)", ge=0.0,
                                    le=1.0)
    nms_iou: float = setting(_DARKNET.nms_iou, "non-maximum suppression: a box overlapping a better one this much "
                             "(IoU) is dropped", gt=0.0, le=1.0, advanced=True)
    max_detections: int = setting(_DARKNET.max_detections, "most boxes kept per frame, best first", ge=1,
                                  advanced=True)
    use_cuda: bool = setting(_DARKNET.use_cuda, "cv2.dnn's CUDA backend (needs an OpenCV built with CUDA)")

    def params(self) -> DarknetParams:
        """The core's parameters (``cfg`` and ``weights`` None until the config names files)."""
        return DarknetParams(**self.model_dump())


class DetectorConfig(_Section):
    """The detector service's configuration (section ``detector`` of a deploy file)."""

    camera: str = setting("head", "camera name in the frame and detection keys", min_length=1)
    stream: str | None = setting(None, "name of its output, detections/{stream}, when another detector on the same "
                                 "camera publishes detections/{camera} (e.g. head-hog); none: the camera's name")
    backend: Backend = setting("hog", "hog (no model file), depth (needs registered depth), yolo-onnx (yolo.model) "
                               "or darknet (darknet.cfg, darknet.weights)")
    max_rate_hz: float | None = setting(None, "process at most this many frames per second of sensor time (a slow "
                                        "second detector, e.g. 3); the frames between are skipped and counted; none: "
                                        "every frame it can", unit="Hz", gt=0.0, le=1000.0)
    depth_available: bool = setting(True, "whether the camera publishes registered depth")
    floor_frame: str = setting("base_link", "depth backend: the frame whose z = 0 plane is the floor (a base on the "
                               "ground), read from tf every frame so a pitching head or a floor hidden by furniture "
                               "cannot lead the estimate astray; '' or no transform: the floor from the depth alone")
    floor_height_m: float = setting(0.0, "the floor's height in floor_frame", unit="m", ge=-2.0, le=2.0)
    floor_tolerance_s: float = setting(0.2, "use the newest transform when none is at the frame's stamp yet, if at "
                                       "most this much older", unit="s", ge=0.0, le=5.0, advanced=True)
    hog: HogConfig = setting(description="the hog backend (and depth's hog_confirm)", default_factory=HogConfig)
    depth: DepthConfig = setting(description="the depth backend", default_factory=DepthConfig)
    yolo: YoloOnnxConfig = setting(description="the yolo-onnx backend", default_factory=YoloOnnxConfig)
    darknet: DarknetConfig = setting(description="the darknet backend", default_factory=DarknetConfig)

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
