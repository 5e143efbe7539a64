"""How far a detector's foot points stray: the floor paths' noise model, measured.

Without depth the localizer puts a person where the foot point (the bottom centre of the box)
meets the floor, with the foot pixel's variances ``sigma_px^2 + (share * h)^2`` across (u) and
down (v) for a box ``h`` pixels high (:func:`~services.localizer.core.floor.foot_variances`).
The shares depend on the detector: HOG's window, a YOLO box and a hand-drawn one err
differently. Here they are measured from the detector's boxes against ground-truth boxes of
the same images:

* **Matching.** In each frame, detections and ground-truth boxes are paired one to one by
  IoU (Hungarian, :func:`scipy.optimize.linear_sum_assignment`), pairs under ``min_iou``
  dropped.
* **Residuals.** Each pair's foot point, detection minus truth, in pixels; its bias (the mean
  residual as a share of the box's height, e.g. a window that reaches below the feet) is
  reported and taken off, since the noise model has none.
* **Fit.** The squared residuals against ``[1, h^2]`` by non-negative least squares
  (:func:`scipy.optimize.nnls`) give ``sigma_px^2`` and ``share^2`` per axis, after
  dropping residuals beyond ``clip`` robust standard deviations (1.4826 MAD, per height
  bin) as mismatches. ``sigma_px`` is at least ``min_sigma_px`` (the localizer needs it above 0).
* **Check.** Per height bin (quartiles of ``h``), the residuals' RMS against the fit's.

Pure numpy and scipy.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
from scipy.optimize import linear_sum_assignment, nnls

__all__ = ["FootNoise", "HeightBin", "fit_foot_noise", "match_boxes"]


@dataclass(frozen=True)
class HeightBin:
    """Matched boxes ``lo`` to ``hi`` pixels high: their count, the residuals' RMS (px) across
    and down, and what the fit predicts there (at the bin's RMS height)."""

    lo: float
    hi: float
    n: int
    rms_u_px: float
    rms_v_px: float
    fit_u_px: float
    fit_v_px: float


@dataclass(frozen=True)
class FootNoise:
    """The measured noise model: ``sigma_u_px``, ``sigma_v_px``, ``share_u``, ``share_v`` as
    :class:`~services.localizer.core.floor.FloorParams` takes them (``foot_sigma_*``);
    ``bias_u``, ``bias_v``: the mean residual as a share of the box's height (+: right,
    down); ``matched`` pairs used, ``dropped`` as mismatches; ``bins`` the check per height."""

    matched: int
    dropped: int
    sigma_u_px: float
    sigma_v_px: float
    share_u: float
    share_v: float
    bias_u: float
    bias_v: float
    bins: list[HeightBin] = field(default_factory=list)


def _iou(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """(N, M) IoU of xyxy boxes ``a`` (N, 4) and ``b`` (M, 4)."""
    lo = np.maximum(a[:, None, :2], b[None, :, :2])
    hi = np.minimum(a[:, None, 2:], b[None, :, 2:])
    inter = np.prod(np.clip(hi - lo, 0.0, None), axis=2)
    area_a = np.prod(a[:, 2:] - a[:, :2], axis=1)
    area_b = np.prod(b[:, 2:] - b[:, :2], axis=1)
    union = area_a[:, None] + area_b[None, :] - inter
    return np.where(union > 0, inter / np.where(union > 0, union, 1.0), 0.0)


def match_boxes(det_frames: np.ndarray, det_boxes: np.ndarray, gt_frames: np.ndarray, gt_boxes: np.ndarray,
                min_iou: float = 0.5) -> tuple[np.ndarray, np.ndarray]:
    """Indices ``(d, g)`` of the detections and ground-truth boxes (xyxy) paired one to one in
    each frame by the largest total IoU, each pair's IoU at least ``min_iou``."""
    if not 0.0 < min_iou <= 1.0:
        raise ValueError(f"min_iou must be in (0, 1], got {min_iou}")
    det_frames, gt_frames = np.asarray(det_frames).reshape(-1), np.asarray(gt_frames).reshape(-1)
    det_boxes = np.asarray(det_boxes, np.float64).reshape(-1, 4)
    gt_boxes = np.asarray(gt_boxes, np.float64).reshape(-1, 4)
    out_d: list[np.ndarray] = []
    out_g: list[np.ndarray] = []
    for frame in np.intersect1d(det_frames, gt_frames).tolist():
        di, gi = np.flatnonzero(det_frames == frame), np.flatnonzero(gt_frames == frame)
        iou = _iou(det_boxes[di], gt_boxes[gi])
        r, c = linear_sum_assignment(iou, maximize=True)
        keep = iou[r, c] >= min_iou
        out_d.append(di[r[keep]])
        out_g.append(gi[c[keep]])
    if not out_d:
        return np.zeros(0, np.int64), np.zeros(0, np.int64)
    return np.concatenate(out_d).astype(np.int64), np.concatenate(out_g).astype(np.int64)


def _robust_sd(x: np.ndarray) -> float:
    return 1.4826 * float(np.median(np.abs(x - np.median(x)))) if len(x) else 0.0


def fit_foot_noise(det_boxes: np.ndarray, gt_boxes: np.ndarray, clip: float = 5.0, min_sigma_px: float = 0.5,
                   bins: int = 4) -> FootNoise:
    """The foot pixel's noise model from matched boxes (xyxy, (K, 4) each, row k a pair; the
    height is the ground truth's); ValueError with fewer than 10 pairs."""
    det = np.asarray(det_boxes, np.float64).reshape(-1, 4)
    gt = np.asarray(gt_boxes, np.float64).reshape(-1, 4)
    if len(det) != len(gt):
        raise ValueError(f"need as many detections as ground-truth boxes, got {len(det)} and {len(gt)}")
    h = gt[:, 3] - gt[:, 1]
    ok = np.isfinite(det).all(axis=1) & np.isfinite(gt).all(axis=1) & (h > 0)
    det, gt, h = det[ok], gt[ok], h[ok]
    if len(h) < 10:
        raise ValueError(f"need at least 10 matched boxes to measure the foot point's noise, got {len(h)}")
    res = np.column_stack([0.5 * (det[:, 0] + det[:, 2]) - 0.5 * (gt[:, 0] + gt[:, 2]), det[:, 3] - gt[:, 3]])
    share = res / h[:, None]
    edges = np.unique(np.quantile(h, np.linspace(0.0, 1.0, bins + 1)))
    which = np.clip(np.searchsorted(edges, h, side="right") - 1, 0, max(len(edges) - 2, 0))
    keep = np.ones(len(h), bool)
    for b in np.unique(which).tolist():  # mismatches: far out of their height bin's spread
        m = which == b
        for axis in (0, 1):
            x = share[m, axis]
            sd = _robust_sd(x)
            if sd > 0:
                keep[np.flatnonzero(m)[np.abs(x - np.median(x)) > clip * sd]] = False
    bias = share[keep].mean(axis=0)
    e = res[keep] - bias[None, :] * h[keep, None]
    design = np.column_stack([np.ones(int(keep.sum())), h[keep] ** 2])
    coef = [nnls(design, e[:, axis] ** 2)[0] for axis in (0, 1)]
    sig_px = [max(min_sigma_px, math.sqrt(c[0])) for c in coef]
    shares = [math.sqrt(c[1]) for c in coef]
    checks = []
    for b in range(len(edges) - 1):
        m = keep & (which == b)
        if not m.any():
            continue
        eb = res[m] - bias[None, :] * h[m, None]
        hr = float(np.sqrt(np.mean(h[m] ** 2)))
        rms = np.sqrt(np.mean(eb ** 2, axis=0))
        fit = [math.sqrt(s * s + (f * hr) ** 2) for s, f in zip(sig_px, shares)]
        checks.append(HeightBin(float(edges[b]), float(edges[b + 1]), int(m.sum()), float(rms[0]), float(rms[1]),
                                fit[0], fit[1]))
    return FootNoise(int(keep.sum()), int((~keep).sum()), sig_px[0], sig_px[1], shares[0], shares[1],
                     float(bias[0]), float(bias[1]), checks)
