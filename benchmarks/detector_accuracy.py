"""Detector accuracy on ``pets09_dev``: PASCAL-VOC AP at IoU >= 0.5 and the foot-point error.

* Ground truth: ``gt.txt`` boxes times 0.625 (they are in 768x576 pixels). Rows with
  ``conf = 0`` are don't-care: a detection matching one (IoU >= 0.5) is neither a true
  nor a false positive.
* AP: detections of all frames sorted by score, each matched greedily to the unmatched
  ground-truth box of its frame it overlaps most; all-point interpolated precision.
* Foot-point error: each true positive's foot point (bottom centre of the box) mapped
  to the ground plane through ``ground_homography.json``, against the person's
  ``world_x, world_y``; median and mean in metres. The homography itself has a median
  error of 0.025 m on the ground-truth boxes.
"""

from __future__ import annotations

import json
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from services.localizer.core import FloorHomography, foot_points

__all__ = ["PetsTruth", "Scores", "load_truth", "score_detections", "to_ground"]

GT_SCALE = 0.625


@dataclass
class PetsTruth:
    """Per frame: ``boxes`` (M, 4) xyxy in frame pixels, ``world`` (M, 2) m, ``care`` (M,) bool."""

    boxes: dict[int, np.ndarray]
    world: dict[int, np.ndarray]
    care: dict[int, np.ndarray]
    H: np.ndarray


@dataclass(frozen=True)
class Scores:
    ap: float
    precision: float  # at the detector's own operating point (every box given)
    recall: float
    foot_median_m: float
    foot_mean_m: float
    true_positives: int


def load_truth(root: Path) -> PetsTruth:
    gt = np.loadtxt(root / "gt.txt", delimiter=",", ndmin=2)
    boxes, world, care = {}, {}, {}
    for frame in np.unique(gt[:, 0]).astype(int):
        r = gt[gt[:, 0] == frame]
        xywh = r[:, 2:6] * GT_SCALE
        boxes[frame] = np.column_stack([xywh[:, :2], xywh[:, :2] + xywh[:, 2:]])
        world[frame] = r[:, 7:9]
        care[frame] = r[:, 6] > 0
    H = np.asarray(json.loads((root / "ground_homography.json").read_text())["H"], np.float64)
    return PetsTruth(boxes, world, care, H)


def to_ground(H: np.ndarray, boxes: np.ndarray) -> np.ndarray:
    """(N, 2) ground-plane positions of the foot points (bottom centre) of (N, 4) xyxy boxes
    through ``H``: the localizer's own foot point and floor homography."""
    pixels, _ = foot_points(boxes)
    return FloorHomography(H).to_floor(pixels)[0]


def _iou(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    x1 = np.maximum(a[:, None, 0], b[None, :, 0])
    y1 = np.maximum(a[:, None, 1], b[None, :, 1])
    x2 = np.minimum(a[:, None, 2], b[None, :, 2])
    y2 = np.minimum(a[:, None, 3], b[None, :, 3])
    inter = np.clip(x2 - x1, 0, None) * np.clip(y2 - y1, 0, None)
    area = lambda x: (x[:, 2] - x[:, 0]) * (x[:, 3] - x[:, 1])  # noqa: E731
    return inter / np.maximum(area(a)[:, None] + area(b)[None] - inter, 1e-12)


def score_detections(truth: PetsTruth, dets: dict[int, tuple[np.ndarray, np.ndarray]], iou: float = 0.5) -> Scores:
    """AP, precision, recall and foot-point error of ``dets``: frame -> (boxes (N, 4) xyxy, scores (N,))."""
    records = []  # (score, is_tp, foot error or nan); don't-care matches left out
    n_care = sum(int(c.sum()) for f, c in truth.care.items() if f in dets)
    for frame, (boxes, scores) in dets.items():
        boxes = np.asarray(boxes, np.float64).reshape(-1, 4)
        gt = truth.boxes.get(frame, np.zeros((0, 4)))
        care = truth.care.get(frame, np.zeros(0, bool))
        order = np.argsort(-np.asarray(scores), kind="stable")
        taken = np.zeros(len(gt), bool)
        m = _iou(boxes, gt) if len(gt) and len(boxes) else np.zeros((len(boxes), len(gt)))
        ground = to_ground(truth.H, boxes) if len(boxes) else np.zeros((0, 2))
        for i in order:
            cand = np.where(taken, -1.0, m[i]) if len(gt) else np.zeros(0)
            j = int(np.argmax(cand)) if len(cand) else -1
            if j >= 0 and cand[j] >= iou:
                taken[j] = True
                if care[j]:
                    err = float(np.linalg.norm(ground[i] - truth.world[frame][j]))
                    records.append((float(scores[i]), True, err))
                continue  # a don't-care match counts for nothing
            records.append((float(scores[i]), False, np.nan))
    if not records:
        return Scores(0.0, 0.0, 0.0, np.nan, np.nan, 0)
    rec = sorted(records, key=lambda r: -r[0])
    tp = np.array([r[1] for r in rec], np.float64)
    ctp, cfp = np.cumsum(tp), np.cumsum(1.0 - tp)
    recall = ctp / max(n_care, 1)
    precision = ctp / np.maximum(ctp + cfp, 1e-12)
    mrec = np.concatenate([[0.0], recall, [1.0]])
    mpre = np.concatenate([[0.0], precision, [0.0]])
    mpre = np.maximum.accumulate(mpre[::-1])[::-1]
    idx = np.flatnonzero(mrec[1:] != mrec[:-1])
    ap = float(np.sum((mrec[idx + 1] - mrec[idx]) * mpre[idx + 1]))
    errs = np.array([r[2] for r in rec if r[1]])
    return Scores(ap, float(precision[-1]), float(recall[-1]),
                  float(np.median(errs)) if len(errs) else np.nan, float(np.mean(errs)) if len(errs) else np.nan,
                  int(tp.sum()))
