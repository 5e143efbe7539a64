"""The robust profile's state: every track as a row of a few arrays (:class:`TrackTable`),
and every track's gallery in one contiguous array (:class:`GalleryBank`).

With the tracks in arrays a frame costs a handful of array operations whatever the number
of people: the predict, the gates, the Kalman update and the life cycle's tests run on
whole columns. The bank keeps the galleries where one batched matrix product measures every
compared (detection, track) pair against every descriptor of the track's gallery.

A gallery here is Pinto's track gallery with a bound (the TU Ilmenau framework's): at most
``capacity`` descriptors; a full one drops the stored descriptor nearest to the new one
(``Gallery(prune="nearest")``, whose behaviour this reproduces descriptor for descriptor).
Pure numpy.
"""

from __future__ import annotations

import bisect
from dataclasses import dataclass, field, fields
from functools import lru_cache

import numpy as np

from services.tracker.core import posture as pose
from services.tracker.core.identity import IdentityMemory
from services.tracker.core.recovery import RecoveryState
from services.tracker.core.types import TrackStatus, TrackView

__all__ = ["GalleryBank", "RobustTrackerState", "TrackRow", "TrackTable", "row_view", "track_rows", "track_view",
           "track_views"]


class GalleryBank:
    """Galleries of at most ``capacity`` descriptors each, in slots of one array.

    ``data`` (S, D, capacity) float32 (each gallery a column per descriptor: the layout a vector-by-matrix product reads fastest), ``sq`` (S, capacity) their squared norms (``inf``
    where a slot holds no descriptor, so a distance to it is ``inf``), ``age`` the order
    they came in, ``n`` (S,) how many each slot holds. A track holds a slot from its first
    descriptor on; a freed slot is reused. Copies share the arrays until either side
    changes them (copy-on-write), so a tracker snapshot costs almost nothing.
    """

    def __init__(self, capacity: int) -> None:
        if capacity <= 0:
            raise ValueError(f"capacity must be positive, got {capacity}")
        self.capacity = capacity
        self.dim = 0
        self.data = np.zeros((0, 0, capacity), np.float32)
        self.sq = np.zeros((0, capacity), np.float32)
        self.age = np.zeros((0, capacity), np.int64)
        self.n = np.zeros(0, np.int64)
        self.counter = np.zeros(0, np.int64)
        self.free: list[int] = []  # ascending
        self._shared = False

    # ---------------------------------------------------------------- slots
    def check_dim(self, dim: int) -> None:
        """ValueError if descriptors of dimension ``dim`` cannot go into these galleries."""
        if self.dim and dim != self.dim:
            raise ValueError(f"descriptors of dimension {dim}, the galleries hold dimension {self.dim}")

    def allocate(self, dim: int) -> int:
        """A free slot for a gallery of ``dim``-D descriptors."""
        self.check_dim(dim)
        self._own()
        if not self.dim:
            self.dim = dim
            self.data = np.zeros((len(self.n), dim, self.capacity), np.float32)
        if not self.free:
            self._grow(max(4, 2 * len(self.n)))
        return self.free.pop(0)

    def release(self, slot: int) -> None:
        """Empty ``slot`` and make it free."""
        self._own()
        self.n[slot] = 0
        self.counter[slot] = 0
        self.sq[slot] = np.inf
        bisect.insort(self.free, slot)

    def _grow(self, size: int) -> None:
        extra = size - len(self.n)
        self.data = np.concatenate([self.data, np.zeros((extra, self.dim, self.capacity), np.float32)])
        self.sq = np.concatenate([self.sq, np.full((extra, self.capacity), np.inf, np.float32)])
        self.age = np.concatenate([self.age, np.zeros((extra, self.capacity), np.int64)])
        self.n = np.concatenate([self.n, np.zeros(extra, np.int64)])
        self.counter = np.concatenate([self.counter, np.zeros(extra, np.int64)])
        self.free.extend(range(size - extra, size))

    def _own(self) -> None:
        if self._shared:
            self.data, self.sq, self.age = self.data.copy(), self.sq.copy(), self.age.copy()
            self.n, self.counter, self.free = self.n.copy(), self.counter.copy(), list(self.free)
            self._shared = False

    def copy(self) -> GalleryBank:
        """A copy sharing the arrays until either side changes them."""
        other = GalleryBank.__new__(GalleryBank)
        other.__dict__.update(self.__dict__)
        self._shared = other._shared = True
        return other

    # -------------------------------------------------------------- queries
    def size(self, slot: int) -> int:
        return int(self.n[slot]) if slot >= 0 else 0

    def sizes(self, slots: list[int]) -> np.ndarray:
        """How many descriptors each of ``slots`` holds (0 for -1: no gallery)."""
        if not len(self.n):
            return np.zeros(len(slots), np.int64)
        s = np.asarray(slots, np.int64)
        return np.where(s >= 0, self.n[s], 0)

    def descriptors(self, slot: int) -> np.ndarray:
        """The descriptors of ``slot``, oldest first: (n, D) float32 (a copy)."""
        n = self.size(slot)
        order = np.argsort(self.age[slot, :n], kind="stable")
        return self.data[slot, :, :n].T[order].copy()

    def pair_sq_distances(self, slots: np.ndarray, x: np.ndarray) -> np.ndarray:
        """Squared Euclidean distances (P, capacity) from each descriptor ``x[p]`` (P, D) to
        every stored descriptor of gallery ``slots[p]``, in storage order (``inf`` beyond a
        gallery's descriptors): what :meth:`add_many` takes to pick the one to drop.

        A slot compared with one descriptor (the usual case) goes into one batched matrix
        product over the whole bank; a slot compared with several, into its own product."""
        x = np.asarray(x, np.float32)
        if not len(slots):
            return np.empty((0, self.capacity), np.float32)
        x_sq = np.einsum("ij,ij->i", x, x)
        listed = slots.tolist()
        if len(set(listed)) == len(listed):  # each slot once (the usual case): no masks
            out = self._distinct_products(slots, listed, x, len(listed) > _FEW_PAIRS)
        else:
            out = self._shared_products(slots, x)
        out += x_sq[:, None]
        return np.maximum(out, 0.0, out=out)

    def _distinct_products(self, slots: np.ndarray, listed: list[int], x: np.ndarray, batched: bool) -> np.ndarray:
        """``sq - 2 x . g`` (P, capacity) for distinct ``slots``: one ``batched`` product over
        the bank, else a product per slot (``inf`` past a gallery's descriptors, as ``sq`` is:
        for a few pairs this costs less than setting up the batched one)."""
        if not batched:
            out = np.empty((len(listed), self.capacity), np.float32)
            for k, slot in enumerate(listed):
                n = int(self.n[slot])
                out[k, n:] = np.inf
                out[k, :n] = self.sq[slot, :n] - 2.0 * (x[k] @ self.data[slot, :, :n])
            return out
        hi = max(listed) + 1  # slots are taken lowest first: the bank's used part
        in_order = hi == len(listed) and listed == list(range(hi))
        if in_order:
            xs = x[:, None, :]
        else:
            xs = np.zeros((hi, 1, self.dim), np.float32)
            xs[slots, 0] = x
        prod = np.matmul(xs, self.data[:hi])[:, 0]  # (hi, capacity): one product per slot
        out = prod if in_order else prod[slots]
        out *= -2.0  # sq - 2 x . g, without temporaries
        out += self.sq[:hi] if in_order else self.sq[slots]
        return out

    def _shared_products(self, slots: np.ndarray, x: np.ndarray) -> np.ndarray:
        """As :meth:`_distinct_products` where some slot is compared with several descriptors."""
        out = np.empty((len(slots), self.capacity), np.float32)
        count = np.bincount(slots, minlength=len(self.n))
        single = count[slots] == 1
        if len(slots) <= _FEW_PAIRS:
            single[:] = False
        if single.any():
            out[single] = self._distinct_products(slots[single], slots[single].tolist(), x[single], True)
        for slot in np.flatnonzero(count > 1 if single.any() else count).tolist():
            rows, n = np.flatnonzero(slots == slot), int(self.n[slot])
            out[rows] = np.inf
            out[rows, :n] = self.sq[slot, :n] - 2.0 * (x[rows] @ self.data[slot, :, :n])
        return out

    # ------------------------------------------------------------- mutation
    def add(self, slot: int, x: np.ndarray) -> None:
        """Insert one descriptor ``x`` (D,) into ``slot``, dropping the nearest stored one when full."""
        x = np.asarray(x, np.float32).reshape(self.dim)
        xx = float(x @ x)
        if not np.isfinite(xx):
            raise ValueError("descriptor has non-finite values")
        self._own()
        n = int(self.n[slot])
        if n < self.capacity:
            self._write(np.array([slot]), np.array([n]), x[None], np.array([xx], np.float32), np.array([n + 1]))
            return
        d2 = self.sq[slot] + np.float32(xx) - 2.0 * (x @ self.data[slot])
        np.maximum(d2, 0.0, out=d2)
        self._write(np.array([slot]), np.array([int(np.argmin(d2))]), x[None], np.array([xx], np.float32),
                    np.array([n]))

    def add_many(self, slots: np.ndarray, x: np.ndarray, d2: np.ndarray | None) -> None:
        """Insert ``x[k]`` (K, D) into gallery ``slots[k]`` (distinct slots); a full one drops
        the stored descriptor nearest to it, by ``d2[k]`` (:meth:`pair_sq_distances`) when given."""
        if not len(slots):
            return
        x = np.asarray(x, np.float32)
        xx = np.matmul(x[:, None, :], x[:, :, None])[:, 0, 0]  # each x . x as one dot product
        if not np.all(np.isfinite(xx)):
            raise ValueError("descriptor has non-finite values")
        self._own()
        n = self.n[slots]
        full = n >= self.capacity
        cols = n.copy()
        if full.any():
            every = bool(full.all())
            if d2 is None:
                d2 = self.pair_sq_distances(slots if every else slots[full], x if every else x[full])
            elif not every:
                d2 = d2[full]
            cols[full] = np.argmin(d2, axis=1)
        self._write(slots, cols, x, xx, np.where(full, n, n + 1))

    def _write(self, slots: np.ndarray, cols: np.ndarray, x: np.ndarray, xx: np.ndarray, n: np.ndarray) -> None:
        counter = self.counter[slots]
        self.data[slots, :, cols] = x
        self.sq[slots, cols] = xx
        self.age[slots, cols] = counter
        self.counter[slots] = counter + 1
        self.n[slots] = n


@dataclass
class TrackTable:
    """The tracks, one row each, in the order they were born. The filters' state is in arrays
    (one product moves every track): ``mean`` (T, S) and ``cov`` (T, S, S), ``posture`` (T, 3)
    and ``orientation`` (T, 8) (the TU Ilmenau framework's filters), ``clf`` (T, D + 1) the online classifiers (rows of zeros while untrained; None until the
    first is trained). The bookkeeping a frame reads a few entries of is in lists: ``id`` (0
    while tentative), ``is_person`` (IsPerson, a probability), ``status``, the stamps, the hit counts, ``in_view`` (None: not known),
    ``camera``, ``slot`` the gallery's in the :class:`GalleryBank` (-1: none yet), and for the ID
    memory's recovery (core/recovery.py) ``fix`` (x, y, variance per axis) at the last detection,
    ``probation`` (the recovered ID, its end, the next check, the share counted as returning)."""

    mean: np.ndarray
    cov: np.ndarray
    posture: np.ndarray
    orientation: np.ndarray
    clf: np.ndarray | None
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
                   np.zeros((0, pose.ORIENTATION_BINS)), None, *([] for _ in range(_LISTS)))

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
_ARRAYS = _FIELDS[:5]  # mean, cov, posture, orientation, clf; then the lists
_LISTS = len(_FIELDS) - len(_ARRAYS)
#: up to this many compared pairs, :meth:`GalleryBank.pair_sq_distances` takes the galleries one by one
_FEW_PAIRS = 2


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
                     posture=t.posture if posture else None, orientation=t.orientation if posture else None)


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
                     posture=t.posture[j] if posture else None, orientation=t.orientation[j] if posture else None)


def track_views(state: RobustTrackerState, stamp: float, view_known: bool, ukf: bool, posture: bool) -> list[TrackView]:
    """Every live track as :func:`track_view`; a coasting one says whether it is in view when
    the frame had a view (``view_known``)."""
    t = state.tracks
    if not t.id:
        return []
    means, covs = (t.mean[:, :6], t.cov[:, :6, :6]) if ukf else (t.mean, t.cov)
    poses = zip(t.posture, t.orientation) if posture else ((None, None) for _ in t.id)
    coasting, make, sizes = TrackStatus.COASTING, TrackView.of_fields, state.bank.n.tolist()
    return [make(i, s, m, c, h, 0, max(0.0, stamp - first), last, sizes[slot] if slot >= 0 else 0, ever,
                 flag if view_known and s is coasting else None, pp, o)
            for i, s, m, c, h, first, last, slot, ever, flag, (pp, o)
            in zip(t.id, t.status, means, covs, t.total_hits, t.first_stamp, t.last_update, t.slot, t.ever_confirmed,
                   t.in_view, poses)]
