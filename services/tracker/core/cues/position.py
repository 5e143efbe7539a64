"""The position cue: where the track predicts the person, against someone else or clutter anywhere
(the TU Ilmenau framework's position likelihood), and the gate of every pair, with the detections'
measurement covariance (Basso/Munaro's sigma^2 = sigma_v^2 + sigma_d^2). :func:`usable_covariances`
is the project's one test of a detection's covariance (the service counts, the cores replace).
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING

import numpy as np

from services.tracker.core.cues.base import Cue, Pairing

if TYPE_CHECKING:
    from services.tracker.core.tracks import RobustTrackerState

__all__ = ["PositionCue", "measurement_covariance", "position_log_odds", "usable_covariances"]

_LOG_2PI = math.log(2.0 * math.pi)


def usable_covariances(covs: np.ndarray) -> np.ndarray:
    """(N,) bool: which covariances (N, 3, 3) are finite, symmetric and positive definite."""
    if not len(covs):
        return np.zeros(0, bool)
    finite = np.all(np.isfinite(covs), axis=(1, 2))
    safe = np.where(finite[:, None, None], covs, np.eye(3))
    sym = 0.5 * (safe + np.swapaxes(safe, 1, 2))
    symmetric = np.all(np.abs(safe - sym) <= 1e-9 + 1e-6 * np.abs(sym), axis=(1, 2))
    return finite & symmetric & np.all(np.linalg.eigvalsh(sym) > 0, axis=1)


def measurement_covariance(cov: np.ndarray | None, usable: np.ndarray | None, r: np.ndarray,
                           n: int) -> tuple[np.ndarray, int]:
    """Each detection's R (N, 3, 3) and how many covariances were unusable: with its own
    covariance ``cov`` where ``usable`` (None: :func:`usable_covariances` tells), ``r + cov``
    (Basso/Munaro's sigma^2 = sigma_v^2 + sigma_d^2: a fixed part, here the body's extent
    around the point the sensor saw, plus the sensor's own, which grows with distance^2);
    elsewhere, or without covariances, ``r``."""
    if cov is None:
        return np.broadcast_to(r, (n, 3, 3)), 0
    if usable is None:
        usable = usable_covariances(cov)
    sym = 0.5 * (cov + np.swapaxes(cov, 1, 2))
    return np.where(usable[:, None, None], sym + r, r), int(n - usable.sum())


def position_log_odds(positions: np.ndarray, r: np.ndarray, means_xy: np.ndarray, covs_xy: np.ndarray,
                      new_density: float) -> tuple[np.ndarray, np.ndarray]:
    """(N, T) log-likelihood ratio of each detection (N, 3) under each track's predicted
    Gaussian on (x, y) (innovation covariance ``S = HPH^T + R``; ``means_xy`` (T, 2),
    ``covs_xy`` (T, 2, 2), ``r`` (N, 3, 3)) against a uniform density ``new_density``
    (people per m^2) of someone else or clutter, and the squared Mahalanobis distances
    (N, T) for the gate. A track that has coasted long has a wide ``S`` and scores lower
    everywhere (TU Ilmenau's |Sigma_h| penalty)."""
    # S's three distinct entries (N, T), each from its own columns: no (N, T, 2, 2) array
    a = r[:, 0, 0, None] + covs_xy[None, :, 0, 0]
    b = r[:, 0, 1, None] + covs_xy[None, :, 0, 1]
    c = r[:, 1, 1, None] + covs_xy[None, :, 1, 1]
    det = a * c - b * b
    dx = positions[:, 0, None] - means_xy[None, :, 0]
    dy = positions[:, 1, None] - means_xy[None, :, 1]
    d2 = (c * dx * dx - 2 * b * dx * dy + a * dy * dy) / det
    log_n = -0.5 * d2 - _LOG_2PI - 0.5 * np.log(det)
    return log_n - math.log(new_density), d2


class PositionCue(Cue):
    """The position log-odds (:func:`position_log_odds`) and the gate: a pair farther than
    ``gate_sq`` (squared Mahalanobis distance on (x, y)) is never matched (``pairing.gated``)."""

    name = "position"

    def __init__(self, new_density: float, gate_sq: float) -> None:
        self.new_density, self.gate_sq = new_density, gate_sq

    def log_odds(self, pairing: Pairing, state: RobustTrackerState) -> np.ndarray:
        t = state.tracks
        total, d2 = position_log_odds(pairing.positions, pairing.r, t.mean[:, :2], t.cov[:, :2, :2], self.new_density)
        pairing.gated = d2 <= self.gate_sq
        return total
