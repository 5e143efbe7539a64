"""The ID memory and Algorithm 2 of seed 000 (III-E): recovering a person's old ID.

The thesis keeps, for every ID, the list of galleries of the past tracks that carried it,
and measures a detection against an ID by the smallest distance to any descriptor of any
of those galleries. The smallest distance over a list of galleries equals the smallest
distance over their union, so each ID here keeps one bounded :class:`Gallery` (at most
``capacity`` descriptors, pruned like a track gallery) that absorbs every archived
gallery of that ID.

The memory can be saved to and loaded from a ``.npz`` file (no pickle). Saving writes a
temporary file next to the target and renames it over the target, so a crash never
leaves a half-written memory behind.
"""

from __future__ import annotations

import os
import tempfile
import zipfile
from collections.abc import Iterable
from pathlib import Path

import numpy as np

from services.tracker.core.gallery import Gallery

__all__ = ["FORMAT_VERSION", "IdentityMemory"]

#: Version of the ``.npz`` layout written by :meth:`IdentityMemory.save`.
FORMAT_VERSION = 1


class IdentityMemory:
    """ID -> bounded descriptor set, plus the next unused ID."""

    def __init__(self, capacity: int = 500, next_id: int = 1) -> None:
        self.capacity = capacity
        self.next_id = next_id
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
        entry = self.entries.get(track_id)
        if entry is None:
            entry = self.entries[track_id] = Gallery(descriptors.shape[1], self.capacity)
        elif entry.dim != descriptors.shape[1]:
            raise ValueError(f"ID {track_id}: descriptors of dimension {descriptors.shape[1]}, memory holds {entry.dim}")
        entry.extend(descriptors)
        self.next_id = max(self.next_id, track_id + 1)
        self.version += 1

    def distances(self, descriptor: np.ndarray, exclude: Iterable[int] = ()) -> tuple[np.ndarray, np.ndarray]:
        """Appearance distance from ``descriptor`` (D,) to every remembered ID not in ``exclude``.

        Returns ``ids`` (K,) int64 and ``distances`` (K,) float64, in ID order.
        """
        skip = set(exclude)
        ids = np.array(sorted(k for k in self.entries if k not in skip), dtype=np.int64)
        x = np.asarray(descriptor, dtype=np.float32)[None]
        dist = np.array([self.entries[int(k)].min_distances(x)[0] for k in ids], dtype=np.float64)
        return ids, dist

    def assign(self, descriptor: np.ndarray | None, live_ids: Iterable[int], t_recover: float) -> tuple[int, bool]:
        """Algorithm 2: the ID for a new track, and whether it was recovered from memory.

        IDs held by live tracks are skipped. If the closest remembered ID is nearer than
        ``t_recover`` it is reused; otherwise (or without a descriptor) ``next_id`` is taken.
        """
        if descriptor is not None and self.entries:
            ids, dist = self.distances(descriptor, exclude=live_ids)
            if len(ids):
                best = int(np.argmin(dist))
                if dist[best] < t_recover:
                    return int(ids[best]), True
        return self.new_id(), False

    def copy(self) -> IdentityMemory:
        """A snapshot sharing descriptor storage copy-on-write."""
        other = IdentityMemory(self.capacity, self.next_id)
        other.entries = {k: g.copy() for k, g in self.entries.items()}
        other.version = self.version
        return other

    # -------------------------------------------------------------- persistence
    def save(self, path: str | Path, model: str = "", extra: Iterable[tuple[int, np.ndarray]] = ()) -> None:
        """Write the memory atomically to ``path`` (``.npz``).

        ``extra`` adds (ID, descriptors (M, D)) blocks stored next to the memory, e.g. the
        galleries of the tracks alive now; :meth:`load` merges them into their IDs.
        """
        blocks = [(k, g.descriptors) for k, g in sorted(self.entries.items())]
        blocks += [(int(k), np.asarray(d, np.float32)) for k, d in extra if len(d)]
        dims = {d.shape[1] for _, d in blocks}
        if len(dims) > 1:
            raise ValueError(f"descriptors of several dimensions {sorted(dims)} cannot be saved together")
        dim = dims.pop() if dims else 0
        ids = np.array([k for k, _ in blocks], dtype=np.int64)
        counts = np.array([len(d) for _, d in blocks], dtype=np.int64)
        data = np.concatenate([d for _, d in blocks]) if blocks else np.zeros((0, dim), np.float32)
        target = Path(path)
        target.parent.mkdir(parents=True, exist_ok=True)
        fd, tmp = tempfile.mkstemp(prefix=target.name + ".", suffix=".tmp", dir=target.parent)
        try:
            with os.fdopen(fd, "wb") as f:
                np.savez(f, format_version=np.int64(FORMAT_VERSION), model=np.str_(model), next_id=np.int64(self.next_id),
                         capacity=np.int64(self.capacity), ids=ids, counts=counts, descriptors=data)
                f.flush()
                os.fsync(f.fileno())
            os.replace(tmp, target)
        except BaseException:
            if os.path.exists(tmp):
                os.unlink(tmp)
            raise

    @classmethod
    def load(cls, path: str | Path, capacity: int | None = None) -> tuple[IdentityMemory, str]:
        """Read a memory written by :meth:`save`; returns it and the embedding model's name.

        Raises ``ValueError`` naming the file when it is not a valid memory file.
        """
        try:
            with np.load(path, allow_pickle=False) as f:
                version = int(f["format_version"])
                model = str(f["model"])
                memory = cls(int(capacity or f["capacity"]), int(f["next_id"]))
                ids, counts, data = f["ids"], f["counts"], f["descriptors"]
        except (OSError, KeyError, EOFError, ValueError, AttributeError, zipfile.BadZipFile) as exc:
            raise ValueError(f"{path} is not a tracker ID memory file: {exc}") from exc
        if version != FORMAT_VERSION:
            raise ValueError(f"{path}: ID memory format {version}, this version reads {FORMAT_VERSION}")
        if counts.sum() != len(data) or len(ids) != len(counts):
            raise ValueError(f"{path}: ID memory file is inconsistent ({len(ids)} ids, {counts.sum()} counted, {len(data)} stored)")
        start = 0
        for k, c in zip(ids.tolist(), counts.tolist()):
            memory.archive(int(k), data[start : start + c])
            start += c
        memory.version = 0
        return memory, model
