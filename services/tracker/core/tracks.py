"""The robust profile's state: every track as a row of a few arrays (:class:`TrackTable`),
their galleries in one contiguous array (:class:`~services.tracker.core.bank.GalleryBank`).

With the tracks in arrays a frame costs a handful of array operations whatever the number
of people: the predict, the gates, the Kalman update and the life cycle's tests run on
whole columns. Pure numpy.
"""

from __future__ import annotations

from dataclasses import dataclass, field, fields
from functools import lru_cache

import numpy as np

from services.tracker.core import posture as pose
from services.tracker.core.bank import GalleryBank
from services.tracker.core.identity import IdentityMemory
from services.tracker.core.recovery import RecoveryState
from services.tracker.core.types import TrackStatus, TrackView

__all__ = ["RobustTrackerState", "TrackRow", "TrackTable", "row_view", "track_rows", "track_view", "track_views"]


@dataclass
class TrackTable:
    """The tracks, one row each, in the order they were born. The filters' state is in arrays
    (one product moves every track): ``mean`` (T, S) and ``cov`` (T, S, S), ``posture`` (T, 3)
    and ``orientation`` (T, 8) (the TU Ilmenau framework's filters), ``clf`` (T, D + 1) the online classifiers (rows of zeros while untrained; None until the
    first is trained), ``stature`` (T,) and ``stature_n`` (T,) the person's stature and how many
    measurements it holds (core/stature.py). The bookkeeping a frame reads a few entries of is in lists: ``id`` (0
    while tentative), ``is_person`` (IsPerson, a probability), ``status``, the stamps, the hit counts, ``in_view`` (None: not known),
    ``camera``, ``slot`` the gallery's in the :class:`GalleryBank` (-1: none yet), and for the ID
    memory's recovery (core/recovery.py) ``fix`` (x, y, variance per axis) at the last detection,
    ``probation`` (the recovered ID, its end, the next check, the share counted as returning)."""

    mean: np.ndarray
    cov: np.ndarray
    posture: np.ndarray
    orientation: np.ndarray
    clf: np.ndarray | None
    stature: np.ndarray
    stature_n: np.ndarray
    id: list[int]
    is_person: list[float]
    status: list[TrackStatus]
    first_stamp: list[float]
    last_update: list[float]
    confident_hits: list[int]
    total_hits: list[int]
    ever_confirmed: list[bool]
    clf_steps: list[int]
    forgotten: list[bool]
    in_view: list[bool | None]
    unseen_s: list[float]
    camera: list[str]
    slot: list[int]
    fix: list[tuple[float, float, float] | None]
    probation: list[tuple[int, float, float, float] | None]

    @classmethod
    def empty(cls, state_dim: int) -> TrackTable:
        return cls(np.zeros((0, state_dim)), np.zeros((0, state_dim, state_dim)), np.zeros((0, 3)),
                   np.zeros((0, pose.ORIENTATION_BINS)), None, np.zeros(0), np.zeros(0, np.int64),
                   *([] for _ in range(_LISTS)))

    def __len__(self) -> int:
        return len(self.id)

    def copy(self) -> TrackTable:
        return TrackTable(*(None if v is None else v.copy() if isinstance(v, np.ndarray) else list(v)
                            for v in (getattr(self, name) for name in _FIELDS)))

    def drop(self, rows: set[int]) -> None:
        """Remove the tracks ``rows``; the others keep their order."""
        idx = np.array([j for j in range(len(self.id)) if j not in rows], np.int64)
        for name in _ARRAYS:
            v = getattr(self, name)
            if v is not None:
                setattr(self, name, v[idx])
        gone = sorted(rows, reverse=True)
        for name in _FIELDS[len(_ARRAYS):]:
            v = getattr(self, name)
            for j in gone:
                del v[j]

    def append(self, mean: np.ndarray, cov: np.ndarray, stamp: float, is_person: list[float], camera: str) -> None:
        """New tentative tracks: ``mean`` (K, S) and ``cov`` (S, S), no gallery yet."""
        k = len(mean)
        self.mean = np.concatenate([self.mean, mean])
        self.cov = np.concatenate([self.cov, np.broadcast_to(cov, (k, *cov.shape))])
        self.posture = np.concatenate([self.posture, _uniform_rows(k, 3)])
        self.orientation = np.concatenate([self.orientation, _uniform_rows(k, pose.ORIENTATION_BINS)])
        if self.clf is not None:
            self.clf = np.concatenate([self.clf, np.zeros((k, self.clf.shape[1]))])
        self.stature = np.concatenate([self.stature, np.zeros(k)])
        self.stature_n = np.concatenate([self.stature_n, np.zeros(k, np.int64)])
        self.id += [0] * k
        self.is_person += is_person
        self.status += [TrackStatus.TENTATIVE] * k
        self.first_stamp += [stamp] * k
        self.last_update += [stamp] * k
        self.confident_hits += [1] * k
        self.total_hits += [1] * k
        self.ever_confirmed += [False] * k
        self.clf_steps += [0] * k
        self.forgotten += [False] * k
        self.in_view += [None] * k
        self.unseen_s += [0.0] * k
        self.camera += [camera] * k
        self.slot += [-1] * k
        self.fix += [None] * k
        self.probation += [None] * k


_FIELDS = tuple(f.name for f in fields(TrackTable))
_ARRAYS = _FIELDS[:7]  # mean, cov, posture, orientation, clf, stature, stature_n; then the lists
_LISTS = len(_FIELDS) - len(_ARRAYS)


@lru_cache(maxsize=64)
def _uniform_rows(k: int, n: int) -> np.ndarray:
    """``k`` uniform distributions over ``n`` values (k, n), read-only."""
    rows = np.tile(pose.uniform(n), (k, 1))
    rows.flags.writeable = False
    return rows


@dataclass
class RobustTrackerState:
    """Everything the robust tracker knows: its tracks, their galleries, the ID memory, the
    remembered people's classifiers (ID -> weights), the last frame's stamp and the recovery's
    state (departures, who was seen with whom, the P(new) counts)."""

    tracks: TrackTable
    bank: GalleryBank
    memory: IdentityMemory
    last_stamp: float | None = None
    classifiers: dict[int, np.ndarray] = field(default_factory=dict)
    recovery: RecoveryState = field(default_factory=RecoveryState)

    def copy(self) -> RobustTrackerState:
        """An independent copy (galleries and memory shared copy-on-write)."""
        return RobustTrackerState(self.tracks.copy(), self.bank.copy(), self.memory.copy(), self.last_stamp,
                                  dict(self.classifiers), self.recovery.copy())

    def live_ids(self, skip: set[int] = frozenset()) -> set[int]:  # type: ignore[assignment]
        """The IDs of the live tracks (less the rows ``skip``)."""
        return {i for j, i in enumerate(self.tracks.id) if i and j not in skip}


@dataclass(frozen=True)
class TrackRow:
    """A read-only picture of one track of the table (for inspection and tests): its columns,
    ``clf`` None while untrained and ``gallery`` None without one."""

    id: int
    status: TrackStatus
    mean: np.ndarray
    cov: np.ndarray
    first_stamp: float
    last_update: float
    confident_hits: int
    total_hits: int
    is_person: float
    ever_confirmed: bool
    clf: np.ndarray | None
    clf_steps: int
    forgotten: bool
    in_view: bool | None
    unseen_s: float
    camera: str
    posture: np.ndarray
    orientation: np.ndarray
    stature: float
    stature_n: int
    gallery: _GalleryRow | None


@dataclass(frozen=True)
class _GalleryRow:
    """A read-only picture of one track's gallery."""

    descriptors: np.ndarray

    def __len__(self) -> int:
        return len(self.descriptors)


def track_rows(table: TrackTable, bank: GalleryBank) -> list[TrackRow]:
    """Every track of ``table`` as a :class:`TrackRow` (copies)."""
    out = []
    for j in range(len(table)):
        col = {name: getattr(table, name)[j] for name in _FIELDS if name not in ("clf", "slot", "fix", "probation")}
        col = {k: v.copy() if isinstance(v, np.ndarray) else v.item() if isinstance(v, np.generic) else v
               for k, v in col.items()}
        col["clf"] = table.clf[j].copy() if table.clf is not None and col["clf_steps"] else None
        slot = table.slot[j]
        col["gallery"] = _GalleryRow(bank.descriptors(slot)) if slot >= 0 else None
        out.append(TrackRow(**col))
    return out


def row_view(t: TrackRow, stamp: float, ukf: bool, posture: bool) -> TrackView:
    """A :class:`TrackRow` as :func:`track_view` reports its track."""
    mean, cov = (t.mean[:6], t.cov[:6, :6]) if ukf else (t.mean, t.cov)
    return TrackView(t.id, t.status, mean, cov, t.total_hits, 0, max(0.0, stamp - t.first_stamp), t.last_update,
                     len(t.gallery) if t.gallery is not None else 0, t.ever_confirmed,
                     posture=t.posture if posture else None, orientation=t.orientation if posture else None,
                     stature=t.stature if t.stature_n else None)


def track_view(state: RobustTrackerState, j: int, stamp: float, status: TrackStatus, in_view: bool | None,
               ukf: bool, posture: bool) -> TrackView:
    """Track ``j`` as the tracker reports it at ``stamp`` (``ukf``: its state is the unscented
    filter's, of which the view shows (x, y, z, vx, vy, vz); ``posture``: posture and
    orientation are estimated). The arrays are shared: the tracker never writes into a mean,
    cov, posture or orientation array it has shown, every change makes new ones."""
    t = state.tracks
    mean, cov = (t.mean[j, :6], t.cov[j, :6, :6]) if ukf else (t.mean[j], t.cov[j])
    return TrackView(t.id[j], status, mean, cov, t.total_hits[j], 0, max(0.0, stamp - t.first_stamp[j]),
                     t.last_update[j], state.bank.size(t.slot[j]), t.ever_confirmed[j], in_view,
                     posture=t.posture[j] if posture else None, orientation=t.orientation[j] if posture else None,
                     stature=float(t.stature[j]) if t.stature_n[j] else None)


def track_views(state: RobustTrackerState, stamp: float, view_known: bool, ukf: bool, posture: bool) -> list[TrackView]:
    """Every live track as :func:`track_view`; a coasting one says whether it is in view when
    the frame had a view (``view_known``)."""
    t = state.tracks
    if not t.id:
        return []
    means, covs = (t.mean[:, :6], t.cov[:, :6, :6]) if ukf else (t.mean, t.cov)
    poses = zip(t.posture, t.orientation) if posture else ((None, None) for _ in t.id)
    coasting, make, sizes = TrackStatus.COASTING, TrackView.of_fields, state.bank.n.tolist()
    statures = [h if k else None for h, k in zip(t.stature.tolist(), t.stature_n.tolist())]
    return [make(i, s, m, c, h, 0, max(0.0, stamp - first), last, sizes[slot] if slot >= 0 else 0, ever,
                 flag if view_known and s is coasting else None, pp, o, body)
            for i, s, m, c, h, first, last, slot, ever, flag, (pp, o), body
            in zip(t.id, t.status, means, covs, t.total_hits, t.first_stamp, t.last_update, t.slot, t.ever_confirmed,
                   t.in_view, poses, statures)]
