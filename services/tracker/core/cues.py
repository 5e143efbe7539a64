"""The robust profile's cues (the TU Ilmenau framework's cue fusion) and the measurement
covariance, as pure functions over one frame.

Each cue gives every (detection, track) pair a log-odds that the pair is the same person
(0: no information); the fusion adds them. The functions return what they computed on the
way (the squared Mahalanobis distances of the gate, the squared descriptor distances of
the pairs compared), so nothing is left on the tracker between two steps of a frame.

:func:`usable_covariances` is the project's one test of a detection's covariance: the
tracker service counts the bad ones with it, the cores replace them.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from services.tracker.core import classifier as clf
from services.tracker.core import recovery as rec

from services.tracker.core.types import TrackStatus

if TYPE_CHECKING:
    from services.tracker.core.bank import GalleryBank
    from services.tracker.core.robust_params import RobustParams
    from services.tracker.core.tracks import RobustTrackerState
    from services.tracker.core.types import AppearanceModel

__all__ = ["PairDistances", "appearance_log_odds", "classifier_log_odds", "logit", "measurement_covariance",
           "memory_alternatives", "position_log_odds", "usable_covariances"]

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


def logit(p: np.ndarray | float) -> np.ndarray:
    p = np.minimum(np.maximum(p, 1e-6), 1 - 1e-6)  # np.clip's values, without its dispatch
    return np.log(p / (1.0 - p))


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


@dataclass(frozen=True)
class PairDistances:
    """The squared descriptor distances of the pairs :func:`appearance_log_odds` compared:
    ``d2[k]`` (capacity,) for the pair (``dets[k]``, ``tracks[k]``)."""

    dets: list[int]
    tracks: list[int]
    d2: np.ndarray

    def get(self, d: np.ndarray, t: np.ndarray) -> np.ndarray | None:
        """The rows of pairs (``d[k]``, ``t[k]``), or None if one of them was not compared."""
        dets, tracks = d.tolist(), t.tolist()
        if dets == self.dets and tracks == self.tracks:  # the very pairs compared (all matched)
            return self.d2
        index = dict(zip(zip(self.dets, self.tracks), range(len(self.dets))))
        rows = [index.get(pair) for pair in zip(dets, tracks)]
        return None if None in rows else self.d2[rows]


def appearance_log_odds(model: AppearanceModel, bank: GalleryBank, slots: list[int], descriptors: np.ndarray,
                        pairs: np.ndarray) -> tuple[np.ndarray, PairDistances]:
    """(N, T) log-odds that detection d is track t by appearance: the model's distance from
    the detection's descriptor (``descriptors`` (N, D)) to the nearest descriptor of the
    track's gallery (``slots`` (T,) in ``bank``, -1: none) through a Fermi function placed by
    the model's calibrated thresholds. Only the ``pairs`` (N, T) bool are compared (0
    elsewhere: no information), in one batched product; their squared distances come back
    for the insertion that follows a match."""
    d_idx, t_idx = np.nonzero(pairs & (bank.sizes(slots) > 0)[None, :])
    d2 = bank.pair_sq_distances(np.asarray(slots, np.int64)[t_idx], descriptors[d_idx])
    out = np.zeros(pairs.shape)
    dist = model.from_euclidean(np.sqrt(d2.min(axis=1))).astype(np.float64)  # the log-odds in float64
    out[d_idx, t_idx] = model.log_odds(dist)
    return out, PairDistances(d_idx.tolist(), t_idx.tolist(), d2)


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


def memory_alternatives(state: RobustTrackerState, p: RobustParams, positions: np.ndarray, r: np.ndarray,
                        descriptors: np.ndarray, has_desc: np.ndarray, gated: np.ndarray,
                        appearance: np.ndarray) -> np.ndarray:
    """(N, T) what to take off the log-odds of the gated pairs of a detection and a track whose
    person may not be the one detected: a coasting track, or a confirmed one the detection does not
    look like (``appearance`` (N, T), the pairs' appearance log-odds, below 0): the ID memory's
    alternative. A remembered person (not live, reachable from where they left) known to be
    someone else than the track's person (the two were detected in one frame; a remembered ID
    never seen with it may be the same person remembered twice) competes with the track, by the
    association's appearance log-odds to their gallery less what a stranger reaches here
    (:func:`recovery.stranger_llr <services.tracker.core.recovery.stranger_llr>` of the detection
    against the other live tracks' galleries, certainly other people if the detection is the
    track's person); at least 0. A person back in view then keeps their own ID instead of
    continuing a look-alike's coasting track, or the track of someone who walked out where they
    walked in (Ban et al.: returning people compete with the tracks). A detection that looks like
    the track's own person leaves that track no alternative to weigh: where everyone looks alike,
    remembered look-alikes would otherwise tax every correct continuation. Only the remembered
    people known to differ from a compared track's person are measured, and the stranger only where
    one of them outweighs "no alternative" (the stranger's log-odds is never below 0)."""
    t, bank, rp, memory = state.tracks, state.bank, p.recovery, state.memory
    out = np.zeros(gated.shape)
    if p.appearance is None:
        return out
    live_ids = state.live_ids()
    together, none = state.recovery.together, frozenset()
    rivals_of = [none if s is TrackStatus.TENTATIVE or not i else
                 frozenset(k for k in together.get(i, none) if k in memory.entries and k not in live_ids)
                 for i, s in zip(t.id, t.status)]
    compared = gated & ((appearance < 0) | np.array([s is TrackStatus.COASTING for s in t.status], bool)[None, :])
    tracks_of = [[j for j in np.flatnonzero(compared[d]).tolist() if rivals_of[j]] if has_desc[d] else []
                 for d in range(len(gated))]
    if not any(tracks_of):
        return out
    model = p.appearance

    def pair_llr(dist: np.ndarray) -> np.ndarray:
        return p.appearance_weight * model.log_odds(model.from_euclidean(np.asarray(dist, np.float64)))

    live = [(t.id[c], t.slot[c]) for c in range(len(t)) if t.id[c] and bank.size(t.slot[c])]
    slots = np.array([s for _, s in live], np.int64)
    stamp = state.last_stamp or 0.0
    for d, tracks in enumerate(tracks_of):
        if not tracks:
            continue
        ids = sorted(set().union(*(rivals_of[j] for j in tracks)))
        x = np.asarray(descriptors[d], np.float32)[None]
        dist = np.array([memory.entries[k].min_distances(x)[0] for k in ids], np.float64)
        var = 0.5 * float(r[d, 0, 0] + r[d, 1, 1])
        reach = rec.reachable(stamp, float(positions[d, 0]), float(positions[d, 1]), var,
                              [state.recovery.departures.get(k) for k in ids], rp).tolist()
        llr_of = {k: v for k, v, ok in zip(ids, pair_llr(dist).tolist(), reach) if ok}
        cohort: list[float] | None = None
        for j in tracks:
            best = max((llr_of[k] for k in rivals_of[j] if k in llr_of), default=0.0)
            if best <= 0.0:  # no rival outweighs "no alternative": the stranger cannot change that
                continue
            if cohort is None:  # the detection against every live gallery, once
                here = np.repeat(descriptors[d][None], len(slots), axis=0)
                cohort = pair_llr(np.sqrt(bank.pair_sq_distances(slots, here).min(axis=1))).tolist() if len(slots) else []
            others = [v for (i, _), v in zip(live, cohort) if i != t.id[j]]
            out[d, j] = max(0.0, best - (rec.stranger_llr(np.array(others)) if others else 0.0))
    return out
