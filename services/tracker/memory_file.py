"""The ID memory's file: an ``.npz`` (no pickle) loaded at start and rewritten on change.

Layout (version :data:`FORMAT_VERSION`): ``format_version``, ``model`` (the embedding model's
name), ``next_id``, ``capacity``, the memory's blocks (:meth:`IdentityMemory.to_blocks`: ``ids``
(K,), ``counts`` (K,), ``descriptors`` (sum of counts, D) float32); optionally the robust profile's
online classifiers (``classifier_ids`` (C,), ``classifiers`` (C, D + 1) float64), when each ID was
last seen (``seen_ids`` (S,), ``seen_at`` (S,), Unix time, for the retention) and the open-set
recovery's arrays (``recovery_*``, core/recovery.py; departures on the sensors' clock, s). A file
without an optional block reads as none. Saving writes a temporary file next to the target, syncs
it and renames it over the target: a crash never leaves a half-written memory behind.
"""

from __future__ import annotations

import logging
import os
import tempfile
import zipfile
from collections.abc import Iterable, Mapping
from pathlib import Path

import numpy as np

from services.tracker.config import TrackerConfig
from services.tracker.core import IdentityMemory

__all__ = ["FORMAT_VERSION", "descriptor_dim", "load_memory", "read_classifiers", "read_last_seen", "read_memory",
           "read_recovery", "save_memory", "shift_recovery"]

log = logging.getLogger(__name__)

#: Version of the ``.npz`` layout written by :func:`save_memory`.
FORMAT_VERSION = 1


def save_memory(path: str | Path, memory: IdentityMemory, model: str = "",
                extra: Iterable[tuple[int, np.ndarray]] = (),
                classifiers: Mapping[int, np.ndarray] | None = None,
                last_seen: Mapping[int, float] | None = None,
                recovery: Mapping[str, np.ndarray] | None = None) -> None:
    """Write ``memory`` atomically to ``path``, with ``extra`` (ID, descriptors (M, D)) blocks (the
    live tracks' galleries: :func:`read_memory` merges them into their IDs), ``classifiers`` (ID ->
    weights (D + 1,)), ``last_seen`` (ID -> Unix time) and the ``recovery``'s arrays. ``OSError``, or
    ``ValueError`` for descriptors or classifiers of several dimensions, or other array names."""
    blocks = dict(recovery or {})
    if any(not k.startswith("recovery_") for k in blocks):
        raise ValueError(f"recovery arrays must be named recovery_*, got {sorted(blocks)}")
    ids, counts, data = memory.to_blocks(extra)
    clf = {int(i): np.asarray(w, np.float64) for i, w in (classifiers or {}).items()}
    if len({len(w) for w in clf.values()}) > 1:
        raise ValueError("classifiers of several dimensions")
    clf_ids = np.array(sorted(clf), np.int64)
    clf_w = np.stack([clf[i] for i in clf_ids.tolist()]) if clf else np.zeros((0, 0))
    seen = dict(sorted((last_seen or {}).items()))
    seen_ids, seen_at = np.array(list(seen), np.int64), np.array(list(seen.values()), np.float64)
    target = Path(path)
    target.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(prefix=target.name + ".", suffix=".tmp", dir=target.parent)
    try:
        with os.fdopen(fd, "wb") as f:
            np.savez(f, format_version=np.int64(FORMAT_VERSION), model=np.str_(model), next_id=np.int64(memory.next_id),
                     capacity=np.int64(memory.capacity), ids=ids, counts=counts, descriptors=data,
                     classifier_ids=clf_ids, classifiers=clf_w, seen_ids=seen_ids, seen_at=seen_at, **blocks)
            f.flush()
            os.fsync(f.fileno())
        os.replace(tmp, target)
    except BaseException:
        if os.path.exists(tmp):
            os.unlink(tmp)
        raise


def read_memory(path: str | Path, capacity: int | None = None) -> tuple[IdentityMemory, str]:
    """The memory :func:`save_memory` wrote and the embedding model's name (``capacity`` overrides
    the file's); ``ValueError`` naming the file when it is not a valid memory file."""
    try:
        with np.load(path, allow_pickle=False) as f:
            version = int(f["format_version"])
            model = str(f["model"])
            capacity, next_id = int(capacity or f["capacity"]), int(f["next_id"])
            ids, counts, data = f["ids"], f["counts"], f["descriptors"]
    except (OSError, KeyError, EOFError, ValueError, AttributeError, zipfile.BadZipFile) as exc:
        raise ValueError(f"{path} is not a tracker ID memory file: {exc}") from exc
    if version != FORMAT_VERSION:
        raise ValueError(f"{path}: ID memory format {version}, this version reads {FORMAT_VERSION}")
    if counts.sum() != len(data) or len(ids) != len(counts):
        raise ValueError(f"{path}: ID memory file is inconsistent ({len(ids)} ids, {counts.sum()} counted, {len(data)} stored)")
    return IdentityMemory.from_blocks(capacity, next_id, ids, counts, data), model


def _optional_pair(path: str | Path, ids_key: str, values_key: str, what: str) -> tuple[np.ndarray, np.ndarray] | None:
    """The (ids, values) arrays of an optional block of the file, None if the file has none;
    ``ValueError`` naming the file and ``what`` when they are unreadable or differ in length."""
    try:
        with np.load(path, allow_pickle=False) as f:
            if values_key not in f.files:
                return None
            ids, values = f[ids_key], f[values_key]
    except (OSError, KeyError, EOFError, ValueError, zipfile.BadZipFile) as exc:
        raise ValueError(f"{path}: unreadable {what} in the ID memory file: {exc}") from exc
    if len(ids) != len(values):
        raise ValueError(f"{path}: inconsistent {what} in the ID memory file ({len(ids)} ids, {len(values)} values)")
    return ids, values


def read_classifiers(path: str | Path) -> dict[int, np.ndarray]:
    """The online classifiers stored by :func:`save_memory` (empty for a file without them);
    ``ValueError`` naming the file when they are unreadable or inconsistent."""
    block = _optional_pair(path, "classifier_ids", "classifiers", "classifiers")
    if block is None:
        return {}
    ids, weights = block
    if (len(ids) and weights.ndim != 2) or not np.all(np.isfinite(weights)):
        raise ValueError(f"{path}: inconsistent classifiers in the ID memory file ({len(ids)} ids, shape {weights.shape})")
    return {int(i): w.astype(np.float64) for i, w in zip(ids.tolist(), weights)}


def read_last_seen(path: str | Path) -> dict[int, float]:
    """ID -> Unix time last seen, as stored by :func:`save_memory` (empty for a file without it)."""
    block = _optional_pair(path, "seen_ids", "seen_at", "last-seen times")
    if block is None:
        return {}
    return {int(i): float(t) for i, t in zip(block[0].tolist(), block[1].tolist())}


def read_recovery(path: str | Path) -> dict[str, np.ndarray]:
    """The recovery's arrays stored by :func:`save_memory` (empty for a file without them); the
    departures' stamps are in the sensors' clock, seconds (:func:`shift_recovery`)."""
    try:
        with np.load(path, allow_pickle=False) as f:
            return {k: f[k] for k in f.files if k.startswith("recovery_")}
    except (OSError, KeyError, EOFError, ValueError, zipfile.BadZipFile) as exc:
        raise ValueError(f"{path}: unreadable recovery state in the ID memory file: {exc}") from exc


def shift_recovery(arrays: Mapping[str, np.ndarray], seconds: float) -> dict[str, np.ndarray]:
    """``arrays`` (the recovery's) with every departure's stamp moved by ``seconds``: the file
    keeps the sensors' clock (Unix time), the tracker counts from its first frame."""
    out = dict(arrays)
    if "recovery_departures" in out and len(out["recovery_departures"]):
        moved = np.array(out["recovery_departures"], np.float64)
        moved[:, 0] += seconds
        out["recovery_departures"] = moved
    return out


def load_memory(config: TrackerConfig) -> tuple[IdentityMemory, str | None]:
    """The ID memory from ``config.memory_path`` (empty if the file does not exist);
    ``ValueError`` for an unreadable file or one written for another model."""
    path = config.memory_path
    if path is None or not path.exists():
        return IdentityMemory(config.memory_size), None
    memory, model = read_memory(path, capacity=config.memory_size)
    if config.embedding_model and model and model != config.embedding_model:
        raise ValueError(f"{path} holds identities of embedding model {model!r}, the tracker is configured for "
                         f"{config.embedding_model!r}; move the file away or set memory_path to another file")
    log.info("loaded %d identities from %s (next id %d)", len(memory), path, memory.next_id)
    return memory, model or None


def descriptor_dim(memory: IdentityMemory) -> int | None:
    """The dimension D of the remembered descriptors; None while the memory is empty."""
    return next((g.dim for g in memory.entries.values()), None)
