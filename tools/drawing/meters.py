"""A stream's rate (Hz) and latency (ms), measured the same way by every view: the operator's
page (``tools.viewer``) and the demo's live table (``tools.demo``) show the same numbers for
the same run.

Arrival times are the transport's receive stamps (``recv_ns``), not the time a reader got
round to polling: a reader that drains its queue twice a second would otherwise see bursts
and report a rate above the sender's.

Numpy only: it takes and returns floats.
"""

from __future__ import annotations

from collections import deque
from dataclasses import dataclass, field
from typing import Iterable

import numpy as np

__all__ = ["RATE_SPAN_S", "StageMeter"]

#: The window (s) of a live rate: the page and the demo's table both show this one.
RATE_SPAN_S = 3.0


@dataclass
class StageMeter:
    """Recent arrivals of one stream: rate (Hz) and latency from the sensor stamp (ms).

    Arrivals and latencies are kept apart: every arrival counts towards the rate, while the
    latency may be sampled (the viewer decodes only the newest message of each poll).
    """

    window: int = 300
    count: int = 0
    #: The first and the last arrival ever (s), for the rate over a whole run.
    first_at: float | None = None
    last_at: float | None = None
    _arrivals: deque[float] = field(default_factory=deque)
    _latencies: deque[tuple[float, float]] = field(default_factory=deque)

    def add(self, now: float, latency_ms: float) -> None:
        """One message that arrived at ``now`` and is ``latency_ms`` older than its stamp."""
        self.arrived([now])
        self.sample(now, latency_ms)

    def arrived(self, times: Iterable[float]) -> None:
        """Arrivals (seconds on the caller's clock, oldest first) whose latency is not measured."""
        for t in times:
            self.count += 1
            self._arrivals.append(t)
            if self.first_at is None:
                self.first_at = t
            self.last_at = t
        while len(self._arrivals) > self.window:
            self._arrivals.popleft()

    def sample(self, now: float, latency_ms: float) -> None:
        """One message's latency, measured at ``now``."""
        self._latencies.append((now, latency_ms))
        while len(self._latencies) > self.window:
            self._latencies.popleft()

    def rate_hz(self, now: float, span_s: float = RATE_SPAN_S) -> float:
        """Messages per second over the last ``span_s`` (0 when fewer than two arrived)."""
        t = np.fromiter(self._arrivals, np.float64, len(self._arrivals))
        recent = t[now - t <= span_s]
        if len(recent) < 2:
            return 0.0
        return (len(recent) - 1) / max(float(recent[-1] - recent[0]), 1e-6)

    def mean_rate_hz(self) -> float | None:
        """Messages per second from the first arrival to the last (None before two)."""
        if self.first_at is None or self.last_at is None or self.last_at <= self.first_at:
            return None
        return (self.count - 1) / (self.last_at - self.first_at)

    def latency_ms(self, q: float, now: float, span_s: float = 10.0) -> float | None:
        """The ``q``-th percentile latency of the last ``span_s`` seconds, or None."""
        recent = sorted(ms for t, ms in self._latencies if now - t <= span_s)
        if not recent:
            return None
        # numpy's default (linear) percentile, without numpy's per-call overhead
        pos = (len(recent) - 1) * q / 100.0
        lo = int(pos)
        hi = min(lo + 1, len(recent) - 1)
        return recent[lo] + (recent[hi] - recent[lo]) * (pos - lo)
