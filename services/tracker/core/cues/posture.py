"""Posture and upper-body orientation per track (TU Ilmenau): two discrete Bayes filters.

* **Posture** (standing, sitting, lying): a Gaussian likelihood of each on the detection's height
  above the floor (``z`` in the map frame: the torso's centre) and its box's height / width (a
  standing torso centre is about 1.1 m up and its box 2.7 times as tall as wide; sitting 0.7 m and
  1.6; lying 0.3 m and 0.6), times ``reported_likelihood`` of a detector's own report. The depth
  detector's "sitting" comes only from a seated shape and is nearly always right; its "standing"
  is Basso/Munaro's height rule, which also takes about half the seated people with the back of
  their chair (the simulator's ``chairs``: 215 of 396 seated detections), so it says little.
* **Orientation**: 8 bins of 45 degrees in the map frame (bin k centred on k * 45 degrees, 0 along
  +x), from a von Mises likelihood around the walking direction whose concentration grows with the
  speed; below ``min_speed`` walking says nothing (an orientation classifier's report, if any).
* Between updates both drift towards uniform, "unknown" (a person may sit down or turn around),
  with ``posture_tau_s`` and ``orientation_tau_s``; orientation also spreads to the neighbouring bins.

Pure numpy; every function takes and returns probability vectors.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field
from functools import lru_cache
from typing import TYPE_CHECKING

import numpy as np

from services.tracker.core.cues.base import Cue, Pairing
from services.tracker.core.tracks import ArrayColumns
from services.tracker.core.types import TrackStatus

if TYPE_CHECKING:
    from services.tracker.core.tracks import RobustTrackerState

__all__ = ["ORIENTATION_BINS", "POSTURES", "PostureColumns", "PostureCue", "PostureParams", "codes", "drift", "orientation_evidence",
           "orientation_evidences", "observe", "posture_evidence", "posture_evidences", "reported_evidences",
           "transition", "uniform", "update", "updates"]

POSTURES = ("standing", "sitting", "lying")
ORIENTATION_BINS = 8
_BIN_CENTRES = np.arange(ORIENTATION_BINS) * (2 * math.pi / ORIENTATION_BINS)
# (torso centre height m, its std; box height/width, its std) per posture
_HEIGHT = np.array([[1.10, 0.20], [0.70, 0.15], [0.30, 0.15]])
_ASPECT = np.array([[2.7, 0.7], [1.6, 0.5], [0.6, 0.3]])


@dataclass(frozen=True)
class PostureParams:
    """The posture filters' settings (the module doc; the README's *Settings*, ``robust.posture``)."""

    posture_tau_s: float = 5.0
    orientation_tau_s: float = 5.0
    min_speed: float = 0.3
    kappa_per_mps: float = 2.0
    max_kappa: float = 4.0
    #: P(a detector reports standing, sitting, lying | each true posture): one row per report
    reported_likelihood: tuple[tuple[float, float, float], ...] = ((1.0, 0.5, 0.2), (0.05, 1.0, 0.2),
                                                                   (0.05, 0.2, 1.0))

    def __post_init__(self) -> None:
        rows = self.reported_likelihood
        lik = np.asarray(rows, float) if len(rows) == 3 and all(len(r) == 3 for r in rows) else np.zeros(0)
        if lik.shape != (3, 3) or np.any(lik < 0) or not np.all(lik.max(axis=1) > 0):
            raise ValueError("reported_likelihood needs 3 rows (standing, sitting, lying reports) of 3 "
                             "non-negative likelihoods, each row with one above 0")


def uniform(n: int) -> np.ndarray:
    return np.full(n, 1.0 / n)


def posture_evidence(height_m: float, aspect: float | None) -> np.ndarray:
    """Likelihood (3,) of standing, sitting, lying given the torso centre's height above the
    floor and the box's height/width (None: the box's shape is unknown)."""
    return posture_evidences(np.array([height_m]), None if aspect is None else np.array([aspect]))[0]


def posture_evidences(height_m: np.ndarray, aspect: np.ndarray | None) -> np.ndarray:
    """:func:`posture_evidence` of several detections at once: heights (M,), aspects (M,)
    (a non-finite or non-positive one: unknown) -> (M, 3)."""
    lik = np.exp(-0.5 * ((np.asarray(height_m, float)[:, None] - _HEIGHT[:, 0]) / _HEIGHT[:, 1]) ** 2)
    if aspect is not None:
        a = np.asarray(aspect, float)[:, None]
        known = np.isfinite(a) & (a > 0)
        shape = np.exp(-0.5 * ((np.where(known, a, 1.0) - _ASPECT[:, 0]) / _ASPECT[:, 1]) ** 2)
        lik = np.where(known, lik * shape, lik)
    return lik + 1e-6  # never certain: a posture the evidence rules out can still come back


def codes(labels: Sequence[str | None]) -> np.ndarray | None:
    """Detectors' posture reports as codes (N,) int8, the index in :data:`POSTURES` (-1: none);
    None when no detection has one."""
    if not any(labels):
        return None
    return np.array([POSTURES.index(x) if x in POSTURES else -1 for x in labels], np.int8)


def reported_evidences(reported: np.ndarray, likelihood: tuple[tuple[float, float, float], ...]) -> np.ndarray:
    """Likelihoods (M, 3) of the postures given detectors' reports (M,) (:func:`codes`): row
    ``likelihood[report]``; a detection without a report, ones."""
    reported = np.asarray(reported, np.int64)
    table = np.vstack([np.asarray(likelihood, float), np.ones((1, len(POSTURES)))])  # -1: the last row
    return table[np.where(reported >= 0, reported, len(POSTURES))]


def orientation_evidence(velocity_xy: np.ndarray, params: PostureParams) -> np.ndarray | None:
    """Likelihood (8,) of each orientation bin from the walking velocity, or None when the
    person is too slow for the walking direction to mean anything."""
    vx, vy = float(velocity_xy[0]), float(velocity_xy[1])
    speed = math.hypot(vx, vy)
    if not math.isfinite(speed) or speed < params.min_speed:
        return None
    kappa = min(params.max_kappa, params.kappa_per_mps * speed)
    return np.exp(kappa * np.cos(_BIN_CENTRES - math.atan2(vy, vx)))


def orientation_evidences(velocity_xy: np.ndarray, params: PostureParams) -> tuple[np.ndarray, np.ndarray]:
    """:func:`orientation_evidence` of several tracks at once: velocities (M, 2) -> the
    likelihoods (M, 8) and which rows have one (M,) (walking fast enough)."""
    v = np.asarray(velocity_xy, float).tolist()
    # math's hypot and atan2, as for one track: numpy's may differ in the last bit
    speed = [math.hypot(vx, vy) for vx, vy in v]
    walking = np.array([math.isfinite(s) and s >= params.min_speed for s in speed], bool)
    if not walking.any():
        return np.ones((len(v), ORIENTATION_BINS)), walking
    heading = np.array([math.atan2(vy, vx) for vx, vy in v]).reshape(-1)
    kappa = np.minimum(params.max_kappa, params.kappa_per_mps * np.where(walking, speed, 0.0))
    return np.exp(kappa[:, None] * np.cos(_BIN_CENTRES[None, :] - heading[:, None])), walking


def update(prior: np.ndarray, likelihood: np.ndarray | None) -> np.ndarray:
    """The Bayes update ``prior * likelihood``, normalised (the prior when there is none)."""
    if likelihood is None:
        return prior
    post = prior * likelihood
    total = float(post.sum())
    return post / total if total > 0 and math.isfinite(total) else prior


def updates(prior: np.ndarray, likelihood: np.ndarray) -> np.ndarray:
    """:func:`update` of several distributions at once (M, K); a row whose product does not
    normalise keeps its prior."""
    post = prior * likelihood
    total = post.sum(axis=1, keepdims=True)
    return np.divide(post, total, out=prior.copy(), where=(total > 0) & np.isfinite(total))


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


def observe(posture: np.ndarray, orientation: np.ndarray, rows: np.ndarray, height_m: np.ndarray,
            aspect: np.ndarray | None, velocity_xy: np.ndarray, young: np.ndarray, classified: np.ndarray | None,
            params: PostureParams, fresh: bool = False,
            reported: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Tracks ``rows`` (M,) of ``posture`` (T, 3) and ``orientation`` (T, 8) after one detection
    each: posture from the height and the box's aspect (None: no boxes, no posture evidence);
    with the detectors' posture reports ``reported`` (M,) (:func:`codes`; None: none);
    orientation from the walking ``velocity_xy`` (M, 2) or, too slow for that, from an
    orientation classifier's probabilities ``classified`` (M, 8; NaN rows: none); a ``young``
    (M,) track's velocity is its prior and says nothing. Returns new arrays, the given ones
    left as they are, unless they are ``fresh`` (nobody else holds them): then updated in place."""
    if aspect is not None:
        posture = posture if fresh else posture.copy()
        lik = posture_evidences(height_m, aspect)
        if reported is not None:
            lik = lik * reported_evidences(reported, params.reported_likelihood)
        posture[rows] = updates(posture[rows], lik)
    old = [k for k, y in enumerate(young.tolist()) if not y]
    if len(old) <= _FEW:  # a few tracks: one at a time is quicker than the arrays
        return posture, _orient_few(orientation, rows, old, velocity_xy, classified, params, fresh)
    return posture, _orient_many(orientation, rows, np.array(old), velocity_xy, classified, params, fresh)


def _orient_few(orientation: np.ndarray, rows: np.ndarray, old: list[int], velocity_xy: np.ndarray,
                classified: np.ndarray | None, params: PostureParams, fresh: bool) -> np.ndarray:
    """:func:`observe`'s orientation update of the tracks ``rows[old]``, one at a time."""
    own, v = fresh, velocity_xy.tolist()
    for k in old:
        lik = orientation_evidence(v[k], params)
        if lik is None and classified is not None and np.all(np.isfinite(classified[k])):
            lik = np.asarray(classified[k], float) + 1e-3
        if lik is not None:
            orientation, own = (orientation if own else orientation.copy()), True
            orientation[rows[k]] = update(orientation[rows[k]], lik)
    return orientation


def _orient_many(orientation: np.ndarray, rows: np.ndarray, old: np.ndarray, velocity_xy: np.ndarray,
                 classified: np.ndarray | None, params: PostureParams, fresh: bool) -> np.ndarray:
    """:func:`observe`'s orientation update of the tracks ``rows[old]``, in arrays."""
    rows, velocity_xy = rows[old], velocity_xy[old]
    lik, use = orientation_evidences(velocity_xy, params)
    if classified is not None:
        classified = classified[old]
        seen = ~use & np.all(np.isfinite(classified), axis=1)
        lik[seen] = np.asarray(classified[seen], float) + 1e-3
        use |= seen
    if use.any():
        orientation = orientation if fresh else orientation.copy()
        orientation[rows[use]] = updates(orientation[rows[use]], lik[use])
    return orientation


#: up to this many tracks, :func:`observe` updates orientations one at a time
_FEW = 4

NAME = "posture"


@lru_cache(maxsize=64)
def _uniform_rows(k: int, n: int) -> np.ndarray:
    """``k`` uniform distributions over ``n`` values (k, n), read-only."""
    rows = np.tile(uniform(n), (k, 1))
    rows.flags.writeable = False
    return rows


@dataclass
class PostureColumns(ArrayColumns):
    """``posture`` (T, 3) and ``orientation`` (T, 8), one distribution per track. A track's report
    holds its rows: every change makes new arrays, except into arrays of this frame's own.
    Neither merges nor clears: how a person stands now is the track's own, and says nothing of who
    they are."""

    posture: np.ndarray = field(default_factory=lambda: np.zeros((0, 3)))
    orientation: np.ndarray = field(default_factory=lambda: np.zeros((0, ORIENTATION_BINS)))

    def rows(self, k: int) -> tuple[np.ndarray, np.ndarray]:
        return _uniform_rows(k, 3), _uniform_rows(k, ORIENTATION_BINS)


class PostureCue(Cue):
    """Drift every track's posture and orientation by ``dt`` (two products), and update the
    matched tracks' from their detections (:func:`posture.observe`)."""

    name = NAME

    def __init__(self, params: PostureParams) -> None:
        self.params = params
        self._dt, self._m = -1.0, (np.eye(3), np.eye(ORIENTATION_BINS))  # drift matrices of the last dt

    def columns(self) -> PostureColumns:
        return PostureColumns()

    def predict(self, state: RobustTrackerState, dt: float) -> None:
        step = round(dt, 3)  # to the millisecond: the matrices are rebuilt only when the rate changes
        if step != self._dt:
            self._dt = step
            self._m = (transition(3, step, self.params.posture_tau_s),
                       transition(ORIENTATION_BINS, step, self.params.orientation_tau_s, circular=True))
        cols: PostureColumns = state.tracks.extra[NAME]  # type: ignore[assignment]
        cols.posture, cols.orientation = cols.posture @ self._m[0], cols.orientation @ self._m[1]

    def learn(self, pairing: Pairing, state: RobustTrackerState, rows: np.ndarray) -> None:
        if not rows.shape[1]:
            return
        t, frame = state.tracks, pairing.frame
        d_idx, t_idx = rows
        cols: PostureColumns = t.extra[NAME]  # type: ignore[assignment]
        cols.posture, cols.orientation = observe(
            cols.posture, cols.orientation, t_idx, pairing.positions[d_idx, 2],
            None if frame.aspects is None else frame.aspects[d_idx], t.mean[t_idx, 3:5],
            np.array([t.status[j] is TrackStatus.TENTATIVE for j in t_idx.tolist()]),
            None if frame.orientations is None else frame.orientations[d_idx], self.params, fresh=pairing.moved,
            reported=None if frame.postures is None else frame.postures[d_idx])
