"""The evidence of open-set recovery (:mod:`~services.tracker.core.recovery`): for each remembered
person a newly confirmed track could be, the log-likelihood ratio of "same person" from the
association's cues (appearance, the remembered classifier, the stature), whether they could have
walked there, and what a stranger reaches. Pure numpy.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from services.tracker.core.cues import classifier as clf
from services.tracker.core.cues import stature as body
from services.tracker.core.cues.classifier import ClassifierParams
from services.tracker.core.identity import IdentityMemory
from services.tracker.core.recovery import (Departure, RecoveryParams, RecoveryState, posterior, reachable, stranger_llr,
                                            support)
from services.tracker.core.cues.stature import StatureParams

__all__ = ["Candidate", "Evidence", "evidence", "keeps", "min_distance"]


@dataclass(frozen=True)
class Candidate:
    """The newly confirmed track as recovery sees it: its gallery's ``descriptors`` (M, D), where it is
    (``stamp``, ``x``, ``y``, ``var`` per axis) and its ``stature`` from ``stature_n`` measurements."""

    descriptors: np.ndarray
    stamp: float
    x: float
    y: float
    var: float
    stature: float = 0.0
    stature_n: int = 0


@dataclass(frozen=True)
class Evidence:
    """What :func:`evidence` found: the remembered ``ids`` (K) the track could be, each one's
    log-likelihood ratio ``llr`` (K,), whether each could have walked there (``reach`` (K,)), the
    stranger's ``new_llr``, and ``rivals(k)``: the (K,) candidates known to be someone else than ``k``."""

    ids: list[int]
    llr: np.ndarray
    reach: np.ndarray
    new_llr: float
    together: dict[int, frozenset[int]]

    def rivals(self, k: int) -> np.ndarray:
        known = self.together.get(k, frozenset())
        return np.array([i in known for i in self.ids], bool)


def min_distance(x: np.ndarray, gallery: np.ndarray) -> float:
    """Smallest Euclidean distance from ``x`` (D,) to the rows of ``gallery`` (M, D) (``inf`` if none)."""
    if not len(gallery):
        return math.inf
    g = np.asarray(gallery, np.float32)
    d2 = float((np.einsum("ij,ij->i", g, g) - 2.0 * (g @ x)).min()) + float(x @ x)
    return math.sqrt(max(d2, 0.0))


def evidence(track: Candidate, memory: IdentityMemory, exclude: set[int], pair_llr: Callable[[np.ndarray], np.ndarray],
             others: list[np.ndarray], classifiers: dict[int, np.ndarray], classifier: ClassifierParams | None,
             state: RecoveryState, params: RecoveryParams, stature: StatureParams | None = None) -> Evidence:
    """The evidence for each remembered person (not in ``exclude``, e.g. the live IDs) ``track`` could
    be, by the association's cues: ``pair_llr`` (Euclidean distances -> the model's weighted log-odds)
    of the track's mean descriptor to the remembered gallery (Algorithm 2's distance), plus their
    classifier's weighted mean log-odds over the track's descriptors and, with ``stature``, the
    stature's log-odds against their departure's. The same measure against ``others`` (the
    galleries of the people in view now) gives the stranger's log-odds (:func:`stranger_llr`)."""
    mean = np.asarray(track.descriptors, np.float32).mean(axis=0)
    ids_a, dist = memory.distances(mean, exclude=exclude)
    ids = ids_a.tolist()
    llr = np.asarray(pair_llr(dist), float).copy()
    cohort = np.array([min_distance(mean, g) for g in others if len(g)])
    new_llr = stranger_llr(pair_llr(cohort)) if len(cohort) else 0.0
    departures = [state.departures.get(k) for k in ids]
    if ids:
        _add_classifiers(llr, track, ids, classifiers, classifier)
        _add_statures(llr, track, departures, stature)
        if params.left_weight < 1:  # who walked out seldom comes straight back
            llr += math.log(params.left_weight) * np.array([d is not None and d.left for d in departures])
    reach = reachable(track.stamp, track.x, track.y, track.var, departures, params)
    return Evidence(ids, llr, reach, new_llr, state.together)


def _add_classifiers(llr: np.ndarray, track: Candidate, ids: list[int], classifiers: dict[int, np.ndarray],
                     classifier: ClassifierParams | None) -> None:
    """``llr`` (K,) plus each remembered person's classifier's weighted mean log-odds over the
    track's descriptors, where they have one of the descriptors' size."""
    if classifier is None or not classifier.weight > 0:
        return
    u = clf.normalise(np.asarray(track.descriptors, np.float32))
    cols = [i for i, k in enumerate(ids) if len(classifiers.get(k, ())) == u.shape[1] + 1]
    if cols:
        w = np.stack([classifiers[ids[i]] for i in cols])
        llr[cols] += classifier.weight * clf.scores(w, u, classifier.clip).mean(axis=0)


def _add_statures(llr: np.ndarray, track: Candidate, departures: list[Departure | None],
                  stature: StatureParams | None) -> None:
    """``llr`` (K,) plus the track's stature's log-odds against each remembered person's."""
    if stature is None or not track.stature_n:  # a young track's few measurements, a learnt memory
        return
    known = [(d.stature, d.stature_n) if d is not None else (0.0, 0) for d in departures]
    lo = body.log_odds(np.array([track.stature]), np.array([h for h, _ in known]),
                       np.array([n for _, n in known], np.int64), stature)
    if lo is not None:
        llr += lo[0]


def keeps(ev: Evidence, k: int, p_new: float, params: RecoveryParams) -> bool:
    """During probation: whether the recovery of ``k`` still stands, its support (against "new"
    and its rivals) at least ``params.p_undo``."""
    post_new, post = posterior(np.where(ev.reach, ev.llr, -np.inf), p_new, ev.new_llr)
    return support(post_new, post, ev.ids.index(k), ev.rivals(k)) >= params.p_undo
