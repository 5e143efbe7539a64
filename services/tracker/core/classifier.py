"""Per-track online appearance classifiers (Basso/Munaro's online colour classifier, an equivalent).

Basso and Munaro keep one online AdaBoost per track on colour histograms: the track's own
detections are its positives, the other people's detections its negatives, and during a
new track's first frames the classifiers of missing tracks score it, so a person who was
fully occluded gets their ID back. Here each track keeps an online **logistic
regression** on the embedder's descriptors instead (any descriptor, not only colour):

* ``score(x) = w . u(x) + b``, with ``u(x) = x / |x|``: the log-odds that descriptor
  ``x`` shows this track's person. An untrained classifier scores 0, "no information",
  which is what a missing cue contributes in TU Ilmenau's fusion.
* One stochastic gradient step per frame in which the track is matched with a descriptor
  **and** at least one other person is in view with a descriptor: the positive is the
  track's detection, the negatives are every other detection of the frame; positives and
  negatives weigh the same in total, and an L2 penalty (``l2``) keeps ``w`` bounded. A
  person alone in view teaches nothing: there is nobody to tell them from.
* Where the gallery's nearest-neighbour distance says how like *any* past view of the
  person a descriptor is, the classifier learns *which* features tell this person from
  the people around them, e.g. the one colour that differs between two people in
  similar clothes.

Pure numpy; all tracks' classifiers are trained and evaluated in one matrix product.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

__all__ = ["ClassifierParams", "normalise", "scores", "train"]


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
    """One SGD step of every classifier; returns the new weights (K, D + 1).

    ``u`` (N, D): the frame's unit descriptors; ``positive`` (K,): the row of ``u`` that is
    classifier k's own detection. Rows other than a classifier's positive are its
    negatives; a classifier with no negative (N == 1) is returned unchanged.
    """
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
