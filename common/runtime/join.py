"""Joining streams that derive from the same source frame: one bounded N-way joiner.

Every message carries its source frame's header, and ``Header.join_key``
(``(stamp_ns, source, seq)``) is what they share. A :class:`Joiner` holds the inputs of
each key in named *slots* until an entry is ready, then releases it once:

* The first slot is the **anchor**: the message that asks for work (detections for the
  localizer and the embedder, localized detections for the tracker). Entries without
  their anchor are buffered inputs (frames, early embeddings): kept up to ``buffer``
  entries, the oldest silently evicted (a frame nobody asked about is normal), and
  dropped as ``orphan`` after ``orphan_s`` if set.
* An anchored entry is **ready** when every slot is filled (or ``complete`` says so).
  It waits at most ``wait_s`` from its anchor's arrival; then it is released
  incomplete (``on_timeout="release"``) or dropped as ``timeout``.
* At most ``max_waiting`` anchored entries wait; beyond that the oldest is dropped as
  ``overflow``.
* ``max_lag_s``: an anchored entry whose stamp is that much older than the newest stamp
  seen is dropped as ``stale`` (a slow consumer never works on old data).
* ``in_order``: slots whose messages arrive in stamp order per source (a FIFO frame
  stream). A missing one older than the newest seen of its source will never come, so
  the entry is dropped as ``lost`` at once instead of waiting for its timeout.
* ``ordered``: release in key order, never past an anchored entry still waiting, so a
  consumer that must apply inputs in sensor-time order gets them so.
* A key released recently (the last ``remember`` keys) is not opened again: a late or
  repeated input for it is dropped as ``late`` (or ``duplicate`` for a second anchor).
  A slot filled twice also counts as ``duplicate``. :meth:`Joiner.forget_released`
  forgets them when the stamps start over.

Filling a slot with ``None`` means "known not to come" (e.g. a rejected input): the
entry no longer waits for it. Every drop is returned to the caller with its reason, so
each node counts it under its own name and nothing is lost silently. Time is passed in
(``now``, monotonic seconds), so the joiner is pure and testable.
"""

from __future__ import annotations

from collections import OrderedDict
from dataclasses import dataclass, field
from typing import Any, Callable, Generic, Literal, Mapping, TypeVar

__all__ = ["Dropped", "JoinKey", "Joined", "Joiner"]

#: ``(stamp_ns, source, seq)``, as ``Header.join_key``.
JoinKey = tuple[int, str, int]
A = TypeVar("A")  # the anchor's type


@dataclass
class _Entry:
    created: float
    items: dict[str, Any] = field(default_factory=dict)
    anchored_at: float | None = None


@dataclass(frozen=True)
class Joined(Generic[A]):
    """A released entry: ``items`` by slot name (absent: never arrived), ``anchor`` its first slot."""

    key: JoinKey
    items: Mapping[str, Any]
    anchor: A
    arrived: float  # monotonic time the anchor arrived
    timed_out: bool = False

    def get(self, slot: str) -> Any:
        """The item of ``slot``; None if it never arrived or was filled with None."""
        return self.items.get(slot)


@dataclass(frozen=True)
class Dropped:
    """An input the joiner gave up on: ``reason`` is one of the reasons in the module doc."""

    key: JoinKey
    reason: str
    slots: tuple[str, ...]  # the slots that had arrived
    anchor: Any = None


class Joiner(Generic[A]):
    """Joins the slots of one key; see the module documentation for every rule."""

    def __init__(self, slots: tuple[str, ...], *, wait_s: float, buffer: int, max_waiting: int,
                 on_timeout: Literal["release", "drop"] = "drop", orphan_s: float | None = None,
                 max_lag_s: float | None = None, in_order: tuple[str, ...] = (), ordered: bool = False,
                 complete: Callable[[Mapping[str, Any]], bool] | None = None, remember: int = 256,
                 clock_jump_s: float | None = None) -> None:
        if len(slots) < 2 or len(set(slots)) != len(slots):
            raise ValueError(f"a join needs at least two distinct slots, got {slots}")
        if buffer < 1 or max_waiting < 1:
            raise ValueError("buffer and max_waiting must be at least 1")
        if unknown := set(in_order) - set(slots[1:]):
            raise ValueError(f"in_order names slots that are not joined slots: {sorted(unknown)}")
        self.slots = slots
        self.anchor_slot = slots[0]
        self.wait_s = wait_s
        self.buffer = buffer
        self.max_waiting = max_waiting
        self.on_timeout = on_timeout
        self.orphan_s = orphan_s
        self.max_lag_ns = None if max_lag_s is None else int(max_lag_s * 1e9)
        self.in_order = in_order
        self.ordered = ordered
        self._complete = complete
        self._remember = remember
        self._entries: dict[JoinKey, _Entry] = {}
        self._released: OrderedDict[JoinKey, None] = OrderedDict()
        self._newest_by_slot: dict[tuple[str, str], int] = {}  # (slot, source) -> newest stamp
        self.newest_ns: int | None = None
        self.evicted = 0
        #: a stamp this much older than the newest is a new clock (a replay that loops, a
        #: clock reset): the released keys are forgotten so the same keys can come again
        self.clock_jump_ns = None if clock_jump_s is None else int(clock_jump_s * 1e9)
        self.clock_jumps = 0

    # ------------------------------------------------------------------ input
    def add(self, slot: str, key: JoinKey, item: Any, now: float) -> list[Dropped]:
        """File ``item`` under ``key``; returns what was dropped as a result (duplicates, overflow)."""
        if slot not in self.slots:
            raise KeyError(f"unknown slot {slot!r}; this join has {self.slots}")
        stamp, source, _ = key
        if self.clock_jump_ns is not None and self.newest_ns is not None and stamp < self.newest_ns - self.clock_jump_ns:
            self.forget_released()
            self.clock_jumps += 1
        self.newest_ns = stamp if self.newest_ns is None else max(self.newest_ns, stamp)
        if slot in self.in_order:
            k = (slot, source)
            self._newest_by_slot[k] = max(self._newest_by_slot.get(k, stamp), stamp)
        if key in self._released:
            return [Dropped(key, "duplicate" if slot == self.anchor_slot else "late", (slot,))]
        entry = self._entries.get(key)
        if entry is None:
            entry = self._entries[key] = _Entry(created=now)
        elif slot in entry.items:
            return [Dropped(key, "duplicate", (slot,))]
        entry.items[slot] = item
        if slot == self.anchor_slot:
            entry.anchored_at = now
        return self._bound()

    def _bound(self) -> list[Dropped]:
        dropped = []
        loose = [k for k, e in self._entries.items() if e.anchored_at is None]
        if len(loose) > self.buffer:
            for k in sorted(loose)[: len(loose) - self.buffer]:
                del self._entries[k]
                self.evicted += 1
        waiting = [k for k, e in self._entries.items() if e.anchored_at is not None]
        if len(waiting) > self.max_waiting:
            for k in sorted(waiting, key=lambda k: self._entries[k].anchored_at)[: len(waiting) - self.max_waiting]:
                dropped.append(self._drop(k, "overflow"))
        return dropped

    # ----------------------------------------------------------------- output
    def _ready(self, entry: _Entry) -> bool:
        if self._complete is not None:
            return self._complete(entry.items)
        return all(s in entry.items for s in self.slots)

    def _lost(self, key: JoinKey, entry: _Entry) -> bool:
        for slot in self.in_order:
            if slot not in entry.items:
                newest = self._newest_by_slot.get((slot, key[1]))
                if newest is not None and newest >= key[0]:
                    return True
        return False

    def _drop(self, key: JoinKey, reason: str) -> Dropped:
        entry = self._entries.pop(key)
        self._remember_key(key)
        return Dropped(key, reason, tuple(entry.items), entry.items.get(self.anchor_slot))

    def _remember_key(self, key: JoinKey) -> None:
        self._released[key] = None
        while len(self._released) > self._remember:
            self._released.popitem(last=False)

    def _release(self, key: JoinKey, timed_out: bool) -> Joined[A]:
        entry = self._entries.pop(key)
        self._remember_key(key)
        assert entry.anchored_at is not None
        return Joined(key, entry.items, entry.items[self.anchor_slot], entry.anchored_at, timed_out)

    def poll(self, now: float, limit: int | None = None) -> tuple[list[Joined[A]], list[Dropped]]:
        """Release what is ready (at most ``limit`` entries) and drop what has expired."""
        released: list[Joined[A]] = []
        dropped: list[Dropped] = []
        blocked = False  # ordered: an entry still waits, so nothing after it is released
        for key in sorted(self._entries):
            entry = self._entries[key]
            if entry.anchored_at is None:
                if self.orphan_s is not None and now - entry.created > self.orphan_s:
                    dropped.append(self._drop(key, "orphan"))
                continue
            if self.max_lag_ns is not None and self.newest_ns is not None and key[0] + self.max_lag_ns < self.newest_ns:
                dropped.append(self._drop(key, "stale"))
                continue
            if blocked:
                continue
            if limit is not None and len(released) >= limit:
                blocked = self.ordered
                continue
            if self._ready(entry):
                released.append(self._release(key, False))
            elif now - entry.anchored_at >= self.wait_s:
                if self.on_timeout == "release":
                    released.append(self._release(key, True))
                else:
                    dropped.append(self._drop(key, "timeout"))
            elif self._lost(key, entry):
                dropped.append(self._drop(key, "lost"))
            elif self.ordered:
                blocked = True
        return released, dropped

    def forget_released(self) -> None:
        """Forget the keys released so far and the newest stamps seen, so that keys can come
        again (a clock jump: a replay that loops sends the same keys a second time). The
        entries still held are kept."""
        self._released.clear()
        self._newest_by_slot.clear()
        self.newest_ns = None

    def next_deadline(self, now: float) -> float | None:
        """Seconds until the earliest waiting entry times out (None if none waits)."""
        waits = [e.anchored_at + self.wait_s - now for e in self._entries.values() if e.anchored_at is not None]
        return max(0.0, min(waits)) if waits else None

    @property
    def waiting(self) -> int:
        """Anchored entries still waiting for their other slots."""
        return sum(1 for e in self._entries.values() if e.anchored_at is not None)

    def __len__(self) -> int:
        return len(self._entries)
