"""Box arithmetic shared by every backend: validation, IoU, clipping and NMS.

Boxes are ``(N, 4)`` float32 ``[x1, y1, x2, y2]`` in pixels; scores ``(N,)`` float32 in [0, 1].
"""

from __future__ import annotations

import cv2
import numpy as np

__all__ = ["DetectorError", "as_rgb", "clip_boxes", "empty_result", "iou_matrix", "nms", "sigmoid"]


class DetectorError(ValueError):
    """A detector cannot be built or cannot run on its input; the message says why and what to do."""


def empty_result() -> tuple[np.ndarray, np.ndarray]:
    """No detections: ``(0, 4)`` float32 boxes and ``(0,)`` float32 scores."""
    return np.zeros((0, 4), np.float32), np.zeros(0, np.float32)


def as_rgb(image: np.ndarray) -> np.ndarray:
    """Check an image for detection and return it as contiguous (H, W, 3) uint8 RGB.

    Accepts (H, W) or (H, W, 1) grey and (H, W, 4) RGBA; raises :class:`DetectorError`
    for an empty image, another dtype or another shape.
    """
    arr = np.asarray(image)
    if arr.ndim not in (2, 3) or arr.size == 0 or min(arr.shape[:2]) == 0:
        raise DetectorError(f"image must be a non-empty (H, W) or (H, W, 3) array, got shape {arr.shape}")
    if arr.dtype != np.uint8:
        raise DetectorError(f"image must be uint8, got {arr.dtype} (is this a depth image?)")
    if arr.ndim == 2 or arr.shape[2] == 1:
        return cv2.cvtColor(arr.reshape(arr.shape[:2]), cv2.COLOR_GRAY2RGB)
    if arr.shape[2] == 4:
        return np.ascontiguousarray(arr[..., :3])
    if arr.shape[2] != 3:
        raise DetectorError(f"image must have 1, 3 or 4 channels, got {arr.shape[2]}")
    return np.ascontiguousarray(arr)


def sigmoid(x: np.ndarray) -> np.ndarray:
    """Logistic function, element-wise, without overflow warnings."""
    return 0.5 * (1.0 + np.tanh(0.5 * np.asarray(x, np.float64)))


def iou_matrix(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Intersection over union of every box in ``a`` (N, 4) with every box in ``b`` (M, 4): (N, M)."""
    a = np.asarray(a, np.float64).reshape(-1, 4)
    b = np.asarray(b, np.float64).reshape(-1, 4)
    x1 = np.maximum(a[:, None, 0], b[None, :, 0])
    y1 = np.maximum(a[:, None, 1], b[None, :, 1])
    x2 = np.minimum(a[:, None, 2], b[None, :, 2])
    y2 = np.minimum(a[:, None, 3], b[None, :, 3])
    inter = np.clip(x2 - x1, 0, None) * np.clip(y2 - y1, 0, None)
    area_a = (a[:, 2] - a[:, 0]) * (a[:, 3] - a[:, 1])
    area_b = (b[:, 2] - b[:, 0]) * (b[:, 3] - b[:, 1])
    union = area_a[:, None] + area_b[None, :] - inter
    return np.where(union > 0, inter / np.maximum(union, 1e-12), 0.0)


def clip_boxes(boxes: np.ndarray, width: int, height: int) -> np.ndarray:
    """Boxes (N, 4) clipped to the image ``[0, width] x [0, height]``, as float32."""
    out = np.asarray(boxes, np.float32).reshape(-1, 4).copy()
    out[:, [0, 2]] = np.clip(out[:, [0, 2]], 0, width)
    out[:, [1, 3]] = np.clip(out[:, [1, 3]], 0, height)
    return out


def nms(boxes: np.ndarray, scores: np.ndarray, iou_threshold: float, score_threshold: float = -np.inf,
        max_detections: int | None = None) -> np.ndarray:
    """Greedy non-maximum suppression; indices of the kept boxes, best score first.

    ``boxes`` (N, 4) xyxy, ``scores`` (N,). Boxes scoring below ``score_threshold`` are
    dropped first; a box is suppressed when its IoU with a better kept box exceeds
    ``iou_threshold``. Uses OpenCV's ``cv2.dnn.NMSBoxes``.
    """
    boxes = np.asarray(boxes, np.float64).reshape(-1, 4)
    scores = np.asarray(scores, np.float64).reshape(-1)
    candidates = np.flatnonzero(scores >= score_threshold)
    if len(candidates) == 0:
        return np.zeros(0, np.int64)
    b, s = boxes[candidates], scores[candidates]
    xywh = np.column_stack([b[:, :2], b[:, 2:] - b[:, :2]])
    # NMSBoxes only needs the order of the scores, refuses negative thresholds and keeps
    # only scores strictly above the threshold: shift the scores to start at 1.
    keep = cv2.dnn.NMSBoxes(xywh.tolist(), (s - s.min() + 1.0).tolist(), 0.0, float(iou_threshold),
                            top_k=int(max_detections or 0))
    keep = candidates[np.asarray(keep, np.int64).reshape(-1)]
    return keep[np.argsort(-scores[keep], kind="stable")]
