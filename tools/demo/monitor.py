"""A live view of the pipeline: the tracks by state, frame rate and latency per stage.

The monitor is an ordinary subscriber: it listens to each stage's output and measures the
age of every message against its source frame's sensor stamp (``recv - header.stamp_ns``),
which is the latency from the camera to that stage. All processes run on one host in the
demo, so the clocks agree. Rates and latencies come from the operator page's meter
(:class:`~tools.drawing.meters.StageMeter`, fed with the transport's receive stamps), so the
table and the page show the same numbers. Everything it renders fits :data:`~tools.demo.text.WIDTH` columns.
"""

from __future__ import annotations

import threading
import time
from typing import Any

import numpy as np

from common.messages import schemas
from common.messages.keys import STATUS, Delivery, Keys, stream
from common.messages.registry import pipeline
from common.messages.schemas import Message, ServiceStatus, Tracks
from common.transport.base import Subscription, Transport
from tools.demo.text import wrap
from tools.drawing.meters import StageMeter

__all__ = ["STAGES", "Monitor"]

#: (stage name, key method, message type), in pipeline order: each stage of the registry and
#: the stream it publishes (the :class:`~common.messages.keys.Keys` method of the same name).
STAGES: tuple[tuple[str, str, type[Message]], ...] = tuple(
    (n.name, n.publishes[0], getattr(schemas, stream(n.publishes[0]).message)) for n in pipeline())
#: The states a track is listed under, in this order.
_STATES = ("confirmed", "coasting", "tentative")


class Monitor:
    """Subscribes to every stage of one camera and keeps the numbers the live view shows."""

    def __init__(self, transport: Transport, keys: Keys, camera: str = "head") -> None:
        self.keys = keys
        self.meters = {name: StageMeter() for name, _, _ in STAGES}
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
        for name, sub in self._subs:
            while (got := sub.try_recv()) is not None:
                self.record(name, got.msg, got.recv_ns)
        while (st := self._status.try_recv()) is not None:
            self.statuses[st.msg.name] = st.msg

    def record(self, stage: str, msg: Message, recv_ns: int) -> None:
        """One message of ``stage``, received at ``recv_ns`` (wall clock, ns)."""
        with self._lock:
            t = recv_ns / 1e9
            self.meters[stage].add(t, (recv_ns - msg.header.stamp_ns) / 1e6)
            if isinstance(msg, Tracks):
                self.latest_tracks = msg
                self.all_tracks.append(msg)

    def summary(self) -> dict[str, dict[str, float | None]]:
        """Per stage: messages, mean rate over the run, latency p50/p95 (ms) from the frame stamp
        (of the last few hundred messages)."""
        out: dict[str, dict[str, float | None]] = {}
        for name, m in self.meters.items():
            end = m.last_at or 0.0
            out[name] = {
                "messages": float(m.count),
                "rate_hz": m.mean_rate_hz(),
                "latency_p50_ms": m.latency_ms(50, end, span_s=float("inf")),
                "latency_p95_ms": m.latency_ms(95, end, span_s=float("inf")),
            }
        return out

    def render_summary(self) -> str:
        """Each stage over the whole run: messages, mean rate, latency p50/p95 (what ``--json``'s
        ``pipeline`` holds), at most :data:`~tools.demo.text.WIDTH` columns."""
        rows = ["the pipeline over the run",
                f"{'stage':<10} {'msgs':>6} {'rate Hz':>7} {'p50 ms':>7} {'p95 ms':>7}"]
        for name, numbers in self.summary().items():
            rate = numbers["rate_hz"]
            rows.append(f"{name:<10} {int(numbers['messages'] or 0):>6} {_rate(rate)} "
                        f"{_ms(numbers['latency_p50_ms'])} {_ms(numbers['latency_p95_ms'])}")
        return "\n".join(rows)

    def render(self, title: str = "", elapsed_s: float | None = None, now: float | None = None) -> str:
        """The live view as text (no terminal control codes), at most :data:`~tools.demo.text.WIDTH` columns.

        ``now``: the wall clock (s) the rates are computed at (default: the current time).
        """
        now = time.time() if now is None else now
        lines = [title] if title else []
        head = f"tracks published at {self.meters['tracker'].rate_hz(now):5.1f} Hz"
        if elapsed_s is not None:
            head += f"   elapsed {elapsed_s:6.1f} s"
        lines += [head, "", self._stage_table(now), ""]
        lines += self._track_lines()
        return wrap("\n".join(lines))

    def _stage_table(self, now: float) -> str:
        """Each stage's messages, rate and latency (last 3 s / 10 s, as the page), and its counters."""
        rows = [f"{'stage':<10} {'msgs':>6} {'rate Hz':>7} {'p50 ms':>7} {'p95 ms':>7} "
                f"{'recv':>6} {'pub':>6} {'drop':>5} {'inval':>5}"]
        for name, _, _ in STAGES:
            m = self.meters[name]
            p50, p95 = m.latency_ms(50, now), m.latency_ms(95, now)
            st = self.statuses.get(name)
            counters = (f"{st.received:>6} {st.published:>6} {st.dropped:>5} {st.invalid:>5}" if st
                        else f"{'(no status yet)':>24}")
            rows.append(f"{name:<10} {m.count:>6} {m.rate_hz(now):>7.1f} {_ms(p50)} {_ms(p95)} {counters}")
        return "\n".join(rows)

    def _track_lines(self) -> list[str]:
        tracks = self.latest_tracks
        if tracks is None:
            return ["no tracks yet"]
        mode = "appearance + position" if tracks.appearance_available else "POSITION ONLY (no embeddings)"
        lines = [f"tracks: {len(tracks.tracks)}   association: {mode}"]
        for state in _STATES:
            of_state = sorted((t for t in tracks.tracks if t.status == state), key=lambda t: t.id)
            if not of_state:
                continue
            lines += ["", f"{state} ({len(of_state)})",
                      f"{'ID':>4} {'x (m)':>7} {'y (m)':>7} {'z (m)':>6} {'speed (m/s)':>11} {'hits':>5} {'age (s)':>7}"]
            for t in of_state:
                speed = float(np.hypot(t.velocity[0], t.velocity[1]))
                lines.append(f"{t.id:>4} {t.position[0]:>7.2f} {t.position[1]:>7.2f} {t.position[2]:>6.2f} "
                             f"{speed:>11.2f} {t.hits:>5} {t.age_s:>7.1f}")
        return lines


def _rate(value: float | None) -> str:
    return f"{value:>7.1f}" if value is not None else f"{'-':>7}"


def _ms(value: float | None) -> str:
    return f"{value:>7.1f}" if value is not None else f"{'-':>7}"
