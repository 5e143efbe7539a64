"""The robust profile's life cycle, in time (services/tracker/README.md, *How it works*, step 6):
ageing (coasting, the limits out of view), birth (Ban et al.'s candidates), confirmation
(Basso/Munaro, with IsPerson), the ID (a hand-over, else Algorithm 2 of Pinto's thesis, open-set:
core/recovery.py, then probation) and the archive into the ID memory. What a matched track learns
is each cue's (core/cues/). Each step is a function of the tracker's state
(:class:`RobustTrackerState`) and its settings. Pure numpy.
"""

from __future__ import annotations

import math

import numpy as np

from services.tracker.core import is_person
from services.tracker.core import recovery as rec
from services.tracker.core import recovery_evidence as rev
from services.tracker.core.cues.base import Cue, Pairing
from services.tracker.core.cues.classifier import trained
from services.tracker.core.cues.stature import stature_of
from services.tracker.core.id_decisions import explain
from services.tracker.core.robust_params import RobustParams
from services.tracker.core.tracks import RobustTrackerState, TrackTable
from services.tracker.core.types import FrameResult, HandOver, IdDecision, IdOutcome, TrackStatus
from services.tracker.core.view import View, Views

_TENTATIVE, _CONFIRMED, _COASTING = TrackStatus.TENTATIVE, TrackStatus.CONFIRMED, TrackStatus.COASTING

__all__ = ["age", "archive", "birth", "births", "bayes", "confirm", "evidence", "handover", "identity", "kept_recovery",
           "load_recovery", "probation"]


def bayes(p: float, q: float) -> float:
    """Binary Bayes update of ``p`` with evidence ``q`` (both probabilities)."""
    num = p * q
    return num / (num + (1 - p) * (1 - q))


def age(state: RobustTrackerState, p: RobustParams, stamp: float, previous: float | None,
        view: View | None, camera: str = "") -> tuple[list[int], list[bool]]:
    """Coasting, the tracks' view flags and the end of tracks at ``stamp`` (``previous``: the
    last frame's stamp; ``camera`` the frame's sensor, whose own view is ``view``'s first).
    Returns the rows to delete (in order) and the rows to keep (neither: tentative tracks that did
    not go on, clutter)."""
    t = state.tracks
    coasting = _coast(t, stamp, _elsewhere(t, stamp, p.report_coast_s, view, camera))
    if view is not None and coasting:
        points = t.mean[coasting, :3]
        seen = view.contains(points, p.view_margin).tolist()
        telling = view.sees_absence(points, p.view_margin).tolist() if view.absence_differs else seen
        before = previous if previous is not None else stamp
        for j, s, a in zip(coasting, seen, telling):
            # out of view since the last frame, or in a view that could not tell them from what stood
            # there (a laser's, by a wall): the time does not count as missed
            if t.in_view[j] is False or (t.in_view[j] and not t.misses_tell[j]):
                t.unseen_s[j] += max(0.0, stamp - max(before, t.last_update[j]))
            t.in_view[j], t.misses_tell[j] = s, a
    var = (t.cov[:, 0, 0] + t.cov[:, 1, 1]).tolist()
    ended, keep = [], []
    for j, last in enumerate(t.last_update):
        gap = stamp - last
        if t.status[j] is _TENTATIVE:
            keep.append(not gap > p.tentative_timeout_s)  # a birth candidate that did not go on: clutter
        elif _lost(p, gap, t.unseen_s[j], t.in_view[j], var[j]):
            ended.append(j)
            keep.append(False)
        else:
            keep.append(True)
    return ended, keep


def _elsewhere(t: TrackTable, stamp: float, within_s: float, view: View | None, camera: str) -> set[int]:
    """The confirmed tracks another sensor detected within ``within_s`` that this frame's own
    sensor could not see (outside its view: ``view``'s first, :meth:`Intake.view`'s order): a laser's
    person behind the robot is not missed by the camera's frame in between two scans."""
    own = view.views[0] if isinstance(view, Views) else view
    if own is None or not camera:
        return set()
    rows = [j for j, last in enumerate(t.last_update)
            if t.status[j] is _CONFIRMED and 0 < stamp - last <= within_s and t.camera[j] != camera]
    if not rows:
        return set()
    seen = own.contains(t.mean[rows, :3]).tolist()
    return {j for j, s in zip(rows, seen) if not s}


def _coast(t: TrackTable, stamp: float, elsewhere: set[int] = frozenset()) -> list[int]:  # type: ignore[assignment]
    """Confirmed tracks not detected at ``stamp`` coast, but those of ``elsewhere``; returns the
    coasting rows (the others forget whether they were in view)."""
    coasting = []
    for j, last in enumerate(t.last_update):
        if stamp - last > 0 and t.status[j] is _CONFIRMED and j not in elsewhere:
            t.status[j] = _COASTING
        if t.status[j] is _COASTING:
            coasting.append(j)
        else:
            t.in_view[j] = None
    return coasting


def _lost(p: RobustParams, gap: float, unseen: float, in_view: bool | None, var: float) -> bool:
    """Whether a confirmed track ``gap`` s since its last detection, ``unseen`` s of them out of
    every view, is lost. In view, a track is dropped on the usual limits; the time out of every view
    does not count towards max_coast_s, and a track that has been out of view has the wider
    variance bound (it may come back into a view far from its prediction)."""
    return (gap - unseen > p.max_coast_s or gap > p.max_coast_unseen_s or var > p.max_position_var_unseen
            or (unseen == 0.0 and in_view is not False and var > p.max_position_var))


def archive(state: RobustTrackerState, j: int, view: View | None = None, horizon_s: float = 0.0) -> None:
    """Track ``j``'s gallery and classifier go to the ID memory (a forgotten person's do not), and
    where and when they left: whether they walked out of ``view`` (their last fix in it, and
    their walk out of it within ``horizon_s``)."""
    t = state.tracks
    if t.forgotten[j]:
        return
    if state.bank.size(t.slot[j]):
        state.memory.archive(t.id[j], state.bank.descriptors(t.slot[j]))
    weights = trained(t, j)
    if weights is not None:
        state.classifiers[t.id[j]] = weights
    if len(state.classifiers) > len(state.memory):  # follow the memory's evictions and forgetting
        state.classifiers = {i: w for i, w in state.classifiers.items() if i in state.memory}
    fix, r = t.fix[j], state.recovery
    if fix is not None and t.id[j] in state.memory:  # where and when they left, for reachability
        r.departures[t.id[j]] = rec.Departure(t.last_update[j], *fix, walked_out(t, j, view, horizon_s),
                                              *stature_of(t, j))
    if len(r.departures) > len(state.memory) or len(r.together) > 2 * len(state.memory) + 64:
        r.forget(keep=set(state.memory.entries) | state.live_ids())


def walked_out(t: TrackTable, j: int, view: View | None, horizon_s: float) -> bool:
    """Whether track ``j``, at its last fix in ``view``, was walking out of it within ``horizon_s``."""
    fix = t.fix[j]
    if view is None or fix is None or horizon_s <= 0:
        return False
    here = np.array([fix[0], fix[1], float(t.mean[j, 2])])
    ahead = here.copy()
    ahead[:2] += horizon_s * t.mean[j, 3:5]
    inside = view.contains(np.stack([here, ahead]))
    return bool(inside[0] and not inside[1])


def births(free: list[int], matched: set[int], positions: np.ndarray, p_det: np.ndarray,
           separation: float) -> list[int]:
    """The unmatched confident detections ``free`` that start tracks: all of them, or with a
    ``separation`` (m) those not that near a ``matched`` detection or a likelier birth."""
    if separation <= 0 or not free:
        return free
    taken = [positions[d, :2] for d in matched]
    out = []
    for d in sorted(free, key=lambda d: -p_det[d]):
        if all(float(np.linalg.norm(positions[d, :2] - q)) >= separation for q in taken):
            out.append(d)
            taken.append(positions[d, :2])
    return sorted(out)


def birth(state: RobustTrackerState, pairing: Pairing, dets: list[int], cues: list[Cue], p0: np.ndarray,
          cap: float = 1.0) -> None:
    """A tentative track at rest (not turning) per detection of ``dets``, its IsPerson the detection's
    P(true person) up to its detector's ``cap`` (core/is_person.py); each cue starts its own
    state of it from the detection (a gallery, a stature)."""
    if not dets:
        return
    t = state.tracks
    d = np.asarray(dets)
    mean = np.concatenate([pairing.positions[d], np.zeros((len(d), t.mean.shape[1] - 3))], axis=1)
    first = len(t)
    t.append(mean, p0, pairing.stamp, is_person.first(pairing.p_det[d].tolist(), cap), pairing.frame.camera,
             pairing.frame.detector)
    for cue in cues:
        cue.born(pairing, state, first, d)


def confirm(state: RobustTrackerState, p: RobustParams, result: FrameResult) -> set[int]:
    """Confirm the birth candidates that have earned it and give them their IDs; returns the
    rows a hand-over replaced, to remove."""
    t = state.tracks
    removed: set[int] = set()
    for j, status in enumerate(t.status):
        if status is not _TENTATIVE or t.confident_hits[j] < p.n_init or t.is_person[j] < p.confirm_is_person:
            continue
        t.status[j], t.ever_confirmed[j] = _CONFIRMED, True
        handed = handover(state, j, removed, p.handover_gate_sq)
        if handed is not None and p.handover_gate_sq is not None:  # (none without a gate)
            row, d2 = handed
            t.id[j] = t.id[row]
            result.new_ids.append(t.id[j])
            result.recovered_ids.append(t.id[j])
            result.id_decisions.append(handed_over(t, j, row, d2, p.handover_gate_sq))
            continue
        track_id, recovered = identity(state, j, removed, p, result)
        t.id[j] = track_id
        result.new_ids.append(track_id)
        if recovered:
            result.recovered_ids.append(track_id)
    return removed


def handover(state: RobustTrackerState, j: int, removed: set[int], gate: float | None) -> tuple[int, float] | None:
    """Hand-over by motion: (the row, the squared Mahalanobis distance on (x, y)) of the track coasting
    out of another camera's view nearest the newly confirmed ``j``'s prediction within ``gate``
    (None: none), which ``j`` replaces: it takes its gallery and what each cue learnt of the person,
    ``removed`` gets the row. Back into the same camera's view is appearance's business."""
    if gate is None:
        return None
    t, bank = state.tracks, state.bank
    best, best_d2 = -1, gate
    for c in range(len(t)):
        if not _left_another_view(t, c, j, removed):
            continue
        s = t.cov[c, :2, :2] + t.cov[j, :2, :2]
        diff = t.mean[j, :2] - t.mean[c, :2]
        d2 = float(diff @ np.linalg.solve(s, diff))
        if d2 <= best_d2:
            best, best_d2 = c, d2
    if best < 0:
        return None
    if bank.size(t.slot[best]):
        if t.slot[j] < 0:
            t.slot[j], t.slot[best] = t.slot[best], -1
        else:
            for desc in bank.descriptors(t.slot[best]):
                bank.add(t.slot[j], desc)
    for cols in t.extra.values():  # what each cue learnt of the person too (a classifier, a stature)
        cols.merge(j, best)
    removed.add(best)
    return best, best_d2


def _left_another_view(t: TrackTable, c: int, j: int, removed: set[int]) -> bool:
    """Whether track ``c`` is a person who walked out of another camera's view than the one track
    ``j`` was born in (coasting out of view, with an ID, not forgotten nor handed over already)."""
    return (t.status[c] is _COASTING and t.in_view[c] is False and bool(t.id[c]) and not t.forgotten[c]
            and c not in removed and bool(t.camera[c]) and t.camera[c] != t.camera[j])  # the same camera: Re-ID's


def handed_over(t: TrackTable, j: int, row: int, d2: float, gate: float) -> IdDecision:
    """The decision of a hand-over: track ``j`` took the ID of ``row``, ``d2`` from its prediction."""
    x, y = float(t.mean[j, 0]), float(t.mean[j, 1])
    away = math.hypot(x - float(t.mean[row, 0]), y - float(t.mean[row, 1]))
    how = HandOver(t.camera[row], d2, max(0.0, t.last_update[j] - t.last_update[row]), away)
    return IdDecision(t.last_update[j], t.id[row], "handover", x, y, 0.0, gate, 0.0, 0.0, (), handover=how)


def identity(state: RobustTrackerState, j: int, removed: set[int], p: RobustParams,
             result: FrameResult | None = None) -> tuple[int, bool]:
    """Algorithm 2, open-set (core/recovery.py): a remembered person's ID when they are more
    probable than "someone new" and their rivals together (probation starts), else a new ID.
    A decision that weighed remembered people is explained in ``result.id_decisions``."""
    rp, t = p.recovery, state.tracks
    if p.appearance is None or not state.bank.size(t.slot[j]):
        return state.memory.new_id(), False
    ev = evidence(state, j, state.live_ids(removed), p)
    p_new = rp.p_new
    decision = rec.decide(ev.llr, ev.reach, p_new, rp, ev.new_llr, lambda i: ev.rivals(ev.ids[i]))
    k, stamp = (state.memory.new_id() if decision.index is None else ev.ids[decision.index]), t.last_update[j]
    if result is not None and ev.ids:
        result.id_decisions.append(_explain(state, j, ev, p_new, k, "new" if decision.index is None else "recovered",
                                            rp.p_recover))
    if decision.index is None:
        return k, False
    if rp.probation_s > 0:
        t.probation[j] = (k, stamp + rp.probation_s, stamp + rp.check_period_s)
    return k, True


def _explain(state: RobustTrackerState, j: int, ev: rev.Evidence, p_new: float, track_id: int, outcome: IdOutcome,
             threshold: float, previous_id: int | None = None) -> IdDecision:
    t = state.tracks
    return explain(ev, p_new, t.last_update[j], float(t.mean[j, 0]), float(t.mean[j, 1]), track_id, outcome, threshold,
                   state.recovery.departures, previous_id)


def evidence(state: RobustTrackerState, j: int, exclude: set[int], p: RobustParams) -> rev.Evidence:
    """core/recovery_evidence.py's evidence for track ``j``: the model's weighted log-odds, the
    remembered classifiers, the statures, the other confirmed people in view now as the stranger's measure."""
    model, t, bank = p.appearance, state.tracks, state.bank
    assert model is not None
    here = rev.Candidate(bank.descriptors(t.slot[j]), t.last_update[j], float(t.mean[j, 0]), float(t.mean[j, 1]),
                         0.5 * float(t.cov[j, 0, 0] + t.cov[j, 1, 1]), *stature_of(t, j))
    others = [bank.descriptors(t.slot[c]) for c in range(len(t)) if c != j and t.id[c] and bank.size(t.slot[c])]
    return rev.evidence(here, state.memory, exclude,
                        lambda d: p.appearance_weight * model.log_odds(model.from_euclidean(d)),
                        others, state.classifiers, p.classifier, state.recovery, p.recovery, p.stature)


def probation(state: RobustTrackerState, p: RobustParams, stamp: float, result: FrameResult) -> None:
    """Check recent recoveries again with the tracks' grown galleries; undo those that no longer
    stand (core/recovery.py): a fresh ID, the remembered person stays remembered, counted."""
    rp, t = p.recovery, state.tracks
    for j, prob in enumerate(t.probation):
        if prob is None:
            continue
        k, until, check = prob
        if t.id[j] != k or t.forgotten[j] or k not in state.memory or not state.bank.size(t.slot[j]):
            t.probation[j] = None
        elif stamp >= check or stamp >= until:
            t.probation[j] = (k, until, stamp + rp.check_period_s) if stamp < until else None
            ev = evidence(state, j, state.live_ids() - {k}, p)
            p_new = rp.p_new
            if not rev.keeps(ev, k, p_new, rp):
                t.id[j], t.probation[j] = state.memory.new_id(), None
                state.recovery.undone += 1
                result.recovery_undone.append((k, t.id[j]))
                result.new_ids.append(t.id[j])
                result.id_decisions.append(_explain(state, j, ev, p_new, t.id[j], "undone", rp.p_undo, k))


def kept_recovery(state: RobustTrackerState) -> dict[str, np.ndarray]:
    """The recovery's state as arrays for the ID memory's file; a live track counts as having
    left where and when it was last detected (after a restart that is where the person is)."""
    t = state.tracks
    live = {t.id[j]: rec.Departure(t.last_update[j], *t.fix[j], False, *stature_of(t, j)) for j in range(len(t))
            if t.id[j] and t.fix[j] is not None and not t.forgotten[j]}
    return state.recovery.to_arrays(live)


def load_recovery(state: RobustTrackerState, arrays: dict[str, np.ndarray]) -> None:
    """The recovery's state from the ID memory's file, for the remembered people only (ValueError
    when inconsistent); the first frame checks its departures against the clock
    (:meth:`~services.tracker.core.recovery.RecoveryState.settle`)."""
    loaded = rec.RecoveryState.from_arrays(arrays)
    loaded.forget(keep=set(state.memory.entries))
    state.recovery = loaded
