"""Why a track has its ID: the ID decisions of both profiles, explained as
:class:`~services.tracker.core.types.IdDecision` (the README's *Inputs and outputs*:
``id_decisions``), from the evidence the decision itself used (no second model): the open-set
recovery's (core/recovery.py) by :func:`explain`, Pinto's Algorithm 2 (the thesis profile) by
:func:`nearest`. ``perception track --id-log`` writes them and ``perception evaluate --identity
--id-log`` joins them to the ground truth, so that a wrong ID can be traced to its cause (a
look-alike, a bar set too low, a walked-out person's weight) rather than guessed at. Pure numpy.
"""

from __future__ import annotations

import math

import numpy as np

from services.tracker.core import recovery as rec
from services.tracker.core import recovery_evidence as rev
from services.tracker.core.association import AppearanceGate
from services.tracker.core.types import AppearanceModel, IdCandidate, IdDecision, IdOutcome

__all__ = ["TOP", "explain", "nearest"]

#: how many candidates a decision lists, the most probable first
TOP = 3


def explain(ev: rev.Evidence, p_new: float, stamp: float, x: float, y: float, track_id: int, outcome: IdOutcome,
            threshold: float, departures: dict[int, rec.Departure], previous_id: int | None = None) -> IdDecision:
    """The :class:`IdDecision` for evidence ``ev`` (:func:`~services.tracker.core.recovery.evidence`)
    weighed with the prior ``p_new``: the posterior and each candidate's support, as
    :func:`~services.tracker.core.recovery.decide` and :func:`~services.tracker.core.recovery.keeps`
    compute them. The first candidate is the most probable one, or for an undone recovery the
    person taken back (``previous_id``), whose support is the decision's."""
    llr = np.where(ev.reach, ev.llr, -np.inf)
    post_new, post = rec.posterior(llr, p_new, ev.new_llr)
    order = np.argsort(-post, kind="stable").tolist()
    if previous_id is not None and previous_id in ev.ids:
        first = ev.ids.index(previous_id)
        order = [first] + [i for i in order if i != first]
    order = order[:TOP]
    candidates = []
    for i in order:
        k = ev.ids[i]
        dep = departures.get(k)
        support = rec.support(post_new, post, i, ev.rivals(k)) if ev.reach[i] else 0.0
        candidates.append(IdCandidate(
            k, float(ev.llr[i]), support, bool(ev.reach[i]),
            None if dep is None else dep.left, None if dep is None else max(0.0, stamp - dep.stamp),
            None if dep is None else math.hypot(x - dep.x, y - dep.y)))
    best = candidates[0].support if candidates else 0.0
    return IdDecision(stamp, track_id, outcome, x, y, best, threshold, post_new, float(ev.new_llr), tuple(candidates),
                      previous_id)


def nearest(stamp: float, x: float, y: float, track_id: int, recovered: bool, ids: np.ndarray, dist: np.ndarray,
            t_recover: float, gate: AppearanceGate | None) -> IdDecision:
    """The :class:`IdDecision` of Pinto's Algorithm 2 (the thesis profile) for a track born at
    (``x``, ``y``): the remembered ``ids`` (K,) it weighed at descriptor distances ``dist`` (K,),
    the nearest first; ``recovered``: the nearest was below ``t_recover`` and gave ``track_id``.
    Each candidate's log-odds are the distance through the association's thresholds (``gate``:
    t_lower, t_upper), what the distance means on the model's calibrated scale. Algorithm 2 weighs
    neither where the candidates left nor when: every one is listed as reachable, with no departure."""
    model = None if gate is None else AppearanceModel(gate.t_lower, gate.t_upper, t_recover)
    order = np.argsort(dist, kind="stable")[:TOP].tolist()
    given = 1.0 if recovered else 0.0
    candidates = tuple(IdCandidate(int(ids[i]), float(model.log_odds(np.array(dist[i]))) if model else 0.0,
                                   given if k == 0 else 0.0, True, distance=float(dist[i]))
                       for k, i in enumerate(order))
    return IdDecision(stamp, track_id, "recovered" if recovered else "new", x, y, given, t_recover, 1.0 - given, 0.0,
                      candidates, rule="nearest")
