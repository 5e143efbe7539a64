"""Pairwise distance matrices fed to the metrics core (vectorised, no gating)."""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

__all__ = ["euclidean_distances", "iou_distances"]


def euclidean_distances(gt: NDArray[np.float64], hyp: NDArray[np.float64]) -> NDArray[np.float64]:
    """Euclidean distances (N, M) between points ``gt`` (N, D) and ``hyp`` (M, D)."""
    delta = gt[:, None, :] - hyp[None, :, :]
    return np.sqrt(np.einsum("nmd,nmd->nm", delta, delta))


def iou_distances(gt: NDArray[np.float64], hyp: NDArray[np.float64]) -> NDArray[np.float64]:
    """``1 - IoU`` (N, M) between boxes ``gt`` (N, 4) and ``hyp`` (M, 4) given as (left, top, width, height).

    Boxes are continuous rectangles (no +1 pixel convention), as in py-motmetrics; a pair
    with no overlap, or with an empty union, has IoU 0.
    """
    a_min, a_max = gt[:, None, :2], gt[:, None, :2] + gt[:, None, 2:]
    b_min, b_max = hyp[None, :, :2], hyp[None, :, :2] + hyp[None, :, 2:]
    inter = np.prod(np.maximum(np.minimum(a_max, b_max) - np.maximum(a_min, b_min), 0.0), axis=-1)
    area_a = np.prod(np.maximum(gt[:, 2:], 0.0), axis=-1)[:, None]
    area_b = np.prod(np.maximum(hyp[:, 2:], 0.0), axis=-1)[None, :]
    union = area_a + area_b - inter
    iou = np.divide(inter, union, out=np.zeros_like(inter), where=(inter > 0) & (union > 0))
    return 1.0 - iou
