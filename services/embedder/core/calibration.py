"""Same-person and different-person distance distributions, and tracker thresholds from them.

The tracker (SPEC §3) accepts an association on appearance alone below ``t_lower``,
needs spatial confirmation between ``t_lower`` and ``t_upper``, refuses at or above
``t_upper``, and re-uses a remembered ID below ``t_recover``. From labelled crops:

* ``t_upper`` = the 99th percentile of same-person distances: at most 1 % of true
  matches are vetoed by appearance;
* ``t_lower`` = the 1st percentile of different-person distances: at most 1 % of
  pairs of different people are accepted on appearance alone;
* ``t_recover`` = the 5th percentile of different-person distances, kept within
  [t_lower, t_upper]: a remembered ID is wrongly recalled for at most 5 % of pairs.

When the two distributions do not overlap (``t_lower`` would exceed ``t_upper``), the
gap itself is used: ``t_lower`` = the same-person 99th percentile, ``t_upper`` = the
different-person 1st percentile, ``t_recover`` half-way.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

__all__ = ["PERCENTILES", "Calibration", "calibrate", "distance_matrix", "pair_distances", "suggest_thresholds"]

PERCENTILES = (1, 5, 10, 25, 50, 75, 90, 95, 99)


def distance_matrix(vectors: np.ndarray, metric: str = "euclidean") -> np.ndarray:
    """(N, N) distances of (N, D) vectors; "cosine" gives 1 - cosine similarity."""
    v = np.asarray(vectors, np.float64)
    if metric == "cosine":
        u = v / np.maximum(np.linalg.norm(v, axis=1, keepdims=True), 1e-12)
        return 1.0 - u @ u.T
    sq = np.sum(v * v, axis=1)
    return np.sqrt(np.maximum(sq[:, None] + sq[None, :] - 2.0 * v @ v.T, 0.0))


def pair_distances(vectors: np.ndarray, labels: np.ndarray, metric: str = "euclidean") -> tuple[np.ndarray, np.ndarray]:
    """Distances of all unordered pairs of (N, D) ``vectors``, split by (N,) ``labels``.

    Returns (same-person distances, different-person distances), both 1-D float64.
    """
    d = distance_matrix(vectors, metric)
    iu = np.triu_indices(len(d), 1)
    lab = np.asarray(labels)
    same = (lab[:, None] == lab[None, :])[iu]
    return d[iu][same], d[iu][~same]


def suggest_thresholds(same: np.ndarray, different: np.ndarray) -> tuple[float, float, float]:
    """(t_lower, t_upper, t_recover) by the rules in the module docstring."""
    if len(same) == 0 or len(different) == 0:
        raise ValueError("need at least one same-person and one different-person pair")
    same_hi = float(np.percentile(same, 99))
    diff_lo = float(np.percentile(different, 1))
    if diff_lo > same_hi:
        return same_hi, diff_lo, 0.5 * (same_hi + diff_lo)
    recover = float(np.clip(np.percentile(different, 5), diff_lo, same_hi))
    return diff_lo, same_hi, recover


@dataclass(frozen=True)
class Calibration:
    """Distance distributions of one model on one labelled set."""

    same: np.ndarray
    different: np.ndarray
    thresholds: tuple[float, float, float]
    auc: float
    rank1: float

    def percentiles(self) -> dict[str, list[float]]:
        return {"same": [float(np.percentile(self.same, p)) for p in PERCENTILES],
                "different": [float(np.percentile(self.different, p)) for p in PERCENTILES]}


def calibrate(vectors: np.ndarray, labels: np.ndarray, metric: str = "euclidean") -> Calibration:
    """Distributions, suggested thresholds, pair AUC and rank-1 of (N, D) ``vectors``.

    AUC: probability that a random same-person pair is closer than a random
    different-person pair. Rank-1: share of crops (whose person appears more than
    once) whose nearest other crop is the same person.
    """
    labels = np.asarray(labels)
    same, diff = pair_distances(vectors, labels, metric)
    thresholds = suggest_thresholds(same, diff)
    order = np.sort(diff)
    auc = float(np.mean(len(order) - np.searchsorted(order, same, side="right")) / len(order))
    d = distance_matrix(vectors, metric)
    np.fill_diagonal(d, np.inf)
    repeated = np.array([(labels == x).sum() > 1 for x in labels])
    rank1 = float(np.mean((labels[d.argmin(axis=1)] == labels)[repeated])) if repeated.any() else float("nan")
    return Calibration(same=same, different=diff, thresholds=thresholds, auc=auc, rank1=rank1)
