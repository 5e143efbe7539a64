"""Open-set recovery: is a newly confirmed person someone new, or remembered person k? (The
README's glossary: recovery, probation, rivals, the stranger's level.)

Asked only "which remembered person is nearest, and is that near enough?", the ID memory (Pinto's
Algorithm 2) also hands old IDs to people it has never seen, and the more people it remembers the
likelier some stranger looks like one of them. Here the hypotheses are "someone new" (log-odds 0,
as Ban et al.'s clutter-or-new-person class) and each remembered person k the track could be, and
k gets the ID only when more probable than all the others together:

* **Evidence** ``llr[k]``: the association's cues and arithmetic (log-odds add), gathered by
  :mod:`~services.tracker.core.recovery_evidence`.
* **Prior**: P(new) = ``p_new``, the rest shared evenly by the K candidates: a larger memory never
  makes the decision more eager. (P(new) estimated online, from the share of newcomers among recent
  contested confirmations, was tried and left: it lost the simulator's IDF1, docs/results.md.)
* **Support**: the best candidate's posterior against "new" and its *rivals*, the candidates
  detected in one frame with it (certainly someone else): two different people alike share the
  probability and neither reaches ``p_recover``, while two IDs never seen together may be one
  person remembered twice, and then either is right: they do not compete.
* **Reachability**: a candidate who could not have walked here since they left (``max_speed``,
  give or take ``n_sigma``) has likelihood 0 (their share of the prior goes to the others).
* **Undo**: for ``probation_s`` the support is checked again every ``check_period_s`` as the
  gallery grows; below ``p_undo`` the track gets a fresh ID, the remembered person stays.

Pure numpy; no tracker state beyond the small :class:`RecoveryState`.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np


__all__ = ["ARRAY_KEYS", "Decision", "Departure", "RecoveryParams", "RecoveryState", "decide", "posterior", "reachable",
           "stranger_llr", "support"]


@dataclass(frozen=True)
class RecoveryParams:
    """How sure the ID memory must be before it gives a remembered ID, and when it takes it back
    (the README's *Settings*, ``robust.recovery``, says what each does). ``p_new`` 0.3 by the rule of
    docs/results.md (*How P(new) was chosen*); ``p_undo`` below ``p_recover``, a hysteresis, so noise
    about the bar does not flip a recovery; ``max_speed``: brisk walking is about 1.8 to 2.5 m/s (a
    robot that moves the tracking frame would add its own speed)."""

    p_new: float = 0.3
    p_recover: float = 0.5
    p_undo: float = 0.25
    max_speed: float = 2.5  # m/s
    n_sigma: float = 3.0
    probation_s: float = 3.0
    check_period_s: float = 0.5
    compete: bool = True  # the ID memory competes in the association (cues/memory.py)
    left_weight: float = 1.0
    exit_horizon_s: float = 1.0

    def __post_init__(self) -> None:
        if not 0 < self.p_new < 1:
            raise ValueError(f"p_new must be in (0, 1), got {self.p_new}")
        if not 0 < self.p_undo <= self.p_recover < 1:
            raise ValueError(f"need 0 < p_undo <= p_recover < 1, got {self.p_undo}, {self.p_recover}")
        if not (self.max_speed > 0 and self.n_sigma >= 0):
            raise ValueError("need max_speed > 0 and n_sigma >= 0")
        if not (0 < self.left_weight <= 1 and self.exit_horizon_s >= 0):
            raise ValueError(f"need 0 < left_weight <= 1 and exit_horizon_s >= 0, got {self.left_weight}, "
                             f"{self.exit_horizon_s}")
        if not (self.probation_s >= 0 and self.check_period_s > 0):
            raise ValueError("need probation_s >= 0 and check_period_s > 0")


@dataclass(frozen=True)
class Departure:
    """Where and when a remembered person was last detected (``stamp`` s, ``x``, ``y`` m, ``var`` m^2
    per axis); ``left``: they walked out of the cameras' view there; their ``stature`` (m) from
    ``stature_n`` measurements (0: not known)."""

    stamp: float
    x: float
    y: float
    var: float
    left: bool = False
    stature: float = 0.0
    stature_n: int = 0


#: the arrays of :meth:`RecoveryState.to_arrays`, as the ID memory's file stores them
ARRAY_KEYS = ("recovery_departure_ids", "recovery_departures", "recovery_together_ids", "recovery_together_counts",
              "recovery_together_with")


@dataclass
class RecoveryState:
    """What recovery remembers besides the descriptors: each remembered ID's departure, and who
    was seen with whom."""

    departures: dict[int, Departure] = field(default_factory=dict)
    #: ID -> the IDs it was detected in the same frame with (certainly other people); frozensets,
    #: replaced and never changed in place, so a copy of the dict is a copy of the state
    together: dict[int, frozenset[int]] = field(default_factory=dict)
    #: recoveries undone so far
    undone: int = 0
    #: the last group recorded: a frame with the same people (or fewer of them) adds nothing
    last_group: frozenset[int] = frozenset()

    def copy(self) -> RecoveryState:
        return RecoveryState(dict(self.departures), dict(self.together), self.undone, self.last_group)

    def to_arrays(self, live: dict[int, Departure] | None = None) -> dict[str, np.ndarray]:
        """The state as plain arrays (:data:`ARRAY_KEYS`), for the ID memory's file; ``live``: the
        people tracked now, kept as if they left where and when they were last detected."""
        deps = {**self.departures, **(live or {})}
        ids = sorted(deps)
        groups = sorted(self.together)
        return {"recovery_departure_ids": np.array(ids, np.int64),
                "recovery_departures": np.array([[d.stamp, d.x, d.y, d.var, float(d.left), d.stature, float(d.stature_n)]
                                                 for d in (deps[i] for i in ids)], np.float64).reshape(-1, 7),
                "recovery_together_ids": np.array(groups, np.int64),
                "recovery_together_counts": np.array([len(self.together[i]) for i in groups], np.int64),
                "recovery_together_with": np.array([o for i in groups for o in sorted(self.together[i])], np.int64)}

    @classmethod
    def from_arrays(cls, arrays: dict[str, np.ndarray]) -> RecoveryState:
        """The state :meth:`to_arrays` wrote (keys it lacks: empty); ``ValueError`` saying which
        block is inconsistent; an older file's ``recovery_counts`` are ignored)."""
        return cls(_departures_of(arrays), _groups_of(arrays))

    def settle(self, stamp: float) -> None:
        """The first frame after a start at ``stamp``: departures stamped later are of another
        clock (a replay or a simulator from its start), and then none of them can be trusted."""
        if any(d.stamp > stamp for d in self.departures.values()):
            self.departures = {}

    def seen_together(self, ids: list[int]) -> None:
        """The people of ``ids`` were detected in one frame: each is someone else than the others."""
        if len(ids) < 2:
            return
        group = frozenset(ids)
        if group <= self.last_group:
            return
        self.last_group = group
        empty: frozenset[int] = frozenset()
        for i in group:
            known = self.together.get(i, empty)
            if not group <= known | {i}:
                self.together[i] = known | (group - {i})

    def forget(self, keep: set[int] | None = None, drop: int | None = None) -> None:
        """Drop what is known of ``drop``, or of every ID not in ``keep``."""
        self.last_group = frozenset()
        if drop is not None:
            self.departures.pop(drop, None)
            self.together.pop(drop, None)
        if keep is not None:
            self.departures = {i: d for i, d in self.departures.items() if i in keep}
            self.together = {i: s & keep for i, s in self.together.items() if i in keep}


@dataclass(frozen=True)
class Decision:
    """``index``: the recovered candidate (None: someone new); ``p``: the best candidate's
    posterior; ``p_new``: the posterior of "new"; ``contested``: whether any remembered candidate
    was reachable (else "new" was the only hypothesis)."""

    index: int | None
    p: float
    p_new: float
    contested: bool = False


def stranger_llr(cohort_llr: np.ndarray) -> float:
    """The log-likelihood ratio a stranger is expected to reach here, from ``cohort_llr``: the
    same evidence measured against people who certainly are someone else (those in view now).
    For a calibrated ratio its mean over different people is 1 (log 0); where the people around
    look alike (everyone in dark clothes) it is larger, and "new" explains the evidence as well
    as a remembered person would. The mean is shrunk towards 1 by one pseudo-observation, and
    never below 1 (an empty or unlike cohort leaves the calibration as it is)."""
    lr = np.exp(np.minimum(np.asarray(cohort_llr, float).reshape(-1), 50.0))
    return max(0.0, math.log((1.0 + float(lr.sum())) / (1.0 + len(lr))))


def posterior(llr: np.ndarray, p_new: float, new_llr: float = 0.0) -> tuple[float, np.ndarray]:
    """(P(new | evidence), P(k | evidence) (K,)) from the candidates' log-likelihood ratios
    ``llr`` (K,) (``-inf``: impossible), the prior ``p_new``, the rest of the prior shared
    evenly by the K candidates, and the new class's own ``new_llr`` (:func:`stranger_llr`; 0
    for the calibrated model)."""
    llr = np.asarray(llr, float).reshape(-1)
    k = len(llr)
    if k == 0:
        return 1.0, np.zeros(0)
    logits = np.concatenate([[math.log(p_new) + new_llr], math.log((1.0 - p_new) / k) + llr])
    top = float(np.max(logits))
    w = np.exp(logits - top)
    w /= w.sum()
    return float(w[0]), w[1:]


def reachable(stamp: float, x: float, y: float, var: float, departures: list[Departure | None],
              params: RecoveryParams) -> np.ndarray:
    """(K,) whether each candidate could have walked from its departure to ``(x, y)`` (variance
    ``var`` per axis) by ``stamp``. A candidate without a departure (e.g. remembered from a
    file, or from before a clock jump) is reachable."""
    out = np.ones(len(departures), bool)
    for i, d in enumerate(departures):
        if d is None:
            continue
        walk = params.max_speed * max(0.0, stamp - d.stamp)
        slack = params.n_sigma * math.sqrt(max(0.0, var) + max(0.0, d.var))
        out[i] = math.hypot(x - d.x, y - d.y) <= walk + slack
    return out


def support(post_new: float, post: np.ndarray, index: int, rivals: np.ndarray | None = None) -> float:
    """Candidate ``index``'s probability against "new" and its ``rivals`` (K,) bool (None: every
    other candidate): ``P(k) / (P(k) + P(new) + sum of the rivals' P)``."""
    others = np.delete(post, index) if rivals is None else post[np.asarray(rivals, bool)]
    p = float(post[index])
    den = p + post_new + float(others.sum())
    return p / den if den > 0 else 0.0


def decide(llr: np.ndarray, reach: np.ndarray, p_new: float, params: RecoveryParams, new_llr: float = 0.0,
           rivals: Callable[[int], np.ndarray] | None = None) -> Decision:
    """The open-set decision: the most probable candidate if its :func:`support` reaches
    ``params.p_recover``, else someone new. ``reach`` (K,) False gives that candidate
    likelihood 0; ``new_llr`` as in :func:`posterior`; ``rivals(k)`` the (K,) candidates known
    to be someone else than ``k`` (None: all of them)."""
    llr = np.where(np.asarray(reach, bool), np.asarray(llr, float), -np.inf)
    post_new, post = posterior(llr, p_new, new_llr)
    if not np.isfinite(llr).any():
        return Decision(None, 0.0, post_new)
    best = int(np.argmax(post))
    p = support(post_new, post, best, None if rivals is None else rivals(best))
    return Decision(best if p >= params.p_recover else None, p, post_new, True)


def _array(arrays: dict[str, np.ndarray], key: str, shape: tuple[int, ...], dtype: type) -> np.ndarray:
    return np.asarray(arrays.get(key, np.zeros(shape, dtype)))


def _departures_of(arrays: dict[str, np.ndarray]) -> dict[int, Departure]:
    """The departures :meth:`RecoveryState.to_arrays` wrote (older files: 4 or 5 values a row)."""
    ids, deps = _array(arrays, "recovery_departure_ids", (0,), np.int64), _array(arrays, "recovery_departures",
                                                                                 (0, 7), np.float64)
    if (deps.ndim != 2 or deps.shape[1] not in (4, 5, 7) or len(deps) != len(ids) or not np.all(np.isfinite(deps))
            or (deps.shape[1] == 7 and np.any(deps[:, 6] < 0))):
        raise ValueError(f"recovery departures: {len(ids)} ids, values of shape {deps.shape} "
                         "(need finite (K, 7), or (K, 4) or (K, 5) from an older file)")
    return {int(i): Departure(*row[:4], bool(row[4]) if len(row) > 4 else False,
                              *((row[5], int(row[6])) if len(row) > 6 else ()))
            for i, row in zip(ids.tolist(), deps.tolist())}


def _groups_of(arrays: dict[str, np.ndarray]) -> dict[int, frozenset[int]]:
    """Who was seen with whom, as :meth:`RecoveryState.to_arrays` wrote it."""
    groups = _array(arrays, "recovery_together_ids", (0,), np.int64)
    counts = _array(arrays, "recovery_together_counts", (0,), np.int64)
    others = _array(arrays, "recovery_together_with", (0,), np.int64)
    if len(groups) != len(counts) or np.any(counts < 0) or int(counts.sum()) != len(others):
        raise ValueError(f"recovery groups: {len(groups)} ids, {len(counts)} counts, {len(others)} members")
    bounds = np.concatenate([[0], np.cumsum(counts)]).tolist()
    members = others.tolist()
    return {int(i): frozenset(members[a:b]) for i, a, b in zip(groups.tolist(), bounds, bounds[1:])}
