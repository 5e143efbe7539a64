"""OpenCV's HOG people detector (Dalal-Triggs linear SVM) with upsampling, box fitting, NMS and box voting.

The default SVM scores a 64x128 window whose person is about 96 px tall, so people
smaller than that are only found after upsampling the image (``upsample``: about
1.1 x 96 / the smallest person's height in pixels). The raw windows are grouped by
real non-maximum suppression rather than OpenCV's rectangle grouping, which merges
neighbours into loose boxes around groups of people.

HOG returns its window, not the person. The SVM was trained on windows with the person
centred and a 16 px margin above the head and below the feet (96 of 128 px, 0.75), and
about half the window wide, so each window is shrunk about its centre to
``box_scale_x`` x ``box_scale_y`` (0.5 x 0.75): the bottom edge is then the feet. Each
box kept by NMS is then replaced by the score-weighted mean of the fitted windows that
overlap it by at least ``vote_iou`` (box voting): the pyramid's scale steps and the
window stride quantise single windows, their mean places the box, and the feet, better.
The SVM margin ``w`` is turned into a score in [0, 1] by the logistic function (0.5 at
the SVM boundary).
"""

from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np

from services.detector.core.boxes import DetectorError, as_rgb, clip_boxes, empty_result, iou_matrix, nms, sigmoid

__all__ = ["HogDetector", "HogParams", "vote_boxes"]


@dataclass(frozen=True)
class HogParams:
    """Settings of :class:`HogDetector` (defaults tuned on PETS09 S2.L1, see the README)."""

    upsample: float = 1.0
    hit_threshold: float = 1.0
    win_stride: int = 8
    scale: float = 1.05
    padding: int = 8
    nms_iou: float = 0.3
    box_scale_x: float = 0.5
    box_scale_y: float = 0.75
    vote_iou: float = 0.5
    max_detections: int = 100

    def __post_init__(self) -> None:
        if not 0.25 <= self.upsample <= 8.0:
            raise DetectorError(f"hog upsample must be in [0.25, 8], got {self.upsample}")
        if self.scale <= 1.0:
            raise DetectorError(f"hog scale (pyramid step) must be > 1, got {self.scale}")
        if self.win_stride <= 0 or self.win_stride % 8:
            raise DetectorError(f"hog win_stride must be a positive multiple of 8 (the cell size), got {self.win_stride}")
        if not 0.0 <= self.vote_iou <= 1.0:
            raise DetectorError(f"hog vote_iou must be in [0, 1] (0 turns box voting off), got {self.vote_iou}")


def vote_boxes(kept: np.ndarray, boxes: np.ndarray, weights: np.ndarray, iou: float) -> np.ndarray:
    """Each of ``kept`` (K, 4) xyxy replaced by the ``weights`` (N,)-weighted mean of the ``boxes``
    (N, 4) that overlap it with IoU >= ``iou`` (a kept box overlaps itself, so it always has one)."""
    if len(kept) == 0:
        return np.asarray(kept, np.float64).reshape(0, 4)
    w = (iou_matrix(kept, boxes) >= iou) * np.asarray(weights, np.float64)[None, :]
    total = w.sum(axis=1, keepdims=True)
    voted = w @ np.asarray(boxes, np.float64) / np.maximum(total, 1e-12)
    return np.where(total > 0, voted, kept)


class HogDetector:
    """People boxes from the default OpenCV HOG people detector.

    ``detect(rgb)`` takes (H, W, 3) uint8 RGB and returns ``(boxes (N, 4) float32 xyxy,
    scores (N,) float32 in [0, 1])``, best first. Depth and camera are ignored.
    """

    name = "hog"
    needs_depth = False
    postures: tuple[str, ...] = ()  # boxes say nothing of the posture
    depths: tuple[float, ...] = ()  # nor of a person's own depth: the localizer reads it in the box
    statures: tuple[float, ...] = ()  # nor of their stature (no floor, no depth)

    def __init__(self, params: HogParams | None = None) -> None:
        self.params = params if params is not None else HogParams()
        self._hog = cv2.HOGDescriptor()
        self._hog.setSVMDetector(cv2.HOGDescriptor_getDefaultPeopleDetector())

    def detect(self, rgb: np.ndarray, depth: np.ndarray | None = None,
               camera: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
        image = as_rgb(rgb)
        windows, margins = self.windows(image)
        return self.boxes_from_windows(windows, margins, image.shape[1], image.shape[0])

    def boxes_from_windows(self, windows: np.ndarray, margins: np.ndarray, width: int,
                           height: int) -> tuple[np.ndarray, np.ndarray]:
        """People boxes from raw windows (as :meth:`windows` returns them) of a ``width`` x ``height`` image.

        Windows whose margin is below ``hit_threshold`` are dropped, the rest are fitted
        to the person, grouped by NMS and voted (see the module docstring). Returns
        ``(boxes (N, 4) float32 xyxy, scores (N,) float32)``, best first.
        """
        p = self.params
        windows = np.asarray(windows, np.float64).reshape(-1, 4)
        margins = np.asarray(margins, np.float64).reshape(-1)
        strong = margins >= p.hit_threshold
        windows, margins = windows[strong], margins[strong]
        if len(windows) == 0:
            return empty_result()
        centre = windows[:, :2] + windows[:, 2:] / 2.0
        half = windows[:, 2:] * np.array([p.box_scale_x, p.box_scale_y]) / 2.0
        boxes = np.column_stack([centre - half, centre + half])
        keep = nms(boxes, margins, p.nms_iou, max_detections=p.max_detections)
        out = boxes[keep]
        if p.vote_iou > 0.0:
            out = vote_boxes(out, boxes, sigmoid(margins), p.vote_iou)
        return clip_boxes(out, width, height), sigmoid(margins[keep]).astype(np.float32)

    def windows(self, image: np.ndarray, hit_threshold: float | None = None) -> tuple[np.ndarray, np.ndarray]:
        """Raw detection windows before NMS: (N, 4) float64 ``x, y, w, h`` in input pixels, (N,) SVM margins."""
        p = self.params
        gray = cv2.cvtColor(image, cv2.COLOR_RGB2GRAY)
        if p.upsample != 1.0:
            interp = cv2.INTER_LINEAR if p.upsample > 1.0 else cv2.INTER_AREA
            gray = cv2.resize(gray, None, fx=p.upsample, fy=p.upsample, interpolation=interp)
        if gray.shape[0] < 128 or gray.shape[1] < 64:
            return np.zeros((0, 4)), np.zeros(0)
        rects, weights = self._hog.detectMultiScale(
            gray, hitThreshold=p.hit_threshold if hit_threshold is None else hit_threshold,
            winStride=(p.win_stride, p.win_stride), padding=(p.padding, p.padding), scale=p.scale,
            groupThreshold=0)
        rects = np.asarray(rects, np.float64).reshape(-1, 4) / p.upsample
        return rects, np.asarray(weights, np.float64).reshape(-1)

    def score_window(self, image: np.ndarray, box: np.ndarray) -> float:
        """Best HOG score in [0, 1] of a person filling ``box`` (4,) xyxy of ``image`` (H, W, 3) RGB.

        The box is widened to the detector's 64x128 window geometry (the inverse of
        ``box_scale``), cut out with a margin, scaled so the person is window-sized and
        scanned at one scale. Used to confirm candidates found by other means.
        """
        p = self.params
        x1, y1, x2, y2 = (float(v) for v in box)
        bh = max(y2 - y1, 1.0) / p.box_scale_y
        bw = bh * 0.5
        cx, cy = (x1 + x2) / 2.0, (y1 + y2) / 2.0
        margin = 0.15
        wx1, wy1 = cx - bw * (0.5 + margin), cy - bh * (0.5 + margin)
        wx2, wy2 = cx + bw * (0.5 + margin), cy + bh * (0.5 + margin)
        scale = 128.0 / bh
        matrix = np.array([[scale, 0.0, -wx1 * scale], [0.0, scale, -wy1 * scale]])
        size = (int(round((wx2 - wx1) * scale)), int(round((wy2 - wy1) * scale)))
        gray = cv2.cvtColor(as_rgb(image), cv2.COLOR_RGB2GRAY)
        patch = cv2.warpAffine(gray, matrix, size, flags=cv2.INTER_LINEAR, borderMode=cv2.BORDER_REPLICATE)
        _, weights = self._hog.detect(patch, hitThreshold=-1e3, winStride=(8, 8), padding=(0, 0))
        weights = np.asarray(weights, np.float64).reshape(-1)
        return float(sigmoid(weights.max())) if len(weights) else 0.0
