"""Colour and depth images paired by stamp, as ``message_filters``' approximate-time policy does
for two streams: each colour image is paired with the depth image nearest in time, within
``slop_s``, once no later depth image can be nearer.

A colour image waits for the depth stream to pass its stamp; it is released unpaired (or
dropped, when depth is required) when depth has passed it with nothing near enough, when it has
waited ``wait_s`` of arrival time, or when ``queue`` newer colour images are waiting. Each
release says why, so the node can count it.
"""

from __future__ import annotations

from collections import deque
from dataclasses import dataclass, field
from typing import Generic, TypeVar

__all__ = ["Pair", "Pairer"]

C = TypeVar("C")
D = TypeVar("D")


@dataclass(frozen=True)
class Pair(Generic[C, D]):
    """A colour item and its depth item (None when released alone), and why it was released."""

    stamp_ns: int
    colour: C
    depth: D | None
    why: str = "paired"


@dataclass
class Pairer(Generic[C, D]):
    slop_s: float = 0.05
    wait_s: float = 0.5
    queue: int = 8
    _colour: deque[tuple[int, float, C]] = field(default_factory=deque)
    _depth: deque[tuple[int, D]] = field(default_factory=deque)
    #: Depth images dropped because no colour image was near them.
    stale_depth: int = 0

    def add_colour(self, stamp_ns: int, item: C, now: float) -> None:
        self._colour.append((stamp_ns, now, item))

    def add_depth(self, stamp_ns: int, item: D) -> None:
        # out-of-order depth is kept in stamp order
        if self._depth and stamp_ns < self._depth[-1][0]:
            items = sorted([*self._depth, (stamp_ns, item)], key=lambda x: x[0])
            self._depth = deque(items)
        else:
            self._depth.append((stamp_ns, item))
        while len(self._depth) > 4 * self.queue:
            self._depth.popleft()
            self.stale_depth += 1

    def ready(self, now: float) -> list[Pair[C, D]]:
        """Everything that can be released at ``now`` (arrival clock, seconds), oldest first.

        A pair with ``depth`` None and ``why`` other than "paired" is unpaired colour: the caller
        publishes it alone (an RGB-only camera) or counts it as dropped (depth required).
        """
        out: list[Pair[C, D]] = []
        slop = int(self.slop_s * 1e9)
        while self._colour:
            stamp, arrived, colour = self._colour[0]
            # depth images too old to pair with this or any later colour image
            while self._depth and self._depth[0][0] < stamp - slop:
                self._depth.popleft()
                self.stale_depth += 1
            newest_depth = self._depth[-1][0] if self._depth else None
            decided = newest_depth is not None and newest_depth >= stamp
            if decided:
                best = min(range(len(self._depth)), key=lambda i: abs(self._depth[i][0] - stamp))
                if abs(self._depth[best][0] - stamp) <= slop:
                    depth = self._depth[best][1]
                    for _ in range(best + 1):
                        self._depth.popleft()
                    self._colour.popleft()
                    out.append(Pair(stamp, colour, depth))
                    continue
                self._colour.popleft()
                out.append(Pair(stamp, colour, None, "no_depth_near"))
                continue
            if now - arrived >= self.wait_s or len(self._colour) > self.queue:
                self._colour.popleft()
                out.append(Pair(stamp, colour, None, "depth_late" if self._depth else "no_depth"))
                continue
            break
        return out

    def __len__(self) -> int:
        return len(self._colour)
