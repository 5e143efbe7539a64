"""Data association: Algorithm 1 of Pinto's thesis (III-D), the position-only fallback, and the
robust profile's assignment on log-odds (:func:`match_log_odds`). Cost matrices are (N detections,
T tracks), from broadcasting; the one Python loop is over the thesis's galleries, a product each.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from scipy.optimize import linear_sum_assignment
from scipy.stats import chi2

from services.tracker.core.gallery import Gallery

__all__ = [
    "AppearanceGate",
    "appearance_cost",
    "chi2_gate",
    "gate_appearance",
    "gate_position",
    "innovation_distance",
    "match",
    "match_log_odds",
    "spatial_distance",
]


@dataclass(frozen=True)
class AppearanceGate:
    """Algorithm 1's thresholds, on the embedding model's distance scale: ``s_max`` bounds the squared
    Mahalanobis distance on (x, y); ``inf`` is the cost of an inadmissible pair (1e5 in the thesis)."""

    t_lower: float
    t_upper: float
    s_max: float = 0.05
    inf: float = 1e5

    def __post_init__(self) -> None:
        if not 0 <= self.t_lower < self.t_upper:
            raise ValueError(f"need 0 <= t_lower < t_upper, got {self.t_lower}, {self.t_upper}")
        if self.s_max < 0:
            raise ValueError(f"s_max must not be negative, got {self.s_max}")


def appearance_cost(descriptors: np.ndarray, galleries: Sequence[Gallery]) -> np.ndarray:
    """``C[d, t]`` (N, T): the smallest Euclidean distance from ``descriptors[d]`` (N, D) to track t's
    gallery; ``nan`` for a detection without a (finite) descriptor or an empty gallery."""
    n = len(descriptors)
    cost = np.full((n, len(galleries)), np.nan)
    if n == 0 or not galleries:
        return cost
    valid = np.all(np.isfinite(descriptors), axis=1)
    if not valid.any():
        return cost
    x = np.asarray(descriptors[valid], dtype=np.float32)
    for t, gallery in enumerate(galleries):
        if len(gallery):
            cost[valid, t] = gallery.min_distances(x)
    return cost


def spatial_distance(positions_xy: np.ndarray, means_xy: np.ndarray, covs_xy: np.ndarray) -> np.ndarray:
    """``S[d, t]`` (N, T): the squared Mahalanobis distance on (x, y) of ``positions_xy`` (N, 2) from
    ``means_xy`` (T, 2) with the tracks' covariances ``covs_xy`` (T, 2, 2)."""
    diff = positions_xy[:, None, :] - means_xy[None, :, :]  # (N, T, 2)
    inv = np.linalg.inv(covs_xy) if len(covs_xy) else np.zeros((0, 2, 2))
    return np.einsum("ntj,tjk,ntk->nt", diff, inv, diff)


def innovation_distance(positions: np.ndarray, means: np.ndarray, covs: np.ndarray, r: np.ndarray) -> np.ndarray:
    """:func:`spatial_distance` (N, T) with the innovation covariance ``S = HPH^T + R`` (``covs`` (T, 6,
    6), ``r`` (3, 3))."""
    s = covs[:, :2, :2] + r[:2, :2]
    return spatial_distance(positions[:, :2], means[:, :2], s)


def gate_appearance(cost: np.ndarray, spatial: np.ndarray, gate: AppearanceGate) -> np.ndarray:
    """Algorithm 1, lines 7-12, on a copy of ``cost``: inadmissible where ``C >= t_upper``, or in the
    ambiguous band ``t_lower < C < t_upper`` without spatial confirmation (``S > s_max``). A ``nan``
    cost (no descriptor, or a track without one yet) counts as the band's middle: only spatial
    closeness can admit the pair."""
    c = np.where(np.isnan(cost), 0.5 * (gate.t_lower + gate.t_upper), cost)
    band = (c > gate.t_lower) & (c < gate.t_upper) & (spatial > gate.s_max)
    return np.where(band | (c >= gate.t_upper), gate.inf, c)


def chi2_gate(probability: float, dof: int = 2) -> float:
    """The squared-Mahalanobis threshold holding ``probability`` of a ``dof``-D Gaussian."""
    return float(chi2.ppf(probability, dof))


def gate_position(spatial: np.ndarray, threshold: float, inf: float = 1e5) -> np.ndarray:
    """Position-only cost: the squared Mahalanobis distance, ``inf`` beyond ``threshold``."""
    return np.where(spatial > threshold, inf, spatial)


def match(cost: np.ndarray, inf: float = 1e5) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Hungarian assignment on ``cost`` (N, T), pairs costing ``inf`` undone: ``matches`` (K, 2) rows
    of (detection, track), the unmatched detections and the unmatched tracks (ascending)."""
    n, t = cost.shape
    if n == 0 or t == 0:
        return np.zeros((0, 2), np.int64), np.arange(n, dtype=np.int64), np.arange(t, dtype=np.int64)
    rows, cols = linear_sum_assignment(cost)
    keep = cost[rows, cols] < inf
    matches = np.stack([rows[keep], cols[keep]], axis=1).astype(np.int64)
    free_d, free_t = np.ones(n, bool), np.ones(t, bool)
    free_d[matches[:, 0]] = False
    free_t[matches[:, 1]] = False
    unmatched_d, unmatched_t = np.flatnonzero(free_d).astype(np.int64), np.flatnonzero(free_t).astype(np.int64)
    return matches, unmatched_d, unmatched_t


def match_log_odds(log_odds: np.ndarray, dets: list[int], tracks: list[int]) -> list[tuple[int, int]]:
    """The pairs (detection, track) of ``dets`` x ``tracks`` with the largest total log-odds
    (``log_odds`` (N, T)), among the pairs with positive log-odds: a pair at or below 0 is
    worth no more than explaining the detection as clutter or a new person (Ban et al.)."""
    if not dets or not tracks:
        return []
    n, t = log_odds.shape
    all_d, all_t = len(dets) == n and dets == list(range(n)), len(tracks) == t and tracks == list(range(t))
    sub = log_odds if all_d and all_t else log_odds[dets][:, tracks]  # no copies when every pair takes part
    if len(dets) == 1 or len(tracks) == 1:  # no assignment problem: the best positive pair
        i, j = divmod(int(np.argmax(sub)), len(tracks))
        return [(dets[i], tracks[j])] if sub[i, j] > 0 else []
    allowed = sub > 0
    if not allowed.any():
        return []
    cost = np.where(allowed, -sub, 0.0)  # a disallowed pair is worth as much as no pair
    rows, cols = linear_sum_assignment(cost)
    return [(dets[i], tracks[j]) for i, j in zip(rows.tolist(), cols.tolist()) if allowed[i, j]]
