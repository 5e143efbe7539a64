"""The robust profile's state: every track as a row of a few arrays (:class:`TrackTable`), what
each cue keeps per track beside them (its :class:`Columns`), their galleries in one array
(:class:`~services.tracker.core.bank.GalleryBank`). A frame then costs a handful of array
operations whatever the number of people: the predict, the gates, the Kalman update and the life
cycle's tests run on whole columns. Pure numpy.
"""

from __future__ import annotations

from dataclasses import dataclass, field, fields
from typing import Protocol, TypeVar

import numpy as np

from services.tracker.core.bank import GalleryBank
from services.tracker.core.identity import IdentityMemory
from services.tracker.core.recovery import RecoveryState
from services.tracker.core.types import TrackStatus


__all__ = ["FIELDS", "ArrayColumns", "Columns", "RobustTrackerState", "TrackTable"]


class Columns(Protocol):
    """A cue's per-track state, one row per track of the table, kept in step with it."""

    def append(self, k: int) -> None:
        """``k`` new tracks (their rows at the end, in the cue's state of "nothing known")."""

    def keep(self, idx: np.ndarray) -> None:
        """Only the rows ``idx``, in that order (tracks were dropped)."""

    def copy(self) -> Columns:
        ...

    def merge(self, j: int, old: int) -> None:
        """Track ``j`` takes over track ``old``'s person (a hand-over between cameras)."""

    def clear(self, j: int) -> None:
        """Track ``j``'s person was forgotten: nothing learnt of them stays."""


_A = TypeVar("_A", bound="ArrayColumns")


class ArrayColumns:
    """:class:`Columns` as a dataclass of arrays, one row per track (None: not started yet): new
    tracks get :meth:`rows`, dropping and copying treat every array alike, and merging or clearing
    changes nothing unless the cue says otherwise."""

    def rows(self, k: int) -> tuple[np.ndarray | None, ...]:
        """One array per field: the rows of ``k`` new tracks, the cue's state of "nothing known"."""
        raise NotImplementedError

    def _arrays(self) -> list[tuple[str, np.ndarray | None]]:
        return [(f.name, getattr(self, f.name)) for f in fields(self)]  # type: ignore[arg-type]

    def append(self, k: int) -> None:
        for (name, v), new in zip(self._arrays(), self.rows(k)):
            setattr(self, name, None if v is None else np.concatenate([v, new]))

    def keep(self, idx: np.ndarray) -> None:
        for name, v in self._arrays():
            setattr(self, name, None if v is None else v[idx])

    def copy(self: _A) -> _A:
        return type(self)(*(None if v is None else v.copy() for _, v in self._arrays()))

    def merge(self, j: int, old: int) -> None:
        return None

    def clear(self, j: int) -> None:
        return None


@dataclass
class TrackTable:
    """The tracks, one row each, in the order they were born: the filter's state in arrays (one
    product moves every track), ``mean`` (T, S) and ``cov`` (T, S, S); the bookkeeping a frame reads
    a few entries of in lists: ``id`` (0 while tentative), ``is_person`` (IsPerson) and ``beliefs`` (by
    detector: core/is_person.py), ``in_view``
    (None: not known) and ``misses_tell`` (a miss there means they are not there: false in a
    laser's view by a wall), ``slot`` the gallery's in the :class:`GalleryBank` (-1: none yet), ``fix`` (x,
    y, variance per axis at the last detection) and ``probation`` (the recovered ID, its end, the
    next check) for core/recovery.py; ``extra`` each cue's :class:`Columns` by the cue's name."""

    mean: np.ndarray
    cov: np.ndarray
    id: list[int]
    is_person: list[float]
    beliefs: list[str | dict[str, float]]
    status: list[TrackStatus]
    first_stamp: list[float]
    last_update: list[float]
    confident_hits: list[int]
    total_hits: list[int]
    ever_confirmed: list[bool]
    forgotten: list[bool]
    in_view: list[bool | None]
    misses_tell: list[bool]
    unseen_s: list[float]
    camera: list[str]
    slot: list[int]
    fix: list[tuple[float, float, float] | None]
    probation: list[tuple[int, float, float] | None]
    extra: dict[str, Columns] = field(default_factory=dict)

    @classmethod
    def empty(cls, state_dim: int, extra: dict[str, Columns] | None = None) -> TrackTable:
        return cls(np.zeros((0, state_dim)), np.zeros((0, state_dim, state_dim)), *([] for _ in range(_LISTS)),
                   extra=dict(extra or {}))

    def __len__(self) -> int:
        return len(self.id)

    def copy(self) -> TrackTable:
        return TrackTable(*(v.copy() if isinstance(v, np.ndarray) else list(v)
                            for v in (getattr(self, name) for name in FIELDS)),
                          extra={k: c.copy() for k, c in self.extra.items()})

    def drop(self, rows: set[int]) -> None:
        """Remove the tracks ``rows``; the others keep their order."""
        idx = np.array([j for j in range(len(self.id)) if j not in rows], np.int64)
        self.mean, self.cov = self.mean[idx], self.cov[idx]
        gone = sorted(rows, reverse=True)
        for name in FIELDS[2:]:
            v = getattr(self, name)
            for j in gone:
                del v[j]
        for c in self.extra.values():
            c.keep(idx)

    def append(self, mean: np.ndarray, cov: np.ndarray, stamp: float, is_person: list[float], camera: str,
               detector: str = "") -> None:
        """New tentative tracks: ``mean`` (K, S) and ``cov`` (S, S), no gallery yet, seen by ``detector``."""
        k = len(mean)
        self.mean = np.concatenate([self.mean, mean])
        self.cov = np.concatenate([self.cov, np.broadcast_to(cov, (k, *cov.shape))])
        self.id += [0] * k
        self.is_person += is_person
        self.beliefs += [detector] * k
        self.status += [TrackStatus.TENTATIVE] * k
        self.first_stamp += [stamp] * k
        self.last_update += [stamp] * k
        self.confident_hits += [1] * k
        self.total_hits += [1] * k
        self.ever_confirmed += [False] * k
        self.forgotten += [False] * k
        self.in_view += [None] * k
        self.misses_tell += [True] * k
        self.unseen_s += [0.0] * k
        self.camera += [camera] * k
        self.slot += [-1] * k
        self.fix += [None] * k
        self.probation += [None] * k
        for c in self.extra.values():
            c.append(k)


FIELDS = tuple(f.name for f in fields(TrackTable) if f.name != "extra")
_LISTS = len(FIELDS) - 2  # after mean and cov, the lists


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
