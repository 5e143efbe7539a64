"""Posture and upper-body orientation per track (TU Ilmenau): two discrete Bayes filters.

* **Posture**: standing, sitting, lying. The evidence is a detection's body height (the
  localized point's height above the floor, ``z`` in the map frame: the torso's centre)
  and its box's height-to-width ratio in the image. Each posture has a Gaussian
  likelihood on both (a standing torso centre is about 1.1 m up and its box about 2.7
  times as tall as wide; sitting 0.7 m and 1.6; lying 0.3 m and 0.6).
* **Orientation**: 8 bins of 45 degrees in the map frame (bin k is centred on k * 45
  degrees, 0 along +x). The evidence is the walking direction when the person moves: a
  von Mises likelihood around the velocity's heading whose concentration grows with the
  speed; below ``min_speed`` the walking direction says nothing and the distribution
  keeps its last estimate, slowly spreading.
* Between updates both drift towards uniform (a person may sit down or turn around),
  with time constants ``posture_tau_s`` and ``orientation_tau_s``; orientation also
  diffuses to the neighbouring bins. A uniform distribution means unknown.

Pure numpy; every function takes and returns probability vectors.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

__all__ = ["ORIENTATION_BINS", "POSTURES", "PostureParams", "drift", "orientation_evidence", "posture_evidence",
           "transition", "uniform", "update"]

POSTURES = ("standing", "sitting", "lying")
ORIENTATION_BINS = 8
_BIN_CENTRES = np.arange(ORIENTATION_BINS) * (2 * math.pi / ORIENTATION_BINS)
# (torso centre height m, its std; box height/width, its std) per posture
_HEIGHT = np.array([[1.10, 0.20], [0.70, 0.15], [0.30, 0.15]])
_ASPECT = np.array([[2.7, 0.7], [1.6, 0.5], [0.6, 0.3]])


@dataclass(frozen=True)
class PostureParams:
    """``posture_tau_s`` / ``orientation_tau_s``: time constants of the drift to uniform;
    ``min_speed``: m/s below which walking says nothing of the orientation; ``kappa_per_mps``:
    von Mises concentration per m/s of speed (capped at ``max_kappa``)."""

    posture_tau_s: float = 5.0
    orientation_tau_s: float = 5.0
    min_speed: float = 0.3
    kappa_per_mps: float = 2.0
    max_kappa: float = 4.0


def uniform(n: int) -> np.ndarray:
    return np.full(n, 1.0 / n)


def posture_evidence(height_m: float, aspect: float | None) -> np.ndarray:
    """Likelihood (3,) of standing, sitting, lying given the torso centre's height above the
    floor and the box's height/width (None: the box's shape is unknown)."""
    lik = np.exp(-0.5 * ((height_m - _HEIGHT[:, 0]) / _HEIGHT[:, 1]) ** 2)
    if aspect is not None and np.isfinite(aspect) and aspect > 0:
        lik = lik * np.exp(-0.5 * ((aspect - _ASPECT[:, 0]) / _ASPECT[:, 1]) ** 2)
    return lik + 1e-6  # never certain: a posture the evidence rules out can still come back


def orientation_evidence(velocity_xy: np.ndarray, params: PostureParams) -> np.ndarray | None:
    """Likelihood (8,) of each orientation bin from the walking velocity, or None when the
    person is too slow for the walking direction to mean anything."""
    vx, vy = float(velocity_xy[0]), float(velocity_xy[1])
    speed = math.hypot(vx, vy)
    if not math.isfinite(speed) or speed < params.min_speed:
        return None
    kappa = min(params.max_kappa, params.kappa_per_mps * speed)
    return np.exp(kappa * np.cos(_BIN_CENTRES - math.atan2(vy, vx)))


def update(prior: np.ndarray, likelihood: np.ndarray | None) -> np.ndarray:
    """The Bayes update ``prior * likelihood``, normalised (the prior when there is none)."""
    if likelihood is None:
        return prior
    post = prior * likelihood
    total = post.sum()
    return post / total if total > 0 and np.isfinite(total) else prior


def transition(n: int, dt: float, tau_s: float, circular: bool = False) -> np.ndarray:
    """The (n, n) matrix of :func:`drift`: ``drift(p, ...) == p @ transition(len(p), ...)``,
    so many tracks' distributions move in one product."""
    if dt <= 0:
        return np.eye(n)
    keep = math.exp(-dt / tau_s)
    m = np.eye(n)
    if circular:
        spread = 0.25 * (1.0 - keep)
        m = (1 - 2 * spread) * m + spread * (np.roll(m, 1, axis=1) + np.roll(m, -1, axis=1))
    return keep * m + (1.0 - keep) / n


def drift(p: np.ndarray, dt: float, tau_s: float, circular: bool = False) -> np.ndarray:
    """``p`` after ``dt`` seconds of the transition model: it relaxes towards uniform with
    time constant ``tau_s``; a circular distribution also spreads to its neighbours."""
    if dt <= 0:
        return p
    keep = math.exp(-dt / tau_s)
    if circular:
        spread = 0.25 * (1.0 - keep)
        p = (1 - 2 * spread) * p + spread * (np.roll(p, 1) + np.roll(p, -1))
    return keep * p + (1.0 - keep) / len(p)
