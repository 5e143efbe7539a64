"""The viewer's pure pieces: colours as the page writes them, headings, trails, rates and latencies.

Everything takes and returns numpy arrays, floats and dataclasses; the node turns
messages into these and the results into the page's JSON. The colour of an ID and which
image box a track is are shared with the other views (:mod:`tools.drawing.tracks`).
"""

from __future__ import annotations

import math
from collections import deque
from dataclasses import dataclass, field
from typing import Iterable

import numpy as np

from tools.drawing.tracks import colour_rgb

__all__ = ["StageMeter", "Trails", "colour_hex", "yaw_of"]


def colour_hex(track_id: int) -> str:
    """``colour_rgb`` as ``#rrggbb``."""
    return "#{:02x}{:02x}{:02x}".format(*colour_rgb(track_id))


def yaw_of(rotation: np.ndarray) -> float:
    """Heading (rad, about z) of a (3, 3) rotation matrix: where its x axis points in the plane."""
    return math.atan2(float(rotation[1, 0]), float(rotation[0, 0]))


@dataclass
class Trails:
    """The last ``span_s`` seconds of each track's ground-plane position.

    ``add(id, t, x, y)`` appends (at most one point per ``min_step_s``); ``prune(now)``
    forgets old points and tracks not seen for ``span_s``.
    """

    span_s: float = 5.0
    min_step_s: float = 0.1
    max_points: int = 100
    _points: dict[int, deque[tuple[float, float, float]]] = field(default_factory=dict)

    def add(self, track_id: int, t: float, x: float, y: float) -> None:
        trail = self._points.setdefault(track_id, deque(maxlen=self.max_points))
        if trail and t - trail[-1][0] < self.min_step_s:
            trail[-1] = (trail[-1][0], x, y)  # keep the newest position, not a denser trail
            return
        trail.append((t, x, y))

    def prune(self, now: float) -> None:
        for track_id in list(self._points):
            trail = self._points[track_id]
            while trail and now - trail[0][0] > self.span_s:
                trail.popleft()
            if not trail:
                del self._points[track_id]

    def get(self, track_id: int) -> list[tuple[float, float]]:
        """The trail of ``track_id``, oldest first, as (x, y) pairs."""
        return [(x, y) for _, x, y in self._points.get(track_id, ())]


@dataclass
class StageMeter:
    """Recent arrivals of one stream: rate (Hz) and latency from the sensor stamp (ms).

    Arrivals and latencies are kept apart: every arrival counts towards the rate, while the
    latency may be sampled (the viewer decodes only the newest message of each poll).
    """

    window: int = 300
    count: int = 0
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
        while len(self._arrivals) > self.window:
            self._arrivals.popleft()

    def sample(self, now: float, latency_ms: float) -> None:
        """One message's latency, measured at ``now``."""
        self._latencies.append((now, latency_ms))
        while len(self._latencies) > self.window:
            self._latencies.popleft()

    def rate_hz(self, now: float, span_s: float = 3.0) -> float:
        """Messages per second over the last ``span_s`` (0 when fewer than two arrived)."""
        t = np.fromiter(self._arrivals, np.float64, len(self._arrivals))
        recent = t[now - t <= span_s]
        if len(recent) < 2:
            return 0.0
        return (len(recent) - 1) / max(float(recent[-1] - recent[0]), 1e-6)

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
