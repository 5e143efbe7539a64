"""The thesis's detector: Darknet YOLOv3 from a ``.cfg`` and ``.weights`` pair, run by ``cv2.dnn``.

OpenCV loads a truncated weights file without complaint and then runs with garbage,
so the weights are counted against the cfg first (:func:`expected_weight_count`).
OpenCV's YOLO layers output rows ``cx, cy, w, h`` (fractions of the network input,
which is the plainly resized image), ``objectness`` and per-class scores already
multiplied by the objectness; the person column is the score.
"""

from __future__ import annotations

import logging
from dataclasses import dataclass
from pathlib import Path

import cv2
import numpy as np

from services.detector.core.boxes import DetectorError, as_rgb, clip_boxes, empty_result, nms
from services.detector.core.yolo_onnx import check_model_file

__all__ = ["DarknetDetector", "DarknetParams", "expected_weight_count", "parse_cfg"]

log = logging.getLogger(__name__)


@dataclass(frozen=True)
class DarknetParams:
    """Settings of :class:`DarknetDetector`; ``input_size`` 0 keeps the cfg's width/height."""

    cfg: Path
    weights: Path
    input_size: int = 0
    person_class: int = 0
    conf_threshold: float = 0.35
    nms_iou: float = 0.45
    max_detections: int = 100
    use_cuda: bool = False


def parse_cfg(text: str) -> list[tuple[str, dict[str, str]]]:
    """Sections of a Darknet cfg in order: ``[(type, {key: value})]``."""
    sections: list[tuple[str, dict[str, str]]] = []
    for raw in text.splitlines():
        line = raw.split("#", 1)[0].strip()
        if not line:
            continue
        if line.startswith("["):
            if not line.endswith("]"):
                raise DetectorError(f"darknet cfg: malformed section header {line!r}")
            sections.append((line[1:-1].strip(), {}))
        elif "=" in line and sections:
            key, value = line.split("=", 1)
            sections[-1][1][key.strip()] = value.strip()
        else:
            raise DetectorError(f"darknet cfg: cannot parse line {line!r}")
    if not sections or sections[0][0] not in ("net", "network"):
        raise DetectorError("darknet cfg must start with a [net] section")
    return sections


_PASS_THROUGH = {"shortcut", "maxpool", "upsample", "yolo", "region", "dropout", "avgpool", "softmax", "cost"}


def expected_weight_count(sections: list[tuple[str, dict[str, str]]]) -> int | None:
    """Number of float32 weights the cfg's layers need, or None if a layer type is not understood."""
    channels = int(sections[0][1].get("channels", 3))
    outputs: list[int] = []
    total = 0
    for kind, opts in sections[1:]:
        if kind in ("convolutional", "conv"):
            filters, size = int(opts.get("filters", 1)), int(opts.get("size", 1))
            groups = int(opts.get("groups", 1))
            bn = int(opts.get("batch_normalize", 0))
            total += filters * (1 + 3 * bn) + filters * (channels // groups) * size * size
            channels = filters
        elif kind == "route":
            layers = [int(v) for v in opts["layers"].split(",")]
            picked = [outputs[v if v >= 0 else len(outputs) + v] for v in layers]
            channels = sum(picked) // int(opts.get("groups", 1))
        elif kind == "reorg":
            channels *= int(opts.get("stride", 2)) ** 2
        elif kind not in _PASS_THROUGH:
            return None
        outputs.append(channels)
    return total


def _header_bytes(path: Path) -> int:
    with path.open("rb") as f:
        head = np.frombuffer(f.read(12), np.int32)
    if len(head) < 3:
        raise DetectorError(f"darknet weights {path} is too short to hold a header; copy the file again")
    major, minor = int(head[0]), int(head[1])
    return 20 if (major * 10 + minor) >= 2 and major < 1000 and minor < 1000 else 16


class DarknetDetector:
    """YOLOv3 (or tiny) person detector from Darknet files.

    ``detect(rgb)`` takes (H, W, 3) uint8 RGB and returns boxes (N, 4) float32 xyxy and
    scores (N,) float32 in [0, 1], best first.
    """

    name = "darknet"
    needs_depth = False
    postures: tuple[str, ...] = ()  # boxes say nothing of the posture
    depths: tuple[float, ...] = ()  # nor of a person's own depth: the localizer reads it in the box
    statures: tuple[float, ...] = ()  # nor of their stature (no floor, no depth)

    def __init__(self, params: DarknetParams) -> None:
        self.params = params
        cfg, weights = Path(params.cfg), Path(params.weights)
        check_model_file(cfg, "darknet cfg", "darknet.cfg")
        check_model_file(weights, "darknet weights", "darknet.weights")
        sections = parse_cfg(cfg.read_text(errors="replace"))
        needed = expected_weight_count(sections)
        if needed is not None:
            have = (weights.stat().st_size - _header_bytes(weights)) // 4
            if have != needed:
                state = "truncated" if have < needed else "larger than the cfg needs"
                raise DetectorError(f"darknet weights {weights} hold {have} values but {cfg} needs {needed}: the file is "
                                    f"{state}; use the weights that belong to this cfg")
        else:
            log.warning("darknet cfg %s has layers whose weights cannot be counted; weights size not checked", cfg)
        try:
            self.net = cv2.dnn.readNetFromDarknet(str(cfg), str(weights))
        except cv2.error as exc:
            raise DetectorError(f"OpenCV cannot load darknet model {cfg} + {weights}: {exc}") from exc
        if params.use_cuda:
            self.net.setPreferableBackend(cv2.dnn.DNN_BACKEND_CUDA)
            self.net.setPreferableTarget(cv2.dnn.DNN_TARGET_CUDA)
        self.output_names = list(self.net.getUnconnectedOutLayersNames())
        net = sections[0][1]
        size = params.input_size
        self.input_wh = (size, size) if size else (int(net.get("width", 416)), int(net.get("height", 416)))
        classes = {int(opts["classes"]) for kind, opts in sections if kind in ("yolo", "region") and "classes" in opts}
        if classes and params.person_class >= min(classes):
            raise DetectorError(f"darknet cfg has {min(classes)} classes, person_class {params.person_class} is out of range")

    def detect(self, rgb: np.ndarray, depth: np.ndarray | None = None,
               camera: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
        image = as_rgb(rgb)
        p = self.params
        blob = cv2.dnn.blobFromImage(image, 1 / 255.0, self.input_wh, swapRB=False, crop=False)
        self.net.setInput(blob)
        rows = np.concatenate([o.reshape(-1, o.shape[-1]) for o in self.net.forward(self.output_names)], axis=0)
        if rows.shape[1] <= 5 + p.person_class:
            raise DetectorError(f"darknet output has {rows.shape[1] - 5} classes, person_class is {p.person_class}")
        cls = rows[:, 5:]
        scores = cls[:, p.person_class]
        keep = (cls.argmax(axis=1) == p.person_class) & (scores >= p.conf_threshold)
        rows, scores = rows[keep], scores[keep]
        if len(rows) == 0:
            return empty_result()
        h, w = image.shape[:2]
        centre = rows[:, :2] * (w, h)
        half = rows[:, 2:4] * (w, h) / 2.0
        boxes = clip_boxes(np.column_stack([centre - half, centre + half]), w, h)
        order = nms(boxes, scores, p.nms_iou, max_detections=p.max_detections)
        return boxes[order], np.clip(scores[order], 0.0, 1.0).astype(np.float32)
