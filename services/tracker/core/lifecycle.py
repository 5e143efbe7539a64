"""The robust profile's life cycle, in time: ageing, birth, confirmation, hand-over, the ID
(Algorithm 2 of Pinto's thesis, open-set: core/recovery.py) and the archive.

* **Ageing.** A confirmed track that misses is *coasting*: it keeps its prediction and is
  deleted after ``max_coast_s`` without a detection or when its position variance passes
  ``max_position_var``; the time it spends out of every camera's view does not count, it
  has the limits ``max_coast_unseen_s`` and ``max_position_var_unseen`` (it cannot be
  detected there). A tentative track without a hit for ``tentative_timeout_s`` is dropped.
* **Birth** (Ban et al.'s birth candidates). A confident detection nobody explains starts a
  tentative track, unless it lies within ``birth_separation_m`` of a detection that went to
  a track or of a likelier birth (a second report of the same person).
* **Confirmation** (Basso/Munaro). After ``n_init`` confident hits, with an IsPerson
  probability of at least ``confirm_is_person``. The ID comes then: by hand-over from a
  track that left another camera's view (:func:`handover`), else a remembered person's by
  the open-set decision of core/recovery.py (:func:`identity`), else a new one. For
  ``recovery.probation_s`` a recovery is checked again and undone when the evidence turns
  (:func:`probation`).
* **Learning.** A matched track's online classifier (Basso/Munaro) takes one step on the
  frame's descriptors, its own detection against the others (:func:`train_classifiers`).
* **Archive.** A deleted track's gallery and classifier go to the ID memory, where and when
  it was last detected to the recovery's departures.

Each step is a function of the tracker's state (:class:`RobustTrackerState`) and its
settings. Pure numpy.
"""

from __future__ import annotations

import math

import numpy as np

from services.tracker.core import classifier as clf
from services.tracker.core import recovery as rec
from services.tracker.core import recovery_evidence as rev
from services.tracker.core import posture as pose
from services.tracker.core import stature
from services.tracker.core.id_decisions import explain
from services.tracker.core.robust_params import RobustParams
from services.tracker.core.tracks import RobustTrackerState, TrackTable
from services.tracker.core.types import FrameInput, FrameResult, HandOver, IdDecision, IdOutcome, TrackStatus
from services.tracker.core.view import View

_TENTATIVE, _CONFIRMED, _COASTING = TrackStatus.TENTATIVE, TrackStatus.CONFIRMED, TrackStatus.COASTING

__all__ = ["age", "archive", "birth", "births", "bayes", "confirm", "evidence", "handover", "identity", "kept_recovery",
           "load_recovery", "observed", "probation", "train_classifiers"]


def bayes(p: float, q: float) -> float:
    """Binary Bayes update of ``p`` with evidence ``q`` (both probabilities)."""
    num = p * q
    return num / (num + (1 - p) * (1 - q))


def age(state: RobustTrackerState, p: RobustParams, stamp: float, previous: float | None,
        view: View | None) -> tuple[list[int], list[bool]]:
    """Coasting, the tracks' view flags and the end of tracks at ``stamp`` (``previous``: the
    last frame's stamp). Returns the rows to delete (in order) and the rows to keep (neither:
    tentative tracks that did not go on, clutter)."""
    t = state.tracks
    coasting = []
    for j, last in enumerate(t.last_update):
        if stamp - last > 0 and t.status[j] is _CONFIRMED:
            t.status[j] = _COASTING
        if t.status[j] is _COASTING:
            coasting.append(j)
        else:
            t.in_view[j] = None
    if view is not None and coasting:
        seen = view.contains(t.mean[coasting, :3], p.view_margin)
        before = previous if previous is not None else stamp
        for j, s in zip(coasting, seen.tolist()):
            if t.in_view[j] is False:  # out of view since the last frame
                t.unseen_s[j] += max(0.0, stamp - max(before, t.last_update[j]))
            t.in_view[j] = s
    # in view, a track is dropped on the usual limits; the time out of every view does not count
    # towards max_coast_s, and a track that has been out of view has the wider variance bound
    # (it may come back into a view far from its prediction)
    var = (t.cov[:, 0, 0] + t.cov[:, 1, 1]).tolist()
    ended, keep = [], []
    for j, last in enumerate(t.last_update):
        gap, unseen = stamp - last, t.unseen_s[j]
        if t.status[j] is _TENTATIVE:
            keep.append(not gap > p.tentative_timeout_s)  # a birth candidate that did not go on: clutter
        elif (gap - unseen > p.max_coast_s or gap > p.max_coast_unseen_s or var[j] > p.max_position_var_unseen
              or (unseen == 0.0 and t.in_view[j] is not False and var[j] > p.max_position_var)):
            ended.append(j)
            keep.append(False)
        else:
            keep.append(True)
    return ended, keep


def archive(state: RobustTrackerState, j: int, view: View | None = None, horizon_s: float = 0.0) -> None:
    """Track ``j``'s gallery and classifier go to the ID memory (a forgotten person's do not), and
    where and when they left: whether they walked out of ``view`` (their last fix in it, and
    their walk out of it within ``horizon_s``)."""
    t = state.tracks
    if t.forgotten[j]:
        return
    if state.bank.size(t.slot[j]):
        state.memory.archive(t.id[j], state.bank.descriptors(t.slot[j]))
    if t.clf_steps[j] and t.clf is not None:
        state.classifiers[t.id[j]] = t.clf[j].copy()
    if len(state.classifiers) > len(state.memory):  # follow the memory's evictions and forgetting
        state.classifiers = {i: w for i, w in state.classifiers.items() if i in state.memory}
    fix, r = t.fix[j], state.recovery
    if fix is not None and t.id[j] in state.memory:  # where and when they left, for reachability
        r.departures[t.id[j]] = rec.Departure(t.last_update[j], *fix, walked_out(t, j, view, horizon_s),
                                              *_stature(t, j))
    if len(r.departures) > len(state.memory) or len(r.together) > 2 * len(state.memory) + 64:
        r.forget(keep=set(state.memory.entries) | state.live_ids())


def _stature(t: TrackTable, j: int) -> tuple[float, int]:
    """Track ``j``'s stature and its count of measurements (0, 0: none), as a departure keeps them."""
    n = int(t.stature_n[j])
    return (float(t.stature[j]) if n else 0.0), n


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


def birth(state: RobustTrackerState, dets: list[int], positions: np.ndarray, descriptors: np.ndarray | None,
          has_desc: np.ndarray, p_det: np.ndarray, stamp: float, camera: str, p0: np.ndarray,
          statures: np.ndarray | None = None) -> None:
    """A tentative track at rest (not turning) per detection of ``dets``, with its descriptor and
    its stature (``statures``: the frame's, NaN where not measured)."""
    if not dets:
        return
    t = state.tracks
    d = np.asarray(dets)
    mean = np.concatenate([positions[d], np.zeros((len(d), t.mean.shape[1] - 3))], axis=1)
    first = len(t)
    t.append(mean, p0, stamp, [bayes(0.5, q) for q in p_det[d].tolist()], camera)
    if statures is not None:  # the new rows' arrays are this frame's own (append made them)
        h = statures[d]
        known = np.flatnonzero(np.isfinite(h))
        t.stature[first + known], t.stature_n[first + known] = h[known], 1
    if descriptors is None:
        return
    rows = [first + k for k, det in enumerate(dets) if has_desc[det]]
    if rows:
        for j in rows:
            t.slot[j] = state.bank.allocate(descriptors.shape[1])
        state.bank.add_many(np.array([t.slot[j] for j in rows]), descriptors[d[has_desc[d]]], None)


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
    """Hand-over by motion: the track coasting out of view, last seen by another camera than the
    one track ``j`` was born in, whose prediction the newly confirmed ``j`` is nearest (squared
    Mahalanobis distance on (x, y) within ``gate``), which ``j`` replaces (it takes its gallery,
    classifier and stature too; ``removed`` gets it): (its row, that distance), None when there is none.
    A person leaving one camera's view and coming back into it is left to appearance."""
    if gate is None:
        return None
    t, bank = state.tracks, state.bank
    best, best_d2 = -1, gate
    for c, status in enumerate(t.status):
        if (status is not _COASTING or t.in_view[c] is not False or not t.id[c] or t.forgotten[c] or c in removed
                or not t.camera[c] or t.camera[c] == t.camera[j]):  # the same camera: re-identification's job
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
    if t.clf_steps[best] and t.clf_steps[j] == 0 and t.clf is not None:
        t.clf[j], t.clf_steps[j] = t.clf[best], t.clf_steps[best]
    n_old, n_new = int(t.stature_n[best]), int(t.stature_n[j])
    if n_old:  # the stature too: the measurements of both, weighed by their counts
        t.stature[j] = (t.stature[best] * n_old + t.stature[j] * n_new) / (n_old + n_new)
        t.stature_n[j] = n_old + n_new
    removed.add(best)
    return best, best_d2


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
    p_new = state.recovery.p_new(rp)
    decision = rec.decide(ev.llr, ev.reach, p_new, rp, ev.new_llr, lambda i: ev.rivals(ev.ids[i]))
    state.recovery.count(decision, rp)
    k, stamp = (state.memory.new_id() if decision.index is None else ev.ids[decision.index]), t.last_update[j]
    if result is not None and ev.ids:
        result.id_decisions.append(_explain(state, j, ev, p_new, k, "new" if decision.index is None else "recovered",
                                            rp.p_recover))
    if decision.index is None:
        return k, False
    if rp.probation_s > 0:
        t.probation[j] = (k, stamp + rp.probation_s, stamp + rp.check_period_s, 1.0 - decision.p_new)
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
                         0.5 * float(t.cov[j, 0, 0] + t.cov[j, 1, 1]), float(t.stature[j]), int(t.stature_n[j]))
    others = [bank.descriptors(t.slot[c]) for c in range(len(t)) if c != j and t.id[c] and bank.size(t.slot[c])]
    return rev.evidence(here, state.memory, exclude,
                        lambda d: p.appearance_weight * model.log_odds(model.from_euclidean(d)),
                        others, state.classifiers, p.classifier, state.recovery, p.recovery, p.stature)


def observed(state: RobustTrackerState, rows: list[int], p: RobustParams) -> None:
    """The tracks ``rows`` were detected in this frame: their fixes (where, for reachability) and
    that they are different people (core/recovery.py's rivals). Position-only: nothing (no
    recovery without appearance; a departure not known later makes a person reachable)."""
    t = state.tracks
    if not rows or p.appearance is None:
        return
    xy, var = t.mean[rows, :2].tolist(), (0.5 * (t.cov[rows, 0, 0] + t.cov[rows, 1, 1])).tolist()
    for j, (x, y), v in zip(rows, xy, var):
        t.fix[j] = (x, y, v)
    state.recovery.seen_together([t.id[j] for j in rows if t.id[j]])


def probation(state: RobustTrackerState, p: RobustParams, stamp: float, result: FrameResult) -> None:
    """Check recent recoveries again with the tracks' grown galleries; undo those that no longer
    stand (core/recovery.py): a fresh ID, the remembered person stays remembered, counted."""
    rp, t = p.recovery, state.tracks
    for j, prob in enumerate(t.probation):
        if prob is None:
            continue
        k, until, check, share = prob
        if t.id[j] != k or t.forgotten[j] or k not in state.memory or not state.bank.size(t.slot[j]):
            t.probation[j] = None
        elif stamp >= check or stamp >= until:
            t.probation[j] = (k, until, stamp + rp.check_period_s, share) if stamp < until else None
            ev = evidence(state, j, state.live_ids() - {k}, p)
            p_new = state.recovery.p_new(rp)
            if not rev.keeps(ev, k, p_new, rp):
                t.id[j], t.probation[j] = state.memory.new_id(), None
                state.recovery.undone += 1
                state.recovery.revise(share)
                result.recovery_undone.append((k, t.id[j]))
                result.new_ids.append(t.id[j])
                result.id_decisions.append(_explain(state, j, ev, p_new, t.id[j], "undone", rp.p_undo, k))


def train_classifiers(state: RobustTrackerState, p: RobustParams, matches: list[tuple[int, int]], u: np.ndarray | None,
                      has_desc: np.ndarray, confident: np.ndarray) -> None:
    """One step of the online classifier (Basso/Munaro) of every track matched with a confident
    descriptor while others are in view (``u``: the frame's unit descriptors, one row per
    detection with ``has_desc``); a forgotten person's track learns nothing."""
    cp, t = p.classifier, state.tracks
    if cp is None or u is None or p.appearance is None or has_desc.sum() < 2:
        return
    row_of, sure = (np.cumsum(has_desc) - 1).tolist(), (has_desc & confident).tolist()  # detection -> its row of u
    pairs = [(row_of[d], j) for d, j in matches if sure[d] and not t.forgotten[j]]
    if not pairs:
        return
    dim = u.shape[1]
    if t.clf is None or t.clf.shape[1] != dim + 1:
        t.clf, t.clf_steps = np.zeros((len(t), dim + 1)), [0] * len(t)
    rows = [j for _, j in pairs]
    positive = np.array([r for r, _ in pairs])
    if rows == list(range(len(t))):  # every track learns: new weights, no gather
        t.clf = clf.train(t.clf, u, positive, cp)
    else:
        t.clf[rows] = clf.train(t.clf[rows], u, positive, cp)
    steps = t.clf_steps
    for j in rows:
        steps[j] += 1


def observe_body(state: RobustTrackerState, p: RobustParams, rows: np.ndarray, frame: FrameInput, moved: bool,
                 confident: np.ndarray) -> None:
    """The tracks matched in ``frame`` (``rows``: detections, tracks): TU Ilmenau's posture from
    the body height and box shape, orientation from walking or, standing still, from the crop
    classifier (:func:`posture.observe`; ``moved``: the arrays are this frame's own); and the
    stature of each confident detection that has one (core/stature.py), none for a forgotten
    person's track."""
    t, pp = state.tracks, p.posture
    if not rows.shape[1]:
        return
    d_idx, t_idx = rows
    if pp is not None:
        t.posture, t.orientation = pose.observe(
            t.posture, t.orientation, t_idx, frame.positions[d_idx, 2],
            None if frame.aspects is None else frame.aspects[d_idx], t.mean[t_idx, 3:5],
            np.array([t.status[j] is TrackStatus.TENTATIVE for j in t_idx.tolist()]),
            None if frame.orientations is None else frame.orientations[d_idx], pp, fresh=moved,
            reported=None if frame.postures is None else frame.postures[d_idx])
    if p.stature is not None and frame.statures is not None:
        ok = confident[d_idx] & ~np.array([t.forgotten[j] for j in t_idx.tolist()], bool)
        t.stature, t.stature_n = stature.observe(t.stature, t.stature_n, t_idx[ok], frame.statures[d_idx][ok],
                                                 p.stature)


def kept_recovery(state: RobustTrackerState) -> dict[str, np.ndarray]:
    """The recovery's state as arrays for the ID memory's file; a live track counts as having
    left where and when it was last detected (after a restart that is where the person is)."""
    t = state.tracks
    live = {t.id[j]: rec.Departure(t.last_update[j], *t.fix[j], False, *_stature(t, j)) for j in range(len(t))
            if t.id[j] and t.fix[j] is not None and not t.forgotten[j]}
    return state.recovery.to_arrays(live)


def load_recovery(state: RobustTrackerState, arrays: dict[str, np.ndarray]) -> None:
    """The recovery's state from the ID memory's file, for the remembered people only (ValueError
    when inconsistent); the first frame checks its departures against the clock
    (:meth:`~services.tracker.core.recovery.RecoveryState.settle`)."""
    loaded = rec.RecoveryState.from_arrays(arrays)
    loaded.forget(keep=set(state.memory.entries))
    state.recovery = loaded
