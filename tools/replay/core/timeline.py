"""Replay timing: stamp ordering, pacing at a rate, time-window selection, rate metering.

Everything here works on integer nanosecond times and takes its clock as an argument, so
it is tested without sleeping. No Zenoh, no messages, no I/O.

The replay *timeline* is each message's stamp (``header.stamp_ns``; the ROS header stamp
for bags). A message without a stamp (0, as static transforms often have) takes the
position of the latest stamped message before it, so it goes out where it was recorded.
"""

from __future__ import annotations

import heapq
import itertools
import time
from collections import deque
from dataclasses import dataclass, field
from typing import Callable, Generic, Iterable, Iterator, TypeVar

__all__ = ["Pacer", "RateMeter", "Reorderer", "TimeWindow", "reorder"]

T = TypeVar("T")

#: How far a message may come later than messages stamped after it (in recording order)
#: and still go out in stamp order: derived messages are received one processing
#: latency after their frame's stamp.
DEFAULT_REORDER_WINDOW_NS = 1_000_000_000


@dataclass
class Reorderer(Generic[T]):
    """Puts items that arrive in recording order into stamp order, within a window.

    An item is released once an item stamped more than ``window_ns`` later has arrived,
    so the output is sorted whenever no item is late by more than the window. Later
    items are still released (never lost) as soon as they arrive, and counted in
    ``late``. Ties keep arrival order.
    """

    window_ns: int = DEFAULT_REORDER_WINDOW_NS
    late: int = 0
    _heap: list[tuple[int, int, T]] = field(default_factory=list)
    _counter: Iterator[int] = field(default_factory=itertools.count)
    _watermark: int = -1
    _released: int = -1
    _last_stamp: int = -1

    def key_of(self, stamp_ns: int) -> int:
        """The timeline position of a stamp; unstamped (<= 0) items follow the latest stamp."""
        if stamp_ns > 0:
            self._last_stamp = max(self._last_stamp, stamp_ns)
            return stamp_ns
        return self._last_stamp

    def push(self, stamp_ns: int, item: T) -> list[tuple[int, T]]:
        """Add an item; returns the ``(timeline position, item)`` pairs now due, in order."""
        key = self.key_of(stamp_ns)
        if key < self._released:
            self.late += 1
            key = self._released
        heapq.heappush(self._heap, (key, next(self._counter), item))
        self._watermark = max(self._watermark, key)
        out: list[tuple[int, T]] = []
        while self._heap and self._heap[0][0] < self._watermark - self.window_ns:
            k, _, it = heapq.heappop(self._heap)
            self._released = k
            out.append((k, it))
        return out

    def flush(self) -> list[tuple[int, T]]:
        """Everything still held, in order (at the end of the input)."""
        out = []
        while self._heap:
            k, _, it = heapq.heappop(self._heap)
            self._released = k
            out.append((k, it))
        return out


def reorder(items: Iterable[tuple[int, T]], window_ns: int = DEFAULT_REORDER_WINDOW_NS) -> Iterator[tuple[int, T]]:
    """``(stamp_ns, item)`` in recording order -> ``(timeline ns, item)`` in stamp order."""
    r: Reorderer[T] = Reorderer(window_ns)
    for stamp, item in items:
        yield from r.push(stamp, item)
    yield from r.flush()


@dataclass(frozen=True)
class TimeWindow:
    """``--start``/``--end`` in seconds from the first timeline position of the file."""

    start_s: float = 0.0
    end_s: float | None = None

    def __post_init__(self) -> None:
        if self.start_s < 0:
            raise ValueError(f"--start must be >= 0 s, got {self.start_s}")
        if self.end_s is not None and self.end_s <= self.start_s:
            raise ValueError(f"--end ({self.end_s} s) must be after --start ({self.start_s} s)")

    def position(self, t_ns: int, t0_ns: int) -> str:
        """``before``, ``inside`` or ``after`` the window."""
        rel = (t_ns - t0_ns) / 1e9
        if rel < self.start_s:
            return "before"
        if self.end_s is not None and rel > self.end_s:
            return "after"
        return "inside"


class Pacer:
    """When to publish each message so that the recorded timing is kept at ``rate``.

    The first message fixes the origin; a message at timeline ``t`` is due at
    ``wall0 + (t - t0) / rate``. ``rate=None`` means as fast as possible. A message
    due in the past goes at once (the replay then runs behind, never faster).
    """

    def __init__(self, rate: float | None = 1.0, clock: Callable[[], int] = time.monotonic_ns) -> None:
        if rate is not None and not rate > 0:
            raise ValueError(f"--rate must be > 0, got {rate}")
        self.rate = rate
        self._clock = clock
        self._t0: int | None = None
        self._wall0 = 0

    def reset(self) -> None:
        """Start over (the next message fixes a new origin), e.g. for ``--loop``."""
        self._t0 = None

    def delay_s(self, t_ns: int) -> float:
        """Seconds to wait before publishing the message at timeline ``t_ns`` (>= 0)."""
        now = self._clock()
        if self._t0 is None:
            self._t0, self._wall0 = t_ns, now
            return 0.0
        if self.rate is None:
            return 0.0
        due = self._wall0 + (t_ns - self._t0) / self.rate
        return max(0.0, (due - now) / 1e9)


class RateMeter:
    """Messages/s and bytes/s over the last ``window_s`` seconds."""

    def __init__(self, window_s: float = 2.0, clock: Callable[[], int] = time.monotonic_ns) -> None:
        self._window_ns = int(window_s * 1e9)
        self._clock = clock
        self._events: deque[tuple[int, int]] = deque()
        self._bytes = 0

    def add(self, nbytes: int) -> None:
        now = self._clock()
        self._events.append((now, nbytes))
        self._bytes += nbytes
        self._trim(now)

    def _trim(self, now: int) -> None:
        while self._events and self._events[0][0] < now - self._window_ns:
            self._bytes -= self._events.popleft()[1]

    def rates(self) -> tuple[float, float]:
        """(messages/s, bytes/s) over the window; (0, 0) before two messages."""
        self._trim(self._clock())
        if len(self._events) < 2:
            return 0.0, 0.0
        span = (self._events[-1][0] - self._events[0][0]) / 1e9
        if span <= 0:
            return 0.0, 0.0
        return (len(self._events) - 1) / span, self._bytes / span
