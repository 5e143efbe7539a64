"""The stature cue (:mod:`services.tracker.core.stature` is its math, a soft biometric): each
track learns how tall its person stands from its confident detections, and a detection of
someone taller or shorter weighs against it."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import TYPE_CHECKING

import numpy as np

from services.tracker.core import stature
from services.tracker.core.cues.base import Cue, Pairing

if TYPE_CHECKING:
    from services.tracker.core.stature import StatureParams
    from services.tracker.core.tracks import RobustTrackerState, TrackTable

__all__ = ["StatureColumns", "StatureCue", "stature_of"]

NAME = "stature"


@dataclass
class StatureColumns:
    """``est`` (T,) each track's stature (m) and ``n`` (T,) how many measurements it holds."""

    est: np.ndarray = field(default_factory=lambda: np.zeros(0))
    n: np.ndarray = field(default_factory=lambda: np.zeros(0, np.int64))

    def append(self, k: int) -> None:
        self.est = np.concatenate([self.est, np.zeros(k)])
        self.n = np.concatenate([self.n, np.zeros(k, np.int64)])

    def keep(self, idx: np.ndarray) -> None:
        self.est, self.n = self.est[idx], self.n[idx]

    def copy(self) -> StatureColumns:
        return StatureColumns(self.est.copy(), self.n.copy())

    def merge(self, j: int, old: int) -> None:
        n_old, n_new = int(self.n[old]), int(self.n[j])
        if n_old:  # the measurements of both, weighed by their counts
            self.est[j] = (self.est[old] * n_old + self.est[j] * n_new) / (n_old + n_new)
            self.n[j] = n_old + n_new

    def clear(self, j: int) -> None:
        self.n[j] = 0


def stature_of(t: TrackTable, j: int) -> tuple[float, int]:
    """Track ``j``'s stature and its count of measurements (0, 0: none)."""
    cols = t.extra.get(NAME)
    n = int(cols.n[j]) if cols is not None else 0  # type: ignore[attr-defined]
    return (float(cols.est[j]) if n else 0.0), n  # type: ignore[union-attr]


class StatureCue(Cue):
    """The log-odds of each detection's stature under the track's (:func:`stature.log_odds`);
    a matched track learns its confident detection's stature (a forgotten person's learns none),
    a new track starts with its detection's."""

    name = NAME

    def __init__(self, params: StatureParams) -> None:
        self.params = params

    def columns(self) -> StatureColumns:
        return StatureColumns()

    def log_odds(self, pairing: Pairing, state: RobustTrackerState) -> np.ndarray | None:
        statures = pairing.frame.statures
        if statures is None:
            return None
        cols: StatureColumns = state.tracks.extra[NAME]  # type: ignore[assignment]
        return stature.log_odds(statures, cols.est, cols.n, self.params)

    def learn(self, pairing: Pairing, state: RobustTrackerState, rows: np.ndarray) -> None:
        statures, t = pairing.frame.statures, state.tracks
        if statures is None or not rows.shape[1]:
            return
        d_idx, t_idx = rows
        ok = pairing.confident[d_idx] & ~np.array([t.forgotten[j] for j in t_idx.tolist()], bool)
        cols: StatureColumns = t.extra[NAME]  # type: ignore[assignment]
        cols.est, cols.n = stature.observe(cols.est, cols.n, t_idx[ok], statures[d_idx][ok], self.params)

    def born(self, pairing: Pairing, state: RobustTrackerState, first: int, dets: np.ndarray) -> None:
        statures = pairing.frame.statures
        if statures is None:
            return
        cols: StatureColumns = state.tracks.extra[NAME]  # type: ignore[assignment]
        h = statures[dets]  # the new rows' arrays are this frame's own (the table's append made them)
        known = np.flatnonzero(np.isfinite(h))
        cols.est[first + known], cols.n[first + known] = h[known], 1
