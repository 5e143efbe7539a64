"""The ID memory and Algorithm 2 of Pinto's thesis (III-E): recovering a person's old ID.

The thesis keeps, for every ID, the galleries of the past tracks that carried it and measures a
detection against an ID by the smallest distance to any of their descriptors: the smallest over
their union, so each ID here keeps one bounded :class:`Gallery` that absorbs every archived
gallery of that ID. The memory turns into plain arrays and back (:meth:`IdentityMemory.to_blocks`,
:meth:`IdentityMemory.from_blocks`); the file is the service's (``memory_file.py``).
"""

from __future__ import annotations

from collections.abc import Iterable

import numpy as np

from services.tracker.core.gallery import Gallery

__all__ = ["IdentityMemory"]


class IdentityMemory:
    """ID -> bounded descriptor set, plus the next unused ID.

    ``max_ids`` (None: unbounded) bounds how many IDs are remembered: archiving one more
    forgets the ID archived longest ago (every archive makes an ID the newest)."""

    def __init__(self, capacity: int = 500, next_id: int = 1, max_ids: int | None = None) -> None:
        self.capacity = capacity
        self.next_id = next_id
        self.max_ids = max_ids
        #: IDs forgotten to keep within ``max_ids``
        self.evicted = 0
        self.entries: dict[int, Gallery] = {}
        #: Incremented whenever a descriptor set changes, so callers can tell when to persist.
        self.version = 0

    def __len__(self) -> int:
        return len(self.entries)

    def __contains__(self, track_id: int) -> bool:
        return track_id in self.entries

    def new_id(self) -> int:
        """Take the next unused ID."""
        track_id = self.next_id
        self.next_id += 1
        return track_id

    def archive(self, track_id: int, descriptors: np.ndarray) -> None:
        """Add a finished track's gallery (M, D) to ``track_id``'s memory."""
        descriptors = np.asarray(descriptors, dtype=np.float32)
        if len(descriptors) == 0:
            return
        entry = self.entries.pop(track_id, None)  # re-inserted below: the newest archived
        if entry is None:
            entry = Gallery(descriptors.shape[1], self.capacity)
        elif entry.dim != descriptors.shape[1]:
            self.entries[track_id] = entry
            raise ValueError(f"ID {track_id}: descriptors of dimension {descriptors.shape[1]}, memory holds {entry.dim}")
        self.entries[track_id] = entry
        entry.extend(descriptors)
        while self.max_ids is not None and len(self.entries) > self.max_ids:
            del self.entries[next(iter(self.entries))]
            self.evicted += 1
        self.next_id = max(self.next_id, track_id + 1)
        self.version += 1

    def forget(self, track_id: int) -> int:
        """Remove everything remembered of ``track_id``; returns how many descriptors went."""
        entry = self.entries.pop(track_id, None)
        if entry is None:
            return 0
        self.version += 1
        return len(entry)

    def distances(self, descriptor: np.ndarray, exclude: Iterable[int] = ()) -> tuple[np.ndarray, np.ndarray]:
        """``ids`` (K,) int64 and ``distances`` (K,): from ``descriptor`` (D,) to every remembered ID not
        in ``exclude``, in ID order."""
        skip = set(exclude)
        ids = np.array(sorted(k for k in self.entries if k not in skip), dtype=np.int64)
        x = np.asarray(descriptor, dtype=np.float32)[None]
        dist = np.array([self.entries[int(k)].min_distances(x)[0] for k in ids], dtype=np.float64)
        return ids, dist

    def assign(self, descriptor: np.ndarray | None, live_ids: Iterable[int], t_recover: float) -> tuple[int, bool]:
        """Algorithm 2: the ID for a new track, and whether it was recovered: the nearest remembered ID
        not held by a live track if nearer than ``t_recover``, else (or without a descriptor) a new one."""
        track_id, recovered, _, _ = self.assign_weighed(descriptor, live_ids, t_recover)
        return track_id, recovered

    def assign_weighed(self, descriptor: np.ndarray | None, live_ids: Iterable[int],
                       t_recover: float) -> tuple[int, bool, np.ndarray, np.ndarray]:
        """:meth:`assign`, with the remembered IDs it weighed and their distances ((K,) int64,
        (K,); empty without a descriptor or anyone to weigh): what explains its decision."""
        ids, dist = np.zeros(0, np.int64), np.zeros(0)
        if descriptor is not None and self.entries:
            ids, dist = self.distances(descriptor, exclude=live_ids)
            if len(ids):
                best = int(np.argmin(dist))
                if dist[best] < t_recover:
                    return int(ids[best]), True, ids, dist
        return self.new_id(), False, ids, dist

    def copy(self) -> IdentityMemory:
        """A snapshot sharing descriptor storage copy-on-write."""
        other = IdentityMemory(self.capacity, self.next_id, self.max_ids)
        other.evicted = self.evicted
        other.entries = {k: g.copy() for k, g in self.entries.items()}
        other.version = self.version
        return other

    # ------------------------------------------------------- plain-array form
    def to_blocks(self, extra: Iterable[tuple[int, np.ndarray]] = ()) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """The remembered descriptors as plain arrays: ``ids`` (K,), ``counts`` (K,) and ``descriptors``
        (sum of counts, D) float32, block k the ``counts[k]`` rows of ID ``ids[k]``; the IDs in order,
        then the ``extra`` (ID, descriptors (M, D)) blocks (:meth:`from_blocks` merges an ID's blocks)."""
        blocks = [(k, g.descriptors) for k, g in sorted(self.entries.items())]
        blocks += [(int(k), np.asarray(d, np.float32)) for k, d in extra if len(d)]
        dims = {d.shape[1] for _, d in blocks}
        if len(dims) > 1:
            raise ValueError(f"descriptors of several dimensions {sorted(dims)} cannot be saved together")
        dim = dims.pop() if dims else 0
        ids = np.array([k for k, _ in blocks], dtype=np.int64)
        counts = np.array([len(d) for _, d in blocks], dtype=np.int64)
        data = np.concatenate([d for _, d in blocks]) if blocks else np.zeros((0, dim), np.float32)
        return ids, counts, data

    @classmethod
    def from_blocks(cls, capacity: int, next_id: int, ids: np.ndarray, counts: np.ndarray,
                    descriptors: np.ndarray) -> IdentityMemory:
        """A memory holding the blocks of :meth:`to_blocks` (``version`` 0); ``ValueError`` when the
        counts do not add up to the descriptors."""
        if counts.sum() != len(descriptors) or len(ids) != len(counts):
            raise ValueError(f"inconsistent blocks ({len(ids)} ids, {counts.sum()} counted, {len(descriptors)} stored)")
        memory = cls(capacity, next_id)
        start = 0
        for k, c in zip(ids.tolist(), counts.tolist()):
            memory.archive(int(k), descriptors[start : start + c])
            start += c
        memory.version = 0
        return memory
