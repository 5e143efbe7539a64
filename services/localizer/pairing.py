"""Pairing derived messages with their source frame: a bounded ring of recent frames.

Frames arrive in order per source. Detections for a frame arrive after it (the
detector needs the frame first), usually after several newer frames, so the
localizer keeps the last few depth frames and looks them up by
``(source, stamp_ns, seq)``.
"""

from __future__ import annotations

from collections import OrderedDict
from typing import Generic, TypeVar

__all__ = ["FrameKey", "FrameRing"]

T = TypeVar("T")
FrameKey = tuple[str, int, int]  # (source, stamp_ns, seq)


class FrameRing(Generic[T]):
    """The ``capacity`` most recent frames, by ``(source, stamp_ns, seq)``."""

    def __init__(self, capacity: int) -> None:
        if capacity < 1:
            raise ValueError(f"capacity must be >= 1, got {capacity}")
        self.capacity = capacity
        self._items: OrderedDict[FrameKey, T] = OrderedDict()
        self._newest: dict[str, int] = {}  # newest stamp_ns seen per source (kept after eviction)
        self.evicted = 0

    def add(self, key: FrameKey, item: T) -> None:
        self._items[key] = item
        self._items.move_to_end(key)
        self._newest[key[0]] = max(self._newest.get(key[0], key[1]), key[1])
        while len(self._items) > self.capacity:
            self._items.popitem(last=False)
            self.evicted += 1

    def get(self, key: FrameKey) -> T | None:
        return self._items.get(key)

    def passed(self, key: FrameKey) -> bool:
        """Whether a frame of this source at or after ``key``'s stamp was already seen.

        Frames of one source arrive in order, so if ``key`` is not held and this is
        true, its frame was lost or evicted and will not come.
        """
        newest = self._newest.get(key[0])
        return newest is not None and newest >= key[1]

    def __len__(self) -> int:
        return len(self._items)
