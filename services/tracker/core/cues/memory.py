"""The ID memory's cue (Ban et al.: returning people compete with the tracks): a remembered
person who could be the one detected is an alternative to the track the detection would
continue. It learns where each matched track's person was seen, and who was seen with whom
(:mod:`~services.tracker.core.recovery`'s rivals), which the open-set recovery reads."""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from services.tracker.core import recovery as rec
from services.tracker.core.cues.base import Cue, Pairing
from services.tracker.core.types import TrackStatus

if TYPE_CHECKING:
    from services.tracker.core.recovery import RecoveryParams
    from services.tracker.core.tracks import RobustTrackerState
    from services.tracker.core.types import AppearanceModel

__all__ = ["MemoryCue", "memory_alternatives"]

_NONE: frozenset[int] = frozenset()


def _rivals(state: RobustTrackerState) -> list[frozenset[int]]:
    """Per track, the remembered people (not live) known to be someone else than its person."""
    t, memory, together = state.tracks, state.memory, state.recovery.together
    live_ids = state.live_ids()
    return [_NONE if s is TrackStatus.TENTATIVE or not i else
            frozenset(k for k in together.get(i, _NONE) if k in memory.entries and k not in live_ids)
            for i, s in zip(t.id, t.status)]


class _Weigh:
    """The weighted appearance log-odds of a distance, and the live galleries a detection is
    measured against for the stranger's level (once per detection, when needed)."""

    def __init__(self, state: RobustTrackerState, model: AppearanceModel, weight: float) -> None:
        self.model, self.weight, self.bank = model, weight, state.bank
        t = state.tracks
        self.live = [(t.id[c], t.slot[c]) for c in range(len(t)) if t.id[c] and state.bank.size(t.slot[c])]
        self.slots = np.array([s for _, s in self.live], np.int64)

    def llr(self, dist: np.ndarray) -> np.ndarray:
        return self.weight * self.model.log_odds(self.model.from_euclidean(np.asarray(dist, np.float64)))

    def cohort(self, x: np.ndarray) -> list[float]:
        """The log-odds of descriptor ``x`` against every live gallery."""
        if not len(self.slots):
            return []
        here = np.repeat(x[None], len(self.slots), axis=0)
        return self.llr(np.sqrt(self.bank.pair_sq_distances(self.slots, here).min(axis=1))).tolist()


def _reachable_llr(state: RobustTrackerState, rp: RecoveryParams, weigh: _Weigh, ids: list[int], x: np.ndarray,
                   xy: tuple[float, float], var: float) -> dict[int, float]:
    """The log-odds of descriptor ``x`` to each remembered person ``ids`` who could have walked to
    ``xy`` (variance ``var`` per axis) since they left."""
    memory = state.memory
    dist = np.array([memory.entries[k].min_distances(np.asarray(x, np.float32)[None])[0] for k in ids], np.float64)
    reach = rec.reachable(state.last_stamp or 0.0, xy[0], xy[1], var, [state.recovery.departures.get(k) for k in ids],
                          rp).tolist()
    return {k: v for k, v, ok in zip(ids, weigh.llr(dist).tolist(), reach) if ok}


def memory_alternatives(state: RobustTrackerState, model: AppearanceModel, weight: float, rp: RecoveryParams,
                        positions: np.ndarray, r: np.ndarray, descriptors: np.ndarray, has_desc: np.ndarray,
                        gated: np.ndarray, appearance: np.ndarray) -> np.ndarray:
    """(N, T) what to take off the log-odds of the gated pairs whose track's person may not be the one
    detected (a coasting track, or one the detection does not look like: ``appearance`` (N, T) below
    0): the best of the track's rivals (remembered, not live, reachable, known to be someone else
    than its person) by the association's appearance log-odds (``model``, ``weight``), less the
    stranger's level against the other live galleries (:func:`~services.tracker.core.recovery.stranger_llr`);
    at least 0. A person back in view then keeps their own ID instead of continuing a look-alike's
    coasting track, or that of someone who walked out where they walked in; a detection that looks
    like the track's person is left alone, or where everyone looks alike remembered look-alikes would
    tax every correct continuation. The stranger is measured only where a rival outweighs 0."""
    t = state.tracks
    out = np.zeros(gated.shape)
    rivals_of = _rivals(state)
    compared = gated & ((appearance < 0) | np.array([s is TrackStatus.COASTING for s in t.status], bool)[None, :])
    tracks_of = [[j for j in np.flatnonzero(compared[d]).tolist() if rivals_of[j]] if has_desc[d] else []
                 for d in range(len(gated))]
    if not any(tracks_of):
        return out
    weigh = _Weigh(state, model, weight)
    for d, tracks in enumerate(tracks_of):
        if tracks:
            ids = sorted(set().union(*(rivals_of[j] for j in tracks)))
            llr_of = _reachable_llr(state, rp, weigh, ids, descriptors[d],
                                    (float(positions[d, 0]), float(positions[d, 1])), 0.5 * float(r[d, 0, 0] + r[d, 1, 1]))
            _weigh_rivals(out[d], t.id, tracks, rivals_of, llr_of, weigh, descriptors[d])
    return out


def _weigh_rivals(out: np.ndarray, track_ids: list[int], tracks: list[int], rivals_of: list[frozenset[int]],
                  llr_of: dict[int, float], weigh: _Weigh, x: np.ndarray) -> None:
    """One detection's row ``out`` (T,) of :func:`memory_alternatives`: for each of its compared
    ``tracks``, the best reachable rival's log-odds (``llr_of``) less the stranger's level."""
    cohort: list[float] | None = None
    for j in tracks:
        best = max((llr_of[k] for k in rivals_of[j] if k in llr_of), default=0.0)
        if best <= 0.0:  # no rival outweighs "no alternative": the stranger cannot change that
            continue
        if cohort is None:  # the detection against every live gallery, once
            cohort = weigh.cohort(x)
        others = [v for (i, _), v in zip(weigh.live, cohort) if i != track_ids[j]]
        out[j] = max(0.0, best - (rec.stranger_llr(np.array(others)) if others else 0.0))


class MemoryCue(Cue):
    """Minus :func:`memory_alternatives` of the frame's described detections (when ``compete``
    and someone is remembered); learns the matched tracks' fixes (x, y and variance, where their
    person was last seen: reachability) and that their people are different people."""

    name = "memory"

    def __init__(self, model: AppearanceModel, weight: float, recovery: RecoveryParams) -> None:
        self.model, self.weight, self.recovery = model, weight, recovery

    def log_odds(self, pairing: Pairing, state: RobustTrackerState) -> np.ndarray | None:
        if pairing.descriptors is None or not self.recovery.compete or not len(state.memory) or pairing.gated is None:
            return None
        appearance = pairing.appearance if pairing.appearance is not None else np.zeros(pairing.gated.shape)
        return -memory_alternatives(state, self.model, self.weight, self.recovery, pairing.positions, pairing.r,
                                    pairing.descriptors, pairing.has_desc, pairing.gated, appearance)

    def learn(self, pairing: Pairing, state: RobustTrackerState, rows: np.ndarray) -> None:
        if not rows.shape[1]:
            return
        t, matched = state.tracks, rows[1].tolist()
        xy, var = t.mean[matched, :2].tolist(), (0.5 * (t.cov[matched, 0, 0] + t.cov[matched, 1, 1])).tolist()
        for j, (x, y), v in zip(matched, xy, var):
            t.fix[j] = (x, y, v)
        state.recovery.seen_together([t.id[j] for j in matched if t.id[j]])
