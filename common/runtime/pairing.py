"""Colour and depth images paired by stamp: each colour image goes with the depth image nearest
in time, within ``slop_ns``, once no later depth image can be nearer (``message_filters``'
approximate-time policy for two streams). One pairer for the live ROS 2 node and for replayed
recordings.

A colour image waits until the depth stream has passed its stamp. It is released without depth
waiting no longer when, whichever comes first (each is off when None):

* it has waited ``wait_s`` of arrival time (a live camera: the caller's clock);
* the colour stream has run ``hold_ns`` ahead of it (a recording: its own stamps);
* more than ``queue`` colour images wait;
* the input ends (``ready(final=True)``).

A colour image released so still takes the nearest depth image within ``slop_ns`` that has come.
Each release says why (``Pair.why``) so the caller can count it; depth images no colour image can
use any more are counted in ``stale_depth``. Generic over the payloads (tested with strings).
"""

from __future__ import annotations

from collections import deque
from dataclasses import dataclass, field
from typing import Generic, TypeVar

__all__ = ["Pair", "StampPairer"]

C = TypeVar("C")
D = TypeVar("D")


@dataclass(frozen=True)
class Pair(Generic[C, D]):
    """A colour item and its depth item (None: released alone), and why: "paired",
    "no_depth_near" (depth passed it with none near enough), "depth_late" (it waited no longer
    and the depth near it had not come), "no_depth" (no depth at all), "no_depth_stream"."""

    stamp_ns: int
    colour: C
    depth: D | None
    why: str = "paired"


@dataclass
class StampPairer(Generic[C, D]):
    slop_ns: int = 50_000_000
    wait_s: float | None = None
    hold_ns: int | None = None
    queue: int | None = None
    #: False: there is no depth stream, each colour image goes at once
    expect_depth: bool = True
    #: depth images kept at most (the oldest go first; None: no bound)
    depth_queue: int | None = None
    paired: int = 0
    unpaired: int = 0
    #: depth images dropped because no colour image could use them
    stale_depth: int = 0
    _colour: deque[tuple[int, float, C]] = field(default_factory=deque)
    _depth: deque[tuple[int, D]] = field(default_factory=deque)

    def add_colour(self, stamp_ns: int, item: C, now: float = 0.0) -> None:
        """A colour image stamped ``stamp_ns``, arrived at ``now`` (the caller's clock, seconds)."""
        self._colour.append((stamp_ns, now, item))

    def add_depth(self, stamp_ns: int, item: D) -> None:
        if self._depth and stamp_ns < self._depth[-1][0]:  # out of order: kept in stamp order
            self._depth = deque(sorted([*self._depth, (stamp_ns, item)], key=lambda x: x[0]))
        else:
            self._depth.append((stamp_ns, item))
        while self.depth_queue is not None and len(self._depth) > self.depth_queue:
            self._depth.popleft()
            self.stale_depth += 1

    def ready(self, now: float = 0.0, final: bool = False) -> list[Pair[C, D]]:
        """Every colour image that can be released at ``now``, oldest first (``final``: all of
        them, the input has ended; the depth left over then counts as stale)."""
        out: list[Pair[C, D]] = []
        while self._colour:
            stamp, arrived, colour = self._colour[0]
            if not self.expect_depth:
                self._colour.popleft()
                out.append(Pair(stamp, colour, None, "no_depth_stream"))
                continue
            while self._depth and self._depth[0][0] < stamp - self.slop_ns:  # too old for this or any later
                self._depth.popleft()
                self.stale_depth += 1
            decided = bool(self._depth) and self._depth[-1][0] >= stamp
            if not (decided or final or self._gives_up(stamp, arrived, now)):
                break
            self._colour.popleft()
            best = self._nearest(stamp)
            if best is None:
                self.unpaired += 1
                out.append(Pair(stamp, colour, None, "no_depth_near" if decided else
                                "depth_late" if self._depth else "no_depth"))
                continue
            for _ in range(best):  # older than the one taken: no later colour image is nearer
                self._depth.popleft()
                self.stale_depth += 1
            self.paired += 1
            out.append(Pair(stamp, colour, self._depth.popleft()[1]))
        if final:
            self.stale_depth += len(self._depth)
            self._depth.clear()
        return out

    def _gives_up(self, stamp: int, arrived: float, now: float) -> bool:
        return ((self.wait_s is not None and now - arrived >= self.wait_s)
                or (self.hold_ns is not None and self._colour[-1][0] - stamp > self.hold_ns)
                or (self.queue is not None and len(self._colour) > self.queue))

    def _nearest(self, stamp: int) -> int | None:
        """The index of the depth image nearest ``stamp`` within the slop (the older on a tie)."""
        best, gap = None, self.slop_ns
        for i, (d, _) in enumerate(self._depth):
            if abs(d - stamp) <= gap and (best is None or abs(d - stamp) < gap):
                best, gap = i, abs(d - stamp)
            if d > stamp:
                break
        return best

    def __len__(self) -> int:
        return len(self._colour)
