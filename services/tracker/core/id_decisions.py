"""Why a track has its ID: the robust profile's ID decisions, explained.

Each time the open-set ID memory (core/recovery.py) decides a newly confirmed person's ID, or
takes back a recovery during probation, the tracker reports an :class:`IdDecision`: the ID
given, the evidence for the most probable remembered people (their log-odds, their support
against "someone new" and their rivals, whether they could have walked there, whether they
had walked out of the view or were lost inside it, how long ago and how far away), the
posterior of "someone new" and the stranger's log-odds. The service logs them, and
``perception track --id-log`` writes them, so that a wrong ID can be traced to its cause
(a look-alike, a bar set too low, a walked-out person's weight) rather than guessed at.

Pure Python and numpy; built from the evidence the decision itself used (no second model).
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass
from typing import Literal

import numpy as np

from services.tracker.core import recovery as rec

__all__ = ["IdCandidate", "IdDecision", "explain"]

Outcome = Literal["new", "recovered", "undone"]

#: how many candidates a decision lists, the most probable first
TOP = 3


@dataclass(frozen=True)
class IdCandidate:
    """A remembered person an ID decision weighed: ``log_odds`` that the track is them (the
    appearance, their classifier and the walked-out prior: recovery's ``llr``), ``support``
    (their probability against "new" and their rivals: what must reach ``p_recover``),
    ``reachable`` (could have walked there since they left), and where they left:
    ``walked_out`` of the cameras' view (False: lost inside it, or the view was not known),
    ``away_s`` ago, ``distance_m`` from here (all three None when their departure is not
    known, e.g. remembered from a file written before a clock jump)."""

    id: int
    log_odds: float
    support: float
    reachable: bool
    walked_out: bool | None = None
    away_s: float | None = None
    distance_m: float | None = None

    def describe(self) -> str:
        where = ""
        if self.away_s is not None and self.distance_m is not None:
            how = "walked out of view" if self.walked_out else "last seen"
            where = f", {how} {self.away_s:.1f} s ago {self.distance_m:.1f} m away"
        if not self.reachable:
            return f"{self.id} (log-odds {self.log_odds:.2f}, could not have walked here{where})"
        return f"{self.id} (log-odds {self.log_odds:.2f}, support {self.support:.2f}{where})"


@dataclass(frozen=True)
class IdDecision:
    """One ID decision at ``stamp`` (s) for the track at (``x``, ``y``): ``outcome`` "new" (a
    fresh ``id``), "recovered" (the remembered ``id``) or "undone" (the recovery of
    ``previous_id`` taken back during probation; the track now has ``id``). ``support`` is the
    best candidate's, against ``threshold`` (``p_recover``, or ``p_undo`` for a check during
    probation); ``p_new`` the posterior of someone new; ``stranger_log_odds`` what a stranger
    reaches here (the people in view now); ``candidates`` the most probable first."""

    stamp: float
    id: int
    outcome: Outcome
    x: float
    y: float
    support: float
    threshold: float
    p_new: float
    stranger_log_odds: float
    candidates: tuple[IdCandidate, ...]
    previous_id: int | None = None

    def summary(self) -> str:
        """One line for a log."""
        listed = "; ".join(c.describe() for c in self.candidates) or "none"
        head = {"new": f"new ID {self.id}", "recovered": f"ID {self.id} recovered",
                "undone": f"recovery of ID {self.previous_id} undone, now ID {self.id}"}[self.outcome]
        if not any(c.reachable for c in self.candidates):
            why = "no remembered person could have walked here"
        else:
            op = ">=" if self.outcome == "recovered" else "<"
            why = f"support {self.support:.2f} {op} {self.threshold:.2f}"
        return (f"{head} at ({self.x:.2f}, {self.y:.2f}) m, t={self.stamp:.2f} s: {why}; P(new) {self.p_new:.2f}, "
                f"a stranger's log-odds {self.stranger_log_odds:.2f}; candidates: {listed}")

    def as_dict(self) -> dict[str, object]:
        """Plain values for JSON (infinite log-odds as None)."""
        out = asdict(self)
        for c in out["candidates"]:  # type: ignore[union-attr]
            if not math.isfinite(c["log_odds"]):
                c["log_odds"] = None
        return out

    @classmethod
    def from_dict(cls, data: dict[str, object]) -> IdDecision:
        """The decision :meth:`as_dict` wrote (other keys, e.g. ``frame``, ignored); ValueError
        naming what is missing or malformed."""
        try:
            cands = tuple(IdCandidate(**{**c, "log_odds": -math.inf if c.get("log_odds") is None else c["log_odds"]})
                          for c in data["candidates"])  # type: ignore[union-attr]
            known = {f for f in cls.__dataclass_fields__ if f != "candidates"}
            out = cls(**{k: v for k, v in data.items() if k in known}, candidates=cands)  # type: ignore[arg-type]
        except (KeyError, TypeError, AttributeError) as exc:
            raise ValueError(f"not an ID decision ({type(exc).__name__}: {exc})") from exc
        if out.outcome not in ("new", "recovered", "undone"):
            raise ValueError(f"not an ID decision: outcome {out.outcome!r} (new, recovered or undone)")
        return out


def explain(ev: rec.Evidence, p_new: float, stamp: float, x: float, y: float, track_id: int, outcome: Outcome,
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
