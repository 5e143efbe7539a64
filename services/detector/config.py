"""DetectorConfig: which backend, its settings, and how to build it.

Defaults: the ``hog`` backend (no model file); seed 002's values for ``depth``. Model
paths are plain settings, nothing is downloaded. :func:`build_detector` turns the
config into a core detector and fails with :class:`DetectorError` naming the setting
to fix (missing/truncated model, unavailable onnxruntime provider).
"""

from __future__ import annotations

from pathlib import Path
from typing import Literal

from pydantic import BaseModel, ConfigDict, Field, model_validator

from services.detector.core import Detector
from services.detector.core.boxes import DetectorError

__all__ = ["BACKENDS", "DarknetConfig", "DepthConfig", "DetectorConfig", "HogConfig", "YoloOnnxConfig", "build_detector"]

BACKENDS = ("hog", "depth", "yolo-onnx", "darknet")
Backend = Literal["hog", "depth", "yolo-onnx", "darknet"]


class _Section(BaseModel):
    model_config = ConfigDict(extra="forbid")


class HogConfig(_Section):
    """OpenCV HOG people detector. ``upsample`` > 1 finds people smaller than ~96 px."""

    upsample: float = Field(default=1.0, ge=0.25, le=8.0, description="image scale before HOG; 2.25 for ~50 px people")
    hit_threshold: float = Field(default=1.0, ge=-2.0, le=5.0, description="minimum SVM margin of a window")
    win_stride: int = Field(default=8, ge=8, le=64, multiple_of=8)
    scale: float = Field(default=1.05, gt=1.0, le=2.0, description="pyramid step")
    nms_iou: float = Field(default=0.3, gt=0.0, le=1.0)
    box_scale_x: float = Field(default=0.6, gt=0.0, le=1.0, description="person width / window width")
    box_scale_y: float = Field(default=0.8, gt=0.0, le=1.0, description="person height / window height")
    max_detections: int = Field(default=100, ge=1)


class DepthConfig(_Section):
    """Seed 002's depth-cluster detector; needs depth registered to the colour image."""

    camera_height_m: float = Field(default=1.2, gt=0.0, le=5.0, description="initial plane: camera height over the floor")
    tilt_deg: float = Field(default=0.0, ge=-45.0, le=89.0, description="initial plane: downward pitch of the camera")
    voxel_m: float = Field(default=0.06, gt=0.0, le=0.5)
    pixel_step: int = Field(default=2, ge=1, le=8, description="use every n-th depth pixel in rows and columns")
    min_depth_m: float = Field(default=0.3, ge=0.0)
    max_depth_m: float = Field(default=8.0, gt=0.0)
    floor_clearance_m: float = Field(default=0.12, ge=0.0, le=0.5, description="points lower than this are floor")
    cluster_tolerance_m: float = Field(default=0.13, gt=0.0, le=1.0)
    min_cluster_points: int = Field(default=15, ge=1)
    min_height_m: float = Field(default=1.4, gt=0.0, description="lower it (e.g. 1.0) to keep sitting people")
    max_height_m: float = Field(default=2.3, gt=0.0)
    max_width_m: float = Field(default=1.5, gt=0.0)
    max_bottom_m: float = Field(default=0.6, ge=0.0, description="a cluster must reach this close to the floor")
    plane_window_m: float = Field(default=0.25, gt=0.0, description="floor candidates: distance from the last plane")
    plane_inlier_m: float = Field(default=0.04, gt=0.0)
    plane_max_step_deg: float = Field(default=10.0, gt=0.0, le=45.0)
    ransac_iterations: int = Field(default=60, ge=1)
    hog_confirm: bool = Field(default=False, description="score each cluster box with HOG and drop weak ones")
    hog_min_score: float = Field(default=0.5, ge=0.0, le=1.0)

    @model_validator(mode="after")
    def _ranges(self) -> DepthConfig:
        if self.min_height_m >= self.max_height_m:
            raise ValueError(f"min_height_m ({self.min_height_m}) must be below max_height_m ({self.max_height_m})")
        if self.min_depth_m >= self.max_depth_m:
            raise ValueError(f"min_depth_m ({self.min_depth_m}) must be below max_depth_m ({self.max_depth_m})")
        return self


class YoloOnnxConfig(_Section):
    """A YOLO export in ONNX (v5 layout (1, N, 5+C) or v8/v11 layout (1, 4+C, N))."""

    model: Path | None = Field(default=None, description="path of the .onnx file")
    layout: Literal["auto", "v5", "v8"] = "auto"
    input_size: int = Field(default=640, ge=32, le=4096, multiple_of=32, description="used when the model's input is dynamic")
    num_classes: int | None = Field(default=None, ge=1, description="helps 'auto' tell v5 from v8")
    person_class: int = Field(default=0, ge=0)
    conf_threshold: float = Field(default=0.35, ge=0.0, le=1.0)
    nms_iou: float = Field(default=0.45, gt=0.0, le=1.0)
    max_detections: int = Field(default=100, ge=1)
    providers: list[str] | None = Field(default=None, description="onnxruntime providers; default TensorRT, CUDA, CPU as available")
    intra_op_threads: int = Field(default=0, ge=0, description="CPU threads, 0 = onnxruntime's choice")


class DarknetConfig(_Section):
    """Darknet YOLOv3 cfg + weights through cv2.dnn."""

    cfg: Path | None = None
    weights: Path | None = None
    input_size: int = Field(default=0, ge=0, le=4096, multiple_of=32, description="0 keeps the cfg's width/height")
    person_class: int = Field(default=0, ge=0)
    conf_threshold: float = Field(default=0.35, ge=0.0, le=1.0)
    nms_iou: float = Field(default=0.45, gt=0.0, le=1.0)
    max_detections: int = Field(default=100, ge=1)
    use_cuda: bool = Field(default=False, description="cv2.dnn CUDA backend (needs an OpenCV built with CUDA)")


class DetectorConfig(_Section):
    """The detector service's configuration (section ``detector`` of a deploy file)."""

    camera: str = Field(default="head", min_length=1, description="camera name in the frame and detection keys")
    backend: Backend = "hog"
    depth_available: bool = Field(default=True, description="whether the camera publishes registered depth")
    recv_timeout_s: float = Field(default=0.5, gt=0.0, description="how long one wait for a frame lasts")
    hog: HogConfig = Field(default_factory=HogConfig)
    depth: DepthConfig = Field(default_factory=DepthConfig)
    yolo: YoloOnnxConfig = Field(default_factory=YoloOnnxConfig)
    darknet: DarknetConfig = Field(default_factory=DarknetConfig)

    @model_validator(mode="after")
    def _backend_inputs(self) -> DetectorConfig:
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
    from services.detector.core.hog import HogDetector, HogParams

    hog_params = HogParams(**config.hog.model_dump())
    if config.backend == "hog":
        return HogDetector(hog_params)
    if config.backend == "depth":
        from services.detector.core.depth import DepthClusterDetector, DepthParams
        from services.detector.core.ground import GroundParams

        d = config.depth
        ground = GroundParams(window_m=d.plane_window_m, inlier_m=d.plane_inlier_m, iterations=d.ransac_iterations,
                              max_step_deg=d.plane_max_step_deg)
        skip = {"plane_window_m", "plane_inlier_m", "ransac_iterations", "plane_max_step_deg"}
        params = DepthParams(ground=ground, **{k: v for k, v in d.model_dump().items() if k not in skip})
        return DepthClusterDetector(params, hog=HogDetector(hog_params) if d.hog_confirm else None)
    if config.backend == "yolo-onnx":
        from services.detector.core.yolo_onnx import YoloOnnxDetector, YoloParams

        y = config.yolo.model_dump()
        y["providers"] = tuple(y["providers"]) if y["providers"] else None
        return YoloOnnxDetector(YoloParams(**y))
    if config.backend == "darknet":
        from services.detector.core.darknet import DarknetDetector, DarknetParams

        return DarknetDetector(DarknetParams(**config.darknet.model_dump()))
    raise DetectorError(f"unknown backend {config.backend!r}; choose one of {', '.join(BACKENDS)}")
