"""The robust profile's life cycle, in time: ageing, birth, confirmation, hand-over, the ID
(Algorithm 2 of Pinto's thesis through the calibrated model, Basso/Munaro's recovery by
classifier) and the archive.

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
  track that left another camera's view (:func:`handover`), else a remembered person's
  (:func:`identity`, :func:`recover_by_classifier`), else a new one.
* **Archive.** A deleted track's gallery and classifier go to the ID memory.

Each step is a function of the tracker's state (:class:`RobustTrackerState`) and its
settings. Pure numpy.
"""

from __future__ import annotations

import numpy as np

from services.tracker.core import classifier as clf
from services.tracker.core.robust_params import RobustParams
from services.tracker.core.tracks import RobustTrackerState
from services.tracker.core.types import FrameResult, TrackStatus
from services.tracker.core.view import FieldOfView, Views

_TENTATIVE, _CONFIRMED, _COASTING = TrackStatus.TENTATIVE, TrackStatus.CONFIRMED, TrackStatus.COASTING

__all__ = ["age", "archive", "birth", "births", "bayes", "confirm", "handover", "identity", "recover_by_classifier"]


def bayes(p: float, q: float) -> float:
    """Binary Bayes update of ``p`` with evidence ``q`` (both probabilities)."""
    num = p * q
    return num / (num + (1 - p) * (1 - q))


def age(state: RobustTrackerState, p: RobustParams, stamp: float, previous: float | None,
        view: FieldOfView | Views | None) -> tuple[list[int], list[bool]]:
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


def archive(state: RobustTrackerState, j: int) -> None:
    """Track ``j``'s gallery and classifier go to the ID memory (a forgotten person's do not)."""
    t = state.tracks
    if t.forgotten[j]:
        return
    if state.bank.size(t.slot[j]):
        state.memory.archive(t.id[j], state.bank.descriptors(t.slot[j]))
    if t.clf_steps[j] and t.clf is not None:
        state.classifiers[t.id[j]] = t.clf[j].copy()
    if len(state.classifiers) > len(state.memory):  # follow the memory's evictions and forgetting
        state.classifiers = {i: w for i, w in state.classifiers.items() if i in state.memory}


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
          has_desc: np.ndarray, p_det: np.ndarray, stamp: float, camera: str, p0: np.ndarray) -> None:
    """A tentative track at rest (not turning) per detection of ``dets``, with its descriptor."""
    if not dets:
        return
    t = state.tracks
    d = np.asarray(dets)
    mean = np.concatenate([positions[d], np.zeros((len(d), t.mean.shape[1] - 3))], axis=1)
    first = len(t)
    t.append(mean, p0, stamp, [bayes(0.5, q) for q in p_det[d].tolist()], camera)
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
        if handed is not None:
            t.id[j] = handed
            result.new_ids.append(handed)
            result.recovered_ids.append(handed)
            continue
        track_id, recovered = identity(state, j, removed, p)
        t.id[j] = track_id
        result.new_ids.append(track_id)
        if recovered:
            result.recovered_ids.append(track_id)
    return removed


def handover(state: RobustTrackerState, j: int, removed: set[int], gate: float | None) -> int | None:
    """Hand-over by motion: the ID of the track coasting out of view, last seen by another
    camera than the one track ``j`` was born in, whose prediction the newly confirmed ``j``
    is nearest (squared Mahalanobis distance on (x, y) within ``gate``), which ``j`` replaces
    (it takes its gallery and classifier too; ``removed`` gets it); None when there is none.
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
    removed.add(best)
    return t.id[best]


def identity(state: RobustTrackerState, j: int, removed: set[int], p: RobustParams) -> tuple[int, bool]:
    """Algorithm 2 through the calibrated model: a remembered person nearer than ``t_recover``
    to the mean of track ``j``'s gallery, else one whose classifier recognises it, else a new ID."""
    model, memory = p.appearance, state.memory
    slot = state.tracks.slot[j]
    if model is None or not state.bank.size(slot) or not memory.entries:
        return memory.new_id(), False
    live = state.live_ids(removed)
    gallery = state.bank.descriptors(slot)
    ids, dist = memory.distances(gallery.mean(axis=0), exclude=live)
    if len(ids):
        dist = model.from_euclidean(dist)
        best = int(np.argmin(dist))
        if dist[best] < model.t_recover:
            return int(ids[best]), True
    recovered = recover_by_classifier(state, gallery, live, p)
    if recovered is not None:
        return recovered, True
    return memory.new_id(), False


def recover_by_classifier(state: RobustTrackerState, gallery: np.ndarray, live: set[int],
                          p: RobustParams) -> int | None:
    """Basso/Munaro's recovery: the remembered people's classifiers score the new track's views
    (``gallery`` (M, D)); the best mean log-odds above ``recover_score`` gives its ID back."""
    cp = p.classifier
    u = clf.normalise(gallery)
    cands = [(i, w) for i, w in state.classifiers.items()
             if i not in live and i in state.memory and len(w) == u.shape[1] + 1]
    if cp is None or not cands:
        return None
    s = clf.scores(np.stack([w for _, w in cands]), u, cp.clip).mean(axis=0)
    best = int(np.argmax(s))
    return int(cands[best][0]) if s[best] >= cp.recover_score else None
