"""The online classifier cue (Basso/Munaro's per-track online classifier;
:mod:`services.tracker.core.classifier` is its math): each track learns which features tell its
person from the others in view, and scores every detection by them. A deleted track's weights
go to ``state.classifiers`` with its gallery (the ID memory's recovery reads them)."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import TYPE_CHECKING

import numpy as np

from services.tracker.core import classifier as clf
from services.tracker.core.cues.base import Cue, Pairing

if TYPE_CHECKING:
    from services.tracker.core.classifier import ClassifierParams
    from services.tracker.core.tracks import RobustTrackerState, TrackTable

__all__ = ["ClassifierColumns", "OnlineClassifierCue", "classifier_log_odds", "trained"]

NAME = "classifier"


@dataclass
class ClassifierColumns:
    """``weights`` (T, D + 1), rows of zeros while untrained (None until the first is trained),
    and ``steps`` (T,) the training steps each has taken (0: untrained)."""

    weights: np.ndarray | None = None
    steps: list[int] = field(default_factory=list)

    def append(self, k: int) -> None:
        if self.weights is not None:
            self.weights = np.concatenate([self.weights, np.zeros((k, self.weights.shape[1]))])
        self.steps += [0] * k

    def keep(self, idx: np.ndarray) -> None:
        if self.weights is not None:
            self.weights = self.weights[idx]
        steps = self.steps
        self.steps = [steps[j] for j in idx.tolist()]

    def copy(self) -> ClassifierColumns:
        return ClassifierColumns(None if self.weights is None else self.weights.copy(), list(self.steps))

    def merge(self, j: int, old: int) -> None:
        if self.steps[old] and self.steps[j] == 0 and self.weights is not None:
            self.weights[j], self.steps[j] = self.weights[old], self.steps[old]

    def clear(self, j: int) -> None:
        if self.weights is not None:
            self.weights[j] = 0.0
        self.steps[j] = 0


def trained(t: TrackTable, j: int) -> np.ndarray | None:
    """Track ``j``'s trained classifier (a copy), None when it has none."""
    cols = t.extra.get(NAME)
    if cols is None or cols.weights is None or not cols.steps[j]:  # type: ignore[attr-defined]
        return None
    return cols.weights[j].copy()  # type: ignore[attr-defined]


def classifier_log_odds(weights: np.ndarray | None, steps: list[int], u: np.ndarray, has_desc: np.ndarray,
                        clip: float) -> np.ndarray:
    """(N, T) the tracks' online classifiers' log-odds (Basso/Munaro) of the unit descriptors
    ``u`` (one row per detection with ``has_desc``): 0 for an untrained classifier (``steps``
    0: no training step yet) or a detection without a descriptor."""
    cols = [j for j, k in enumerate(steps) if k]
    if len(cols) == len(steps) and len(u) == len(has_desc) and weights is not None:
        return clf.scores(weights, u, clip)  # every classifier trained, every detection described
    out = np.zeros((len(has_desc), len(steps)))
    if len(cols) and weights is not None:
        out[np.ix_(np.flatnonzero(has_desc), cols)] = clf.scores(weights[cols], u, clip)
    return out


class OnlineClassifierCue(Cue):
    """``weight`` x the track's classifier's log-odds of the detection's unit descriptor; one
    training step for every track matched with a confident descriptor while someone else is
    described in the frame (its detection the positive, the others the negatives); a forgotten
    person's track learns nothing."""

    name = NAME

    def __init__(self, params: ClassifierParams) -> None:
        self.params = params

    def columns(self) -> ClassifierColumns:
        return ClassifierColumns()

    def log_odds(self, pairing: Pairing, state: RobustTrackerState) -> np.ndarray | None:
        if pairing.u is None or not self.params.weight > 0:
            return None
        cols: ClassifierColumns = state.tracks.extra[NAME]  # type: ignore[assignment]
        return self.params.weight * classifier_log_odds(cols.weights, cols.steps, pairing.u, pairing.has_desc,
                                                        self.params.clip)

    def learn(self, pairing: Pairing, state: RobustTrackerState, rows: np.ndarray) -> None:
        u, has_desc, t = pairing.u, pairing.has_desc, state.tracks
        if u is None or has_desc.sum() < 2:
            return
        row_of, sure = (np.cumsum(has_desc) - 1).tolist(), (has_desc & pairing.confident).tolist()  # detection -> its row of u
        pairs = [(row_of[d], j) for d, j in zip(*rows.tolist()) if sure[d] and not t.forgotten[j]]
        if not pairs:
            return
        cols: ClassifierColumns = t.extra[NAME]  # type: ignore[assignment]
        dim = u.shape[1]
        if cols.weights is None or cols.weights.shape[1] != dim + 1:
            cols.weights, cols.steps = np.zeros((len(t), dim + 1)), [0] * len(t)
        learners = [j for _, j in pairs]
        positive = np.array([r for r, _ in pairs])
        if learners == list(range(len(t))):  # every track learns: new weights, no gather
            cols.weights = clf.train(cols.weights, u, positive, self.params)
        else:
            cols.weights[learners] = clf.train(cols.weights[learners], u, positive, self.params)
        steps = cols.steps
        for j in learners:
            steps[j] += 1
