"""Per-track online appearance classifiers (Basso/Munaro's online colour classifier, an equivalent).

Basso and Munaro keep one online AdaBoost per track on colour histograms: the track's own
detections its positives, the other people's its negatives, and a new track's first frames are
scored by the missing tracks' classifiers, so a person who was fully occluded gets their ID back.
Here each track keeps an online **logistic regression** on the embedder's descriptors (any
descriptor, not only colour): ``score(x) = w . u(x) + b`` with ``u(x) = x / |x|``, the log-odds
that ``x`` shows this track's person (untrained: 0, "no information", as a missing cue in TU
Ilmenau's fusion). One SGD step per frame in which the track is matched with a descriptor while
someone else is described too: its detection the positive, the others the negatives, each side
weighing the same in total, an L2 penalty keeping ``w`` bounded; a person alone in view teaches
nothing. Where the gallery says how like *any* past view of the person a descriptor is, the
classifier learns *which* features tell them from the people around them (the one colour that
differs between two people in similar clothes).

Pure numpy; all tracks' classifiers are trained and evaluated in one matrix product.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import TYPE_CHECKING

import numpy as np

from services.tracker.core.cues.base import Cue, Pairing
from services.tracker.core.tracks import ArrayColumns

if TYPE_CHECKING:
    from services.tracker.core.tracks import RobustTrackerState, TrackTable

__all__ = ["ClassifierColumns", "ClassifierParams", "OnlineClassifierCue", "classifier_log_odds", "normalise", "scores",
           "train", "trained"]


@dataclass(frozen=True)
class ClassifierParams:
    """``rate``: SGD step; ``l2``: weight decay per step; ``clip``: bound on a score's log-odds;
    ``weight``: its weight in the association's log-odds (0 turns the classifiers off), and
    in the ID memory's recovery (a remembered person's classifier's mean log-odds over a new
    track's views, core/recovery.py)."""

    rate: float = 1.0
    l2: float = 0.003
    clip: float = 4.0
    weight: float = 0.5

    def __post_init__(self) -> None:
        if not (self.rate > 0 and 0 <= self.l2 < 1 and self.clip > 0 and self.weight >= 0):
            raise ValueError("need rate > 0, 0 <= l2 < 1, clip > 0 and weight >= 0")


def normalise(x: np.ndarray) -> np.ndarray:
    """Rows of ``x`` scaled to unit length (zero rows stay zero): (N, D) float64."""
    x = np.asarray(x, np.float64)
    norm = np.sqrt(np.add.reduce(x * x, axis=1, keepdims=True))  # np.linalg.norm's sum, without its checks
    if norm.all():  # the usual case: no zero row
        return x / norm
    return np.divide(x, norm, out=np.zeros_like(x), where=norm > 0)


def scores(weights: np.ndarray, u: np.ndarray, clip: float) -> np.ndarray:
    """Log-odds (N, K) of unit descriptors ``u`` (N, D) under classifiers ``weights``
    (K, D + 1; the last column is the bias), clipped to ``[-clip, clip]``."""
    s = u @ weights[:, :-1].T + weights[:, -1]
    return np.clip(s, -clip, clip)


def train(weights: np.ndarray, u: np.ndarray, positive: np.ndarray, params: ClassifierParams) -> np.ndarray:
    """The weights (K, D + 1) after one SGD step of every classifier on the frame's unit descriptors
    ``u`` (N, D): row ``positive[k]`` classifier k's own detection, the others its negatives (none,
    N == 1: unchanged)."""
    k, n = len(weights), len(u)
    if k == 0 or n < 2:
        return weights
    s = u @ weights[:, :-1].T + weights[:, -1]  # unclipped, for the gradient
    np.negative(s, out=s)
    np.exp(s, out=s)
    s += 1.0
    p = np.reciprocal(s, out=s)  # (N, K) P(own person) of each descriptor
    # the error p - label, positives and negatives weighing the same in total: 1 and 1 / (n - 1) each
    cols = np.arange(k)
    own = p[positive, cols] - 1.0
    err = p
    err *= 1.0 / (n - 1)
    err[positive, cols] = own
    grad = np.empty_like(weights)
    grad[:, :-1] = err.T @ u
    grad[:, -1] = err.sum(axis=0)
    new = weights * (1.0 - params.l2)
    new[:, -1] = weights[:, -1]  # no decay on the bias
    return new - params.rate * grad

NAME = "classifier"


@dataclass
class ClassifierColumns(ArrayColumns):
    """``weights`` (T, D + 1), rows of zeros while untrained (None until the first is trained),
    and ``steps`` (T,) the training steps each has taken (0: untrained)."""

    weights: np.ndarray | None = None
    steps: np.ndarray = field(default_factory=lambda: np.zeros(0, np.int64))

    def rows(self, k: int) -> tuple[np.ndarray | None, np.ndarray]:
        return None if self.weights is None else np.zeros((k, self.weights.shape[1])), np.zeros(k, np.int64)

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


def classifier_log_odds(weights: np.ndarray | None, steps: np.ndarray, u: np.ndarray, has_desc: np.ndarray,
                        clip: float) -> np.ndarray:
    """(N, T) the tracks' online classifiers' log-odds (Basso/Munaro) of the unit descriptors
    ``u`` (one row per detection with ``has_desc``): 0 for an untrained classifier (``steps``
    0: no training step yet) or a detection without a descriptor."""
    cols = np.flatnonzero(steps).tolist()
    if len(cols) == len(steps) and len(u) == len(has_desc) and weights is not None:
        return scores(weights, u, clip)  # every classifier trained, every detection described
    out = np.zeros((len(has_desc), len(steps)))
    if len(cols) and weights is not None:
        out[np.ix_(np.flatnonzero(has_desc), cols)] = scores(weights[cols], u, clip)
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
            cols.weights, cols.steps = np.zeros((len(t), dim + 1)), np.zeros(len(t), np.int64)
        learners = [j for _, j in pairs]
        positive = np.array([r for r, _ in pairs])
        if learners == list(range(len(t))):  # every track learns: new weights, no gather
            cols.weights = train(cols.weights, u, positive, self.params)
        else:
            cols.weights[learners] = train(cols.weights[learners], u, positive, self.params)
        cols.steps[learners] += 1  # distinct tracks: one match each
