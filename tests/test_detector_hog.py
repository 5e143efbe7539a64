"""hog backend: precision/recall on real PETS09 frames, NMS, score range."""

from __future__ import annotations

from pathlib import Path

import cv2
import numpy as np
import pytest
from scipy.optimize import linear_sum_assignment

from services.detector.core.boxes import iou_matrix, nms
from services.detector.core.hog import HogDetector, HogParams

#: Measured with these settings on the four frames: precision 1.00 (15/15), recall 0.83 (15/18).
PETS09 = HogParams(upsample=2.25)
PRECISION_FLOOR = 0.90
RECALL_FLOOR = 0.75
GT_SCALE = 0.625  # ground truth is in the original 768x576 pixels, the frames are 480x360


def load_pets09(root: Path) -> list[tuple[np.ndarray, np.ndarray]]:
    """(RGB frame (H, W, 3), ground-truth boxes (M, 4) xyxy in its pixels) per frame."""
    folder = root / "pets09"
    if not (folder / "gt.txt").is_file():
        pytest.skip(f"PETS09 frames not found in {folder}")
    gt: dict[int, list[list[float]]] = {}
    for line in (folder / "gt.txt").read_text().splitlines():
        frame, _, x, y, w, h = (float(v) for v in line.split(",")[:6])
        gt.setdefault(int(frame), []).append([x, y, x + w, y + h])
    out = []
    for frame, boxes in sorted(gt.items()):
        bgr = cv2.imread(str(folder / f"frame_{frame:04d}.png"))
        assert bgr is not None, f"cannot read frame {frame}"
        out.append((cv2.cvtColor(bgr, cv2.COLOR_BGR2RGB), np.array(boxes) * GT_SCALE))
    return out


def match_counts(boxes: np.ndarray, gt: np.ndarray, iou: float = 0.5) -> tuple[int, int, int]:
    """(true positives, false positives, false negatives) under one-to-one matching at IoU >= ``iou``."""
    if len(boxes) == 0:
        return 0, 0, len(gt)
    m = iou_matrix(boxes, gt)
    rows, cols = linear_sum_assignment(-m)
    tp = int((m[rows, cols] >= iou).sum())
    return tp, len(boxes) - tp, len(gt) - tp


def test_pets09_precision_recall(shared_data: Path) -> None:
    detector = HogDetector(PETS09)
    tp = fp = fn = 0
    for rgb, gt in load_pets09(shared_data):
        boxes, scores = detector.detect(rgb)
        assert boxes.dtype == np.float32 and scores.dtype == np.float32
        assert np.all((scores >= 0) & (scores <= 1))
        assert np.all(np.diff(scores) <= 0), "best first"
        a, b, c = match_counts(boxes, gt)
        tp, fp, fn = tp + a, fp + b, fn + c
    precision, recall = tp / max(tp + fp, 1), tp / (tp + fn)
    assert precision >= PRECISION_FLOOR, f"precision {precision:.2f} (tp {tp}, fp {fp})"
    assert recall >= RECALL_FLOOR, f"recall {recall:.2f} (tp {tp}, fn {fn})"


def test_raw_windows_without_nms_are_worse(shared_data: Path) -> None:
    """The reason for NMS: the raw windows around each person are many and overlapping."""
    detector = HogDetector(PETS09)
    rgb, gt = load_pets09(shared_data)[2]
    windows, _ = detector.windows(rgb)
    boxes, _ = detector.detect(rgb)
    assert len(windows) > 2 * len(boxes)
    assert len(boxes) <= len(gt) + 2


def test_no_people_at_native_scale_in_small_frame(shared_data: Path) -> None:
    """People of ~50 px are below the 64x128 window: upsampling is what finds them."""
    rgb, _ = load_pets09(shared_data)[0]
    assert len(HogDetector(HogParams(upsample=1.0)).detect(rgb)[0]) < len(HogDetector(PETS09).detect(rgb)[0])


def test_nms_keeps_best_of_overlapping() -> None:
    boxes = np.array([[0, 0, 10, 20], [1, 1, 11, 21], [50, 50, 60, 70], [51, 50, 61, 70], [100, 0, 110, 20]], float)
    scores = np.array([0.9, 0.95, 0.5, 0.4, 0.1])
    assert nms(boxes, scores, 0.5).tolist() == [1, 2, 4]
    assert nms(boxes, scores, 0.5, score_threshold=0.3).tolist() == [1, 2]
    assert nms(boxes, scores, 0.5, max_detections=1).tolist() == [1]
    assert nms(boxes, -scores, 0.5).tolist() == [4, 3, 0]  # raw margins may be negative
    assert nms(np.zeros((0, 4)), np.zeros(0), 0.5).tolist() == []


def test_blank_image_has_no_detections() -> None:
    boxes, scores = HogDetector().detect(np.full((240, 320, 3), 128, np.uint8))
    assert boxes.shape == (0, 4) and scores.shape == (0,)


def test_image_smaller_than_window() -> None:
    boxes, _ = HogDetector().detect(np.zeros((40, 30, 3), np.uint8))
    assert boxes.shape == (0, 4)
