"""YOLO person detectors exported to ONNX, run with onnxruntime.

Two output layouts are decoded:

* **v5** (YOLOv5/v7 export): ``(1, N, 5 + C)`` rows ``cx, cy, w, h, objectness, C class
  scores``; a box scores ``objectness * class score``.
* **v8** (YOLOv8/v11 export): ``(1, 4 + C, N)``, i.e. the transposed rows
  ``cx, cy, w, h, C class scores`` without objectness.

Boxes are in the pixels of the letterboxed network input and are mapped back to the
original image. Nothing is downloaded: the model path comes from the configuration.
"""

from __future__ import annotations

import logging
from dataclasses import dataclass
from pathlib import Path
from typing import Literal, Sequence

import cv2
import numpy as np

from services.detector.core.boxes import DetectorError, as_rgb, clip_boxes, empty_result, nms

__all__ = ["PREFERRED_PROVIDERS", "Letterbox", "YoloOnnxDetector", "YoloParams", "choose_providers",
           "decode_yolo", "letterbox"]

log = logging.getLogger(__name__)

#: Execution providers in order of preference when none are configured.
PREFERRED_PROVIDERS = ("TensorrtExecutionProvider", "CUDAExecutionProvider", "CPUExecutionProvider")

Layout = Literal["auto", "v5", "v8"]


@dataclass(frozen=True)
class YoloParams:
    """Settings of :class:`YoloOnnxDetector`."""

    model: Path
    layout: Layout = "auto"
    input_size: int = 640
    person_class: int = 0
    num_classes: int | None = None
    conf_threshold: float = 0.35
    nms_iou: float = 0.45
    max_detections: int = 100
    providers: tuple[str, ...] | None = None
    intra_op_threads: int = 0


@dataclass(frozen=True)
class Letterbox:
    """How an image was fitted into the network input: ``input = original * scale + (pad_x, pad_y)``."""

    scale: float
    pad_x: float
    pad_y: float

    def to_original(self, boxes: np.ndarray) -> np.ndarray:
        """Boxes (N, 4) xyxy in network-input pixels -> original-image pixels."""
        out = np.asarray(boxes, np.float64).copy()
        out[:, [0, 2]] = (out[:, [0, 2]] - self.pad_x) / self.scale
        out[:, [1, 3]] = (out[:, [1, 3]] - self.pad_y) / self.scale
        return out


def letterbox(image: np.ndarray, size: tuple[int, int], fill: int = 114) -> tuple[np.ndarray, Letterbox]:
    """Resize ``image`` (H, W, 3) keeping its aspect ratio and pad it to ``size`` (H, W), centred."""
    h, w = image.shape[:2]
    th, tw = size
    scale = min(th / h, tw / w)
    nh, nw = max(1, int(round(h * scale))), max(1, int(round(w * scale)))
    resized = cv2.resize(image, (nw, nh), interpolation=cv2.INTER_LINEAR) if (nh, nw) != (h, w) else image
    top, left = (th - nh) // 2, (tw - nw) // 2
    out = np.full((th, tw, 3), fill, np.uint8)
    out[top:top + nh, left:left + nw] = resized
    return out, Letterbox(scale, float(left), float(top))


def decode_yolo(output: np.ndarray, layout: Layout, person_class: int, conf_threshold: float,
                num_classes: int | None = None) -> tuple[np.ndarray, np.ndarray, str]:
    """Person boxes (M, 4) xyxy and scores (M,) above ``conf_threshold`` from one raw output.

    ``output`` is (1, N, 5+C) or (N, 5+C) for v5, (1, 4+C, N) or (4+C, N) for v8. With
    ``layout="auto"`` the smaller axis is the attribute axis; its length minus
    ``num_classes`` (when known) tells 5 (v5) from 4 (v8), otherwise a transposed output
    is v8 and a row-major one v5. Returns the layout used as third element.
    """
    out = np.asarray(output, np.float32)
    if out.ndim == 3:
        if out.shape[0] != 1:
            raise DetectorError(f"YOLO output has batch size {out.shape[0]}, expected 1")
        out = out[0]
    if out.ndim != 2:
        raise DetectorError(f"YOLO output must be (1, N, 5+C) or (1, 4+C, N), got shape {np.shape(output)}")
    transposed = out.shape[0] < out.shape[1]
    rows = out.T if transposed else out
    if layout == "auto":
        attrs = rows.shape[1]
        if num_classes is not None and attrs - num_classes in (4, 5):
            layout = "v8" if attrs - num_classes == 4 else "v5"
        else:
            layout = "v8" if transposed else "v5"
    head = 5 if layout == "v5" else 4
    classes = rows.shape[1] - head
    if classes <= person_class:
        raise DetectorError(f"YOLO output has {classes} classes in the {layout} layout, person_class is {person_class}")
    cls = rows[:, head:]
    best = cls.argmax(axis=1)
    score = cls[np.arange(len(rows)), person_class]
    if layout == "v5":
        score = score * rows[:, 4]
    keep = (best == person_class) & (score >= conf_threshold)
    sel, score = rows[keep], score[keep]
    half = sel[:, 2:4] / 2.0
    boxes = np.column_stack([sel[:, :2] - half, sel[:, :2] + half])
    return boxes, score, layout


def choose_providers(requested: Sequence[str] | None, available: Sequence[str]) -> list[str]:
    """The providers to use: ``requested`` (all must be available) or the preferred available ones."""
    if requested:
        missing = [p for p in requested if p not in available]
        if missing:
            raise DetectorError(f"onnxruntime providers {missing} are not available here (available: {list(available)}); "
                                "install onnxruntime-gpu with matching CUDA/TensorRT, or drop them from yolo.providers")
        return list(requested)
    chosen = [p for p in PREFERRED_PROVIDERS if p in available]
    return chosen or list(available)


def _ort_errors() -> tuple[type[BaseException], ...]:
    """onnxruntime's own exception types (they derive from Exception directly), plus RuntimeError."""
    from onnxruntime.capi import onnxruntime_pybind11_state as state

    names = ("Fail", "InvalidArgument", "NoSuchFile", "NoModel", "EngineError", "RuntimeException",
             "InvalidProtobuf", "ModelLoaded", "NotImplemented", "InvalidGraph", "EPFail")
    found = tuple(getattr(state, n) for n in names if isinstance(getattr(state, n, None), type))
    return (*found, RuntimeError)


def check_model_file(path: Path, what: str, setting: str) -> None:
    """Raise :class:`DetectorError` unless ``path`` is a non-empty readable file."""
    if not path.is_file():
        raise DetectorError(f"{what} {path} does not exist; set {setting} to the file on this machine "
                            "(nothing is downloaded)")
    if path.stat().st_size == 0:
        raise DetectorError(f"{what} {path} is empty; copy the file again")


class YoloOnnxDetector:
    """A YOLO person detector from an ONNX file.

    ``detect(rgb)`` takes (H, W, 3) uint8 RGB and returns boxes (N, 4) float32 xyxy in
    its pixels and scores (N,) float32, best first. The input size is read from the
    model when static, otherwise ``input_size`` is used.
    """

    name = "yolo-onnx"
    needs_depth = False
    postures: tuple[str, ...] = ()  # boxes say nothing of the posture
    depths: tuple[float, ...] = ()  # nor of a person's own depth: the localizer reads it in the box
    statures: tuple[float, ...] = ()  # nor of their stature (no floor, no depth)

    def __init__(self, params: YoloParams) -> None:
        import onnxruntime as ort

        self.params = params
        model = Path(params.model)
        check_model_file(model, "ONNX model", "yolo.model")
        self.providers = choose_providers(params.providers, ort.get_available_providers())
        options = ort.SessionOptions()
        if params.intra_op_threads:
            options.intra_op_num_threads = params.intra_op_threads
        options.log_severity_level = 3
        try:
            self.session = ort.InferenceSession(str(model), sess_options=options, providers=self.providers)
        except _ort_errors() as exc:
            raise DetectorError(f"ONNX model {model} cannot be loaded ({type(exc).__name__}: {exc}); "
                                "is the file complete (not truncated) and an ONNX export of a YOLO model?") from exc
        inputs = self.session.get_inputs()
        if len(inputs) != 1 or len(inputs[0].shape) != 4:
            raise DetectorError(f"ONNX model {model} must have one (1, 3, H, W) input, has {[i.shape for i in inputs]}")
        self.input_name = inputs[0].name
        shape = inputs[0].shape
        h = shape[2] if isinstance(shape[2], int) else params.input_size
        w = shape[3] if isinstance(shape[3], int) else params.input_size
        self.input_hw = (int(h), int(w))
        self.output_name = self.session.get_outputs()[0].name
        log.info("loaded %s: input %s, providers %s", model, self.input_hw, self.session.get_providers())

    def detect(self, rgb: np.ndarray, depth: np.ndarray | None = None,
               camera: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
        image = as_rgb(rgb)
        p = self.params
        padded, box = letterbox(image, self.input_hw)
        blob = np.ascontiguousarray(padded.transpose(2, 0, 1)[None], dtype=np.float32) * np.float32(1 / 255.0)
        try:
            (output,) = self.session.run([self.output_name], {self.input_name: blob})
        except _ort_errors() as exc:
            raise DetectorError(f"onnxruntime failed on a {blob.shape} input: {exc}") from exc
        boxes, scores, _ = decode_yolo(output, p.layout, p.person_class, p.conf_threshold, p.num_classes)
        if len(boxes) == 0:
            return empty_result()
        h, w = image.shape[:2]
        boxes = clip_boxes(box.to_original(boxes), w, h)
        keep = nms(boxes, scores, p.nms_iou, max_detections=p.max_detections)
        return boxes[keep], np.clip(scores[keep], 0.0, 1.0).astype(np.float32)
