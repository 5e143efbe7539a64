"""The posture and orientation filters of the TU Ilmenau framework
(:mod:`services.tracker.core.posture` is their math): each track keeps P(standing, sitting,
lying) and P(orientation bin), which drift back towards "unknown" in time and learn from each
matched detection (its height and box shape; the walking direction or, standing still, the
embedder's orientation classifier). They say how a person is, not who: no log-odds."""

from __future__ import annotations

from dataclasses import dataclass, field
from functools import lru_cache
from typing import TYPE_CHECKING

import numpy as np

from services.tracker.core import posture as pose
from services.tracker.core.cues.base import Cue, Pairing
from services.tracker.core.types import TrackStatus

if TYPE_CHECKING:
    from services.tracker.core.posture import PostureParams
    from services.tracker.core.tracks import RobustTrackerState

__all__ = ["PostureColumns", "PostureCue"]

NAME = "posture"


@lru_cache(maxsize=64)
def _uniform_rows(k: int, n: int) -> np.ndarray:
    """``k`` uniform distributions over ``n`` values (k, n), read-only."""
    rows = np.tile(pose.uniform(n), (k, 1))
    rows.flags.writeable = False
    return rows


@dataclass
class PostureColumns:
    """``posture`` (T, 3) and ``orientation`` (T, 8), one distribution per track. A track shown in
    a view holds its rows: every change makes new arrays, except into arrays of this frame's own."""

    posture: np.ndarray = field(default_factory=lambda: np.zeros((0, 3)))
    orientation: np.ndarray = field(default_factory=lambda: np.zeros((0, pose.ORIENTATION_BINS)))

    def append(self, k: int) -> None:
        self.posture = np.concatenate([self.posture, _uniform_rows(k, 3)])
        self.orientation = np.concatenate([self.orientation, _uniform_rows(k, pose.ORIENTATION_BINS)])

    def keep(self, idx: np.ndarray) -> None:
        self.posture, self.orientation = self.posture[idx], self.orientation[idx]

    def copy(self) -> PostureColumns:
        return PostureColumns(self.posture.copy(), self.orientation.copy())

    def merge(self, j: int, old: int) -> None:
        return None  # how a person stands now is the new track's own

    def clear(self, j: int) -> None:
        return None  # a posture says nothing of who the person is


class PostureCue(Cue):
    """Drift every track's posture and orientation by ``dt`` (two products), and update the
    matched tracks' from their detections (:func:`posture.observe`)."""

    name = NAME

    def __init__(self, params: PostureParams) -> None:
        self.params = params
        self._dt, self._m = -1.0, (np.eye(3), np.eye(pose.ORIENTATION_BINS))  # drift matrices of the last dt

    def columns(self) -> PostureColumns:
        return PostureColumns()

    def predict(self, state: RobustTrackerState, dt: float) -> None:
        step = round(dt, 3)  # to the millisecond: the matrices are rebuilt only when the rate changes
        if step != self._dt:
            self._dt = step
            self._m = (pose.transition(3, step, self.params.posture_tau_s),
                       pose.transition(pose.ORIENTATION_BINS, step, self.params.orientation_tau_s, circular=True))
        cols: PostureColumns = state.tracks.extra[NAME]  # type: ignore[assignment]
        cols.posture, cols.orientation = cols.posture @ self._m[0], cols.orientation @ self._m[1]

    def learn(self, pairing: Pairing, state: RobustTrackerState, rows: np.ndarray) -> None:
        if not rows.shape[1]:
            return
        t, frame = state.tracks, pairing.frame
        d_idx, t_idx = rows
        cols: PostureColumns = t.extra[NAME]  # type: ignore[assignment]
        cols.posture, cols.orientation = pose.observe(
            cols.posture, cols.orientation, t_idx, pairing.positions[d_idx, 2],
            None if frame.aspects is None else frame.aspects[d_idx], t.mean[t_idx, 3:5],
            np.array([t.status[j] is TrackStatus.TENTATIVE for j in t_idx.tolist()]),
            None if frame.orientations is None else frame.orientations[d_idx], self.params, fresh=pairing.moved,
            reported=None if frame.postures is None else frame.postures[d_idx])
