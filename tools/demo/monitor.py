"""A live view of the pipeline: confirmed tracks, frame rate and latency per stage.

The monitor is an ordinary subscriber: it listens to each stage's output and measures the
age of every message against its source frame's sensor stamp (``now - header.stamp_ns``),
which is the latency from the camera to that stage. All processes run on one host in the
demo, so the clocks agree.
"""

from __future__ import annotations

import threading
import time
from collections import deque
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from common.messages import schemas
from common.messages.keys import STATUS, Delivery, Keys, stream
from common.messages.registry import pipeline
from common.messages.schemas import Message, ServiceStatus, Tracks
from common.transport.base import Subscription, Transport

__all__ = ["STAGES", "Monitor", "StageStats"]

#: (stage name, key method, message type), in pipeline order: each stage of the registry and
#: the stream it publishes (the :class:`~common.messages.keys.Keys` method of the same name).
STAGES: tuple[tuple[str, str, type[Message]], ...] = tuple(
    (n.name, n.publishes[0], getattr(schemas, stream(n.publishes[0]).message)) for n in pipeline())
_WINDOW = 300


@dataclass
class StageStats:
    """Recent latencies (ms) and arrival times of one stage's messages."""

    latencies_ms: deque[float] = field(default_factory=lambda: deque(maxlen=_WINDOW))
    arrivals: deque[float] = field(default_factory=lambda: deque(maxlen=_WINDOW))
    count: int = 0

    def add(self, latency_ms: float, now: float) -> None:
        self.latencies_ms.append(latency_ms)
        self.arrivals.append(now)
        self.count += 1

    def rate_hz(self, now: float, span_s: float = 3.0) -> float:
        recent = [t for t in self.arrivals if now - t <= span_s]
        if len(recent) < 2:
            return 0.0
        return (len(recent) - 1) / max(recent[-1] - recent[0], 1e-6)

    def percentile(self, q: float) -> float | None:
        return float(np.percentile(list(self.latencies_ms), q)) if self.latencies_ms else None


class Monitor:
    """Subscribes to every stage of one camera and keeps the numbers the live view shows."""

    def __init__(self, transport: Transport, keys: Keys, camera: str = "head") -> None:
        self.keys = keys
        self.stats = {name: StageStats() for name, _, _ in STAGES}
        self.latest_tracks: Tracks | None = None
        self.all_tracks: list[Tracks] = []
        self.statuses: dict[str, ServiceStatus] = {}
        self._lock = threading.Lock()
        self._subs: list[tuple[str, Subscription[Any]]] = []
        for name, method, model in STAGES:
            key = getattr(keys, method)() if method == "tracks" else getattr(keys, method)(camera)
            self._subs.append((name, transport.subscribe(key, model, Delivery(latest=False, queue=1024, congestion="block"))))
        self._status = transport.subscribe(keys.status(), ServiceStatus, STATUS)
        self.transport = transport

    def poll(self) -> None:
        """Take in everything that arrived since the last call."""
        now = time.time()
        for name, sub in self._subs:
            while (got := sub.try_recv()) is not None:
                msg = got.msg
                with self._lock:
                    self.stats[name].add((got.recv_ns - msg.header.stamp_ns) / 1e6, now)
                    if isinstance(msg, Tracks):
                        self.latest_tracks = msg
                        self.all_tracks.append(msg)
        while (st := self._status.try_recv()) is not None:
            self.statuses[st.msg.name] = st.msg

    def summary(self) -> dict[str, dict[str, float | None]]:
        """Per stage: messages, mean rate over the run, latency p50/p95 (ms) from the frame stamp."""
        out: dict[str, dict[str, float | None]] = {}
        for name, s in self.stats.items():
            span = (s.arrivals[-1] - s.arrivals[0]) if len(s.arrivals) > 1 else 0.0
            out[name] = {
                "messages": float(s.count),
                "rate_hz": (len(s.arrivals) - 1) / span if span > 0 else None,
                "latency_p50_ms": s.percentile(50),
                "latency_p95_ms": s.percentile(95),
            }
        return out

    def render(self, title: str = "", elapsed_s: float | None = None) -> str:
        """The live view as text (no terminal control codes)."""
        now = time.time()
        lines = []
        if title:
            lines.append(title)
        tracker = self.stats["tracker"]
        head = f"tracks published at {tracker.rate_hz(now):5.1f} Hz"
        if elapsed_s is not None:
            head += f"   elapsed {elapsed_s:6.1f} s"
        lines += [head, ""]
        lines.append(f"{'stage':<10} {'msgs':>6} {'rate Hz':>8} {'latency p50':>12} {'p95':>8}   service counters")
        for name, _, _ in STAGES:
            s = self.stats[name]
            p50, p95 = s.percentile(50), s.percentile(95)
            lat = f"{p50:9.1f} ms {p95:6.1f} ms" if p50 is not None and p95 is not None else f"{'-':>12} {'-':>8}"
            st = self.statuses.get(name)
            counters = (f"recv {st.received} pub {st.published} drop {st.dropped} inval {st.invalid}"
                        if st else "(no status yet)")
            lines.append(f"{name:<10} {s.count:>6} {s.rate_hz(now):>8.1f} {lat}   {counters}")
        lines.append("")
        tracks = self.latest_tracks
        if tracks is None:
            lines.append("no tracks yet")
        else:
            mode = "appearance + position" if tracks.appearance_available else "POSITION ONLY (no embeddings)"
            lines.append(f"confirmed tracks: {len(tracks.tracks)}   association: {mode}")
            lines.append(f"{'ID':>4} {'x (m)':>7} {'y (m)':>7} {'z (m)':>6} {'speed':>6} {'state':<10} {'hits':>5} {'age s':>6}")
            for t in sorted(tracks.tracks, key=lambda t: t.id):
                speed = float(np.hypot(t.velocity[0], t.velocity[1]))
                lines.append(f"{t.id:>4} {t.position[0]:>7.2f} {t.position[1]:>7.2f} {t.position[2]:>6.2f} {speed:>6.2f} "
                             f"{t.status:<10} {t.hits:>5} {t.age_s:>6.1f}")
        return "\n".join(lines)
