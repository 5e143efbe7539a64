"""Pairwise distance and similarity matrices fed to the metrics core (vectorised, no gating)."""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

__all__ = ["distance_similarity", "euclidean_distances", "iou_distances", "iou_similarity"]


def euclidean_distances(gt: NDArray[np.float64], hyp: NDArray[np.float64]) -> NDArray[np.float64]:
    """Euclidean distances (N, M) between points ``gt`` (N, D) and ``hyp`` (M, D)."""
    delta = gt[:, None, :] - hyp[None, :, :]
    return np.sqrt(np.einsum("nmd,nmd->nm", delta, delta))


def iou_similarity(gt: NDArray[np.float64], hyp: NDArray[np.float64]) -> NDArray[np.float64]:
    """IoU (N, M) between boxes ``gt`` (N, 4) and ``hyp`` (M, 4) given as (left, top, width, height).

    Boxes are continuous rectangles (no +1 pixel convention), as in py-motmetrics and
    TrackEval; a pair with no overlap, or with an empty union, has IoU 0.
    """
    a_min, a_max = gt[:, None, :2], gt[:, None, :2] + gt[:, None, 2:]
    b_min, b_max = hyp[None, :, :2], hyp[None, :, :2] + hyp[None, :, 2:]
    inter = np.prod(np.maximum(np.minimum(a_max, b_max) - np.maximum(a_min, b_min), 0.0), axis=-1)
    area_a = np.prod(np.maximum(gt[:, 2:], 0.0), axis=-1)[:, None]
    area_b = np.prod(np.maximum(hyp[:, 2:], 0.0), axis=-1)[None, :]
    union = area_a + area_b - inter
    return np.divide(inter, union, out=np.zeros_like(inter), where=(inter > 0) & (union > 0))


def iou_distances(gt: NDArray[np.float64], hyp: NDArray[np.float64]) -> NDArray[np.float64]:
    """``1 - IoU`` (N, M) between boxes ``gt`` (N, 4) and ``hyp`` (M, 4) given as (left, top, width, height)."""
    return 1.0 - iou_similarity(gt, hyp)


def distance_similarity(dist: NDArray[np.float64], zero_distance: float) -> NDArray[np.float64]:
    """``max(0, 1 - d / zero_distance)``: TrackEval's similarity of points (``_calculate_euclidean_similarity``).

    TrackEval's default ``zero_distance`` is 2 m, so that a similarity of 0.5 is a 1 m
    distance; the tracks format uses twice its match threshold.
    """
    return np.maximum(0.0, 1.0 - np.asarray(dist, dtype=np.float64) / zero_distance)
