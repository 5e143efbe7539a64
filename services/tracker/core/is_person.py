"""IsPerson per detector (the TU Ilmenau framework, section 4, "Modeling of Detectors' Uncertainties"):
each track keeps a binary Bayes belief per detector that saw it, updated with that detector's
calibrated P(true person) and drifting back to 0.5 with that detector's time constant; the track's
IsPerson is their normalised product (the form of the framework's Eq 1, 0.5 neutral). A detector's
belief is bounded by its ``max_is_person``: a 2-D laser's legs, which chair and table legs imitate,
can support a person the camera confirmed, and make a camera's first sight of a person the laser
followed confirm them sooner, but never confirm anyone alone.

The table keeps, per track, in ``is_person`` the product and in ``beliefs`` either the name of the
only detector that saw it (its belief is then ``is_person`` itself: one camera costs what a single
belief costs) or a dict of the beliefs by detector, replaced, never changed in place (snapshots
share the lists' entries). Pure Python.
"""

from __future__ import annotations

import math

from services.tracker.core.tracks import TrackTable

__all__ = ["combine", "fade", "first", "update"]


def combine(beliefs: dict[str, float]) -> float:
    """The normalised product of the detectors' beliefs."""
    yes = no = 1.0
    for q in beliefs.values():
        yes *= q
        no *= 1.0 - q
    return yes / (yes + no)


def _bayes(p: float, q: float) -> float:
    num = p * q
    return num / (num + (1 - p) * (1 - q))


def first(p_true: list[float], cap: float) -> list[float]:
    """New tracks' beliefs from their first detections' P(true person), bounded by ``cap``."""
    return [min(cap, q) for q in p_true]


def update(t: TrackTable, pairs: list[tuple[int, int]], p_true: list[float], detector: str, cap: float) -> None:
    """Tracks ``j`` seen by detections ``d`` (``pairs``) of ``detector``, P(true person) ``p_true[d]``."""
    is_person, beliefs = t.is_person, t.beliefs
    for d, j in pairs:
        b = beliefs[j]
        if b == detector:  # the only detector that saw it: the belief is is_person
            is_person[j] = min(cap, _bayes(is_person[j], p_true[d]))
            continue
        both = {b: is_person[j]} if isinstance(b, str) else dict(b)
        both[detector] = min(cap, _bayes(both.get(detector, 0.5), p_true[d]))
        beliefs[j] = both
        is_person[j] = combine(both)


def fade(t: TrackTable, dt: float, tau_s: float, taus: dict[str, float]) -> None:
    """Every belief drifts back to 0.5 over ``dt`` s, with its detector's time constant (``taus``,
    by detector; the others ``tau_s``)."""
    f = math.exp(-dt / tau_s)
    if not taus and all(isinstance(b, str) for b in t.beliefs):
        t.is_person = [0.5 + (q - 0.5) * f for q in t.is_person]
        return
    fades = {k: math.exp(-dt / tau) for k, tau in taus.items()}
    is_person, beliefs = list(t.is_person), list(t.beliefs)
    for j, b in enumerate(beliefs):
        if isinstance(b, str):
            is_person[j] = 0.5 + (is_person[j] - 0.5) * fades.get(b, f)
        else:
            faded = {k: 0.5 + (q - 0.5) * fades.get(k, f) for k, q in b.items()}
            beliefs[j], is_person[j] = faded, combine(faded)
    t.is_person, t.beliefs = is_person, beliefs
