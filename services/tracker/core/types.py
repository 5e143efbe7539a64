"""What every tracker core takes and gives: one frame's input, the tracks it reports, why they
have their IDs, the embedding model's and the detector's calibrations. Shared by both profiles
(:mod:`~services.tracker.core.thesis`, :mod:`~services.tracker.core.robust`) and by
everything that drives them through :class:`~services.tracker.core.protocol.TrackerCore`.

Pure numpy; no I/O.
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass, field, fields
from enum import Enum
from typing import TYPE_CHECKING, Literal, NamedTuple

import numpy as np

if TYPE_CHECKING:
    from common.geometry.occupancy import ObstacleMap
    from services.tracker.core.view import View

__all__ = ["AppearanceModel", "FrameInput", "FrameResult", "HandOver", "IdCandidate", "IdDecision", "IdOutcome", "IdRule",
           "KeptMemory", "ScoreModel", "TrackStatus", "TrackReport"]


class TrackStatus(str, Enum):
    TENTATIVE = "tentative"
    CONFIRMED = "confirmed"
    COASTING = "coasting"  # confirmed, missed lately: reported with its prediction (robust profile)
    DELETED = "deleted"


@dataclass(frozen=True)
class TrackReport:
    """A read-only picture of a track after an update."""

    id: int
    status: TrackStatus
    mean: np.ndarray
    cov: np.ndarray
    hits: int
    misses: int
    age_s: float
    last_update: float
    gallery_size: int
    ever_confirmed: bool = False
    #: whether the camera could see the track's position at this update (None: not known)
    in_view: bool | None = None
    #: P(standing, sitting, lying) (3,) and P(orientation bin) (8,); None: not estimated
    posture: np.ndarray | None = None
    orientation: np.ndarray | None = None
    #: the person's stature (m), the running mean of their measured ones; None: not measured
    stature: float | None = None

    @classmethod
    def of_fields(cls, *values: object) -> TrackReport:
        """A report from all its fields in order, made as a plain class would be: a frozen dataclass's
        ``__init__`` sets every field through ``object.__setattr__``, twice as slow, and the robust
        core makes one report per track per frame."""
        report = object.__new__(cls)
        report.__dict__.update(zip(_REPORT_FIELDS, values))
        return report

    @property
    def position(self) -> np.ndarray:
        return self.mean[:3]

    @property
    def velocity(self) -> np.ndarray:
        return self.mean[3:]


_REPORT_FIELDS = tuple(f.name for f in fields(TrackReport))


#: what an ID decision did: a fresh ID, a remembered one, a recovery taken back, or the ID of a
#: track another camera lost (a hand-over by motion)
IdOutcome = Literal["new", "recovered", "undone", "handover"]
#: how an ID decision was made: the robust profile's open-set posterior, or Pinto's Algorithm 2
IdRule = Literal["open-set", "nearest"]


@dataclass(frozen=True)
class IdCandidate:
    """A remembered person an ID decision weighed: ``log_odds`` that the track is them (recovery's
    ``llr``), ``support`` (against "new" and their rivals: what must reach ``p_recover``),
    ``reachable``, and where they left: ``walked_out`` of the cameras' view (False: lost inside it,
    or the view was not known), ``away_s`` ago, ``distance_m`` from here (None: not known)."""

    id: int
    log_odds: float
    support: float
    reachable: bool
    walked_out: bool | None = None
    away_s: float | None = None
    distance_m: float | None = None
    #: the descriptor distance to their nearest remembered descriptor (the ``nearest`` rule only)
    distance: float | None = None

    def describe(self) -> str:
        if self.distance is not None:
            return f"{self.id} (descriptor distance {self.distance:.2f}, log-odds {self.log_odds:.2f})"
        where = ""
        if self.away_s is not None and self.distance_m is not None:
            how = "walked out of view" if self.walked_out else "last seen"
            where = f", {how} {self.away_s:.1f} s ago {self.distance_m:.1f} m away"
        if not self.reachable:
            return f"{self.id} (log-odds {self.log_odds:.2f}, could not have walked here{where})"
        return f"{self.id} (log-odds {self.log_odds:.2f}, support {self.support:.2f}{where})"


@dataclass(frozen=True)
class HandOver:
    """A hand-over by motion: the ID's track, last seen by ``camera`` ``away_s`` ago ``distance_m``
    from here, had its prediction at squared Mahalanobis distance ``d2`` (the gate is the
    decision's ``threshold``)."""

    camera: str
    d2: float
    away_s: float
    distance_m: float


@dataclass(frozen=True)
class IdDecision:
    """One ID decision at ``stamp`` (s) for the track at (``x``, ``y``): ``outcome`` "new" (a
    fresh ``id``), "recovered" (the remembered ``id``) or "undone" (the recovery of
    ``previous_id`` taken back during probation; the track now has ``id``). ``support`` is the
    best candidate's, against ``threshold`` (``p_recover``, or ``p_undo`` for a check during
    probation); ``p_new`` the posterior of someone new; ``stranger_log_odds`` what a stranger
    reaches here (the people in view now); ``candidates`` the most probable first. "handover":
    the ``id`` of a track another camera lost (``handover``; no candidates weighed)."""

    stamp: float
    id: int
    outcome: IdOutcome
    x: float
    y: float
    support: float
    threshold: float
    p_new: float
    stranger_log_odds: float
    candidates: tuple[IdCandidate, ...]
    previous_id: int | None = None
    handover: HandOver | None = None
    #: "open-set": the robust profile's posterior against someone new; "nearest": Pinto's
    #: Algorithm 2 (the thesis profile), the nearest remembered person if their descriptor
    #: distance is below ``threshold`` (t_recover); ``support`` 1 for the ID it gave back, else 0
    rule: IdRule = "open-set"

    def summary(self) -> str:
        """One line for a log."""
        where = f"at ({self.x:.2f}, {self.y:.2f}) m, t={self.stamp:.2f} s"
        if self.rule == "nearest":
            head = f"ID {self.id} recovered" if self.outcome == "recovered" else f"new ID {self.id}"
            best = min(self.candidates, key=lambda c: c.distance if c.distance is not None else math.inf)
            op = "<" if self.outcome == "recovered" else ">="
            return (f"{head} {where} (Algorithm 2): the nearest remembered person, {best.id}, at descriptor "
                    f"distance {best.distance:.2f} {op} t_recover {self.threshold:.2f}; candidates: "
                    + "; ".join(c.describe() for c in self.candidates))
        if self.handover is not None:
            h = self.handover
            return (f"ID {self.id} handed over from camera {h.camera!r} {where}: its track coasted out of that "
                    f"camera's view {h.away_s:.1f} s ago {h.distance_m:.1f} m away, its prediction at squared "
                    f"Mahalanobis distance {h.d2:.1f} (gate {self.threshold:.1f})")
        listed = "; ".join(c.describe() for c in self.candidates) or "none"
        head = {"new": f"new ID {self.id}", "recovered": f"ID {self.id} recovered",
                "undone": f"recovery of ID {self.previous_id} undone, now ID {self.id}"}[self.outcome]
        if not any(c.reachable for c in self.candidates):
            why = "no remembered person could have walked here"
        else:
            op = ">=" if self.outcome == "recovered" else "<"
            why = f"support {self.support:.2f} {op} {self.threshold:.2f}"
        return (f"{head} {where}: {why}; P(new) {self.p_new:.2f}, "
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
            known = {f for f in cls.__dataclass_fields__ if f not in ("candidates", "handover")}
            how = data.get("handover")
            out = cls(**{k: v for k, v in data.items() if k in known}, candidates=cands,  # type: ignore[arg-type]
                      handover=None if how is None else HandOver(**how))  # type: ignore[arg-type]
        except (KeyError, TypeError, AttributeError) as exc:
            raise ValueError(f"not an ID decision ({type(exc).__name__}: {exc})") from exc
        if out.outcome not in ("new", "recovered", "undone", "handover"):
            raise ValueError(f"not an ID decision: outcome {out.outcome!r} (new, recovered, undone or handover)")
        if out.rule not in ("open-set", "nearest") or (out.rule == "nearest" and not out.candidates):
            raise ValueError(f"not an ID decision: rule {out.rule!r} (open-set, or nearest with its candidates)")
        return out


@dataclass
class FrameResult:
    """What one update did."""

    stamp: float
    appearance_available: bool
    tracks: list[TrackReport] = field(default_factory=list)  # live tracks (tentative and confirmed)
    deleted: list[TrackReport] = field(default_factory=list)
    new_ids: list[int] = field(default_factory=list)
    recovered_ids: list[int] = field(default_factory=list)
    #: recoveries taken back this frame (robust profile): (the remembered ID, the fresh ID the track got)
    recovery_undone: list[tuple[int, int]] = field(default_factory=list)
    #: why this frame's newly confirmed tracks got their IDs, and why recoveries were undone
    #: (robust profile's ID memory, when it weighed remembered people: :class:`IdDecision`)
    id_decisions: list[IdDecision] = field(default_factory=list)
    matches: int = 0
    #: confident unmatched detections that started no track because they lie on the static map's obstacles
    births_blocked: int = 0

    @property
    def confirmed(self) -> list[TrackReport]:
        """The tracker's output: Confirmed tracks only."""
        return [t for t in self.tracks if t.status is TrackStatus.CONFIRMED]


@dataclass(frozen=True)
class AppearanceModel:
    """An embedding model's calibrated distances: same-person probability 0.9 at ``t_lower``, 0.1 at
    ``t_upper``; ``t_recover`` for the ID memory; ``metric`` ``euclidean`` or ``cosine`` (1 - cos on
    unit vectors; the thesis profile compares Euclidean distances whatever it says); ``s_max`` its own
    Algorithm 1 bound (thesis profile; None: the profile's)."""

    t_lower: float
    t_upper: float
    t_recover: float
    metric: Literal["euclidean", "cosine"] = "euclidean"
    s_max: float | None = None

    def __post_init__(self) -> None:
        if not 0 <= self.t_lower < self.t_upper:
            raise ValueError(f"need 0 <= t_lower < t_upper, got {self.t_lower}, {self.t_upper}")

    def log_odds(self, distance: np.ndarray) -> np.ndarray:
        """Log-odds that a pair at ``distance`` is the same person (0 where ``nan``)."""
        mid = 0.5 * (self.t_lower + self.t_upper)
        # logistic through (t_lower, 0.9) and (t_upper, 0.1): slope ln(9) / half-width
        slope = math.log(9.0) / (0.5 * (self.t_upper - self.t_lower))
        out = slope * (mid - distance)
        return np.where(np.isnan(out), 0.0, out)

    def from_euclidean(self, d: np.ndarray) -> np.ndarray:
        """The model's distance from the Euclidean distance of unit vectors."""
        return 0.5 * d * d if self.metric == "cosine" else d


@dataclass(frozen=True)
class ScoreModel:
    """Detector score -> P(true person): ``sigmoid((score - center) / scale)``; ``center`` None: the
    scores are not calibrated, every detection has ``default_p``. ``birth_score``: detections below
    it may update tracks but never start one (None: every detection may). ``max_is_person``: the
    most this detector's own IsPerson belief of a track may reach (core/is_person.py; below the
    profile's ``confirm_is_person``: it never confirms a track alone); ``is_person_tau_s`` its
    belief's drift back to 0.5 (None: the profile's)."""

    center: float | None = None
    scale: float = 1.0
    default_p: float = 0.7
    birth_score: float | None = None
    max_is_person: float = 1.0
    is_person_tau_s: float | None = None

    def probability(self, scores: np.ndarray) -> np.ndarray:
        if self.center is None:
            return np.full(len(scores), self.default_p)
        return 1.0 / (1.0 + np.exp(-(np.asarray(scores, float) - self.center) / self.scale))

    def confident(self, scores: np.ndarray) -> np.ndarray:
        if self.birth_score is None:
            return np.ones(len(scores), bool)
        return np.asarray(scores, float) >= self.birth_score


class FrameInput(NamedTuple):
    """One frame as a core takes it, converted once (:meth:`of`; a named tuple: cheap to make):
    ``positions`` (N, 3) float64 in the tracking frame; ``descriptors`` (N, D) float32 (a NaN row:
    none; None: a position-only frame); ``measurement_cov`` (N, 3, 3) (None: none) and ``cov_usable``
    (N,) which are usable (:func:`~services.tracker.core.cues.usable_covariances`; None: the core
    checks); ``scores`` (N,) the detector's (zeros: none); ``view`` what the cameras could see (None:
    unknown); ``aspects`` (N,) the boxes' height / width (None: no boxes); ``orientations`` (N, 8) an
    orientation classifier's probabilities in the tracking frame's bins (NaN rows: none);
    ``score_model`` how this detector's scores read (None: the profile's); ``camera`` the frame's;
    ``postures`` (N,) int8 the detector's reports, ``posture.POSTURES`` indices (-1: none; None: no
    reports); ``statures`` (N,) measured statures (m; NaN: not measured; None: none);
    ``detector`` the detector's name (its own IsPerson belief: core/is_person.py);
    ``obstacles`` the static map as it is now, when one arrives while tracking (ROS 2's ``/map``;
    None: the profile's, if any)."""

    positions: np.ndarray
    descriptors: np.ndarray | None = None
    measurement_cov: np.ndarray | None = None
    cov_usable: np.ndarray | None = None
    scores: np.ndarray | None = None
    view: View | None = None
    aspects: np.ndarray | None = None
    orientations: np.ndarray | None = None
    score_model: ScoreModel | None = None
    camera: str = ""
    postures: np.ndarray | None = None
    statures: np.ndarray | None = None
    obstacles: ObstacleMap | None = None
    detector: str = ""

    @classmethod
    def of(cls, positions: np.ndarray, descriptors: np.ndarray | None = None,
           measurement_cov: np.ndarray | None = None, scores: np.ndarray | None = None,
           view: View | None = None, aspects: np.ndarray | None = None,
           orientations: np.ndarray | None = None, score_model: ScoreModel | None = None,
           camera: str = "", postures: np.ndarray | None = None,
           statures: np.ndarray | None = None) -> FrameInput:
        """Convert one frame's arrays (ValueError for descriptors of the wrong shape)."""
        positions = np.asarray(positions, dtype=np.float64)
        if positions.ndim != 2 or positions.shape[1:] != (3,):
            positions = positions.reshape(-1, 3)
        n = len(positions)
        if descriptors is not None:
            descriptors = np.asarray(descriptors, dtype=np.float32)
            if descriptors.ndim != 2 or len(descriptors) != n:
                raise ValueError(f"descriptors must be (N, D) with N = {n} detections, got shape {descriptors.shape}")
        if measurement_cov is not None:
            measurement_cov = np.asarray(measurement_cov, dtype=np.float64).reshape(n, 3, 3)
        if scores is None:
            scores = np.zeros(n)
        else:
            scores = np.asarray(scores, dtype=np.float64)
            if scores.shape != (n,):
                scores = scores.reshape(n)
        if postures is not None:
            postures = np.asarray(postures, np.int8).reshape(n)
        if statures is not None:
            statures = np.asarray(statures, np.float64)
            if statures.size != n:
                raise ValueError(f"statures must hold one value per detection (N = {n}, NaN: not measured), "
                                 f"got shape {statures.shape}")
            statures = statures.reshape(n)
        return cls(positions, descriptors, measurement_cov, None, scores, view, aspects, orientations, score_model,
                   camera, postures, statures)


@dataclass
class KeptMemory:
    """What the ID memory's file keeps beside the remembered galleries: the ``live_galleries`` (ID,
    descriptors (M, D)), the trained ``classifiers`` by ID and the open-set recovery's named arrays
    (empty for a profile without them); on import, None leaves a part as it is."""

    live_galleries: list[tuple[int, np.ndarray]] = field(default_factory=list)
    classifiers: dict[int, np.ndarray] | None = None
    recovery: dict[str, np.ndarray] | None = None
