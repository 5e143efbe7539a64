"""Publish a :class:`~tools.replay.sources.Source` onto a transport, with its timing.

Works on any :class:`~common.transport.base.Transport` (the in-memory one in tests). Items
are put into stamp order (:func:`~tools.replay.core.timeline.reorder`), paced by a
:class:`~tools.replay.core.timeline.Pacer` and published on their key, remapped.
Static transforms are always published, even before ``--start``, since the services
need them whatever part of the file is replayed.
"""

from __future__ import annotations

import dataclasses
import logging
import time
from collections import Counter
from dataclasses import dataclass, field
from typing import Any, Iterator, Protocol, Sequence

from common.messages.keys import FRAMES, RELIABLE, SCANS, STATUS, Delivery
from common.messages.schemas import LaserScan, RGBDFrame, ServiceStatus
from common.transport.base import Publisher, Transport
from tools.replay.core.mapping import remap_key
from tools.replay.core.timeline import DEFAULT_REORDER_WINDOW_NS, Pacer, Reorderer, TimeWindow
from tools.replay.progress import Progress
from tools.replay.sources import Item, Source, SourceError

__all__ = ["ReplayOptions", "ReplayStats", "Replayer", "StopFlag"]

log = logging.getLogger(__name__)


class StopFlag(Protocol):
    def is_set(self) -> bool: ...

    def wait(self, timeout: float | None = None) -> bool: ...


@dataclass
class ReplayOptions:
    """``rate=None`` replays as fast as the subscribers keep up (``--max``)."""

    rate: float | None = 1.0
    loop: bool = False
    window: TimeWindow = field(default_factory=TimeWindow)
    remap: Sequence[tuple[str, str]] = ()
    wait_subscribers_s: float = 2.0
    reorder_window_ns: int = DEFAULT_REORDER_WINDOW_NS


@dataclass
class ReplayStats:
    published: Counter[str] = field(default_factory=Counter)
    bytes: int = 0
    elapsed_s: float = 0.0
    passes: int = 0
    late: int = 0

    @property
    def total(self) -> int:
        return sum(self.published.values())


def delivery_for(model: type, as_fast_as_possible: bool) -> Delivery:
    """The live stream's delivery; ``--max`` makes every publisher block on congestion."""
    base = {RGBDFrame: FRAMES, ServiceStatus: STATUS, LaserScan: SCANS}.get(model, RELIABLE)
    return dataclasses.replace(base, congestion="block") if as_fast_as_possible else base


class Replayer:
    """Replays one source; ``run`` returns when the file (or ``--end``) is done or on stop."""

    def __init__(self, transport: Transport, source: Source, options: ReplayOptions,
                 progress: Progress | None = None) -> None:
        self.transport = transport
        self.source = source
        self.options = options
        self.progress = progress
        self.stats = ReplayStats()
        self._pubs: dict[str, Publisher[Any]] = {}
        for key, model in source.streams().items():
            self._publisher(key, model)

    @property
    def publishers(self) -> list[Publisher[Any]]:
        return list(self._pubs.values())

    def _publisher(self, key: str, model: type) -> Publisher[Any]:
        pub = self._pubs.get(key)
        if pub is None:
            target = remap_key(key, self.options.remap)
            pub = self._pubs[key] = self.transport.publisher(target, model, delivery_for(model, self.options.rate is None))
            if target != key:
                log.info("remapping %s -> %s", key, target)
        return pub

    def wait_for_subscribers(self, stop: StopFlag) -> None:
        """Wait until every stream has a subscriber, up to ``wait_subscribers_s``."""
        deadline = time.monotonic() + self.options.wait_subscribers_s
        while not stop.is_set() and time.monotonic() < deadline:
            if all(p.has_subscribers() for p in self._pubs.values()):
                return
            stop.wait(0.02)
        missing = [p.key for p in self._pubs.values() if not p.has_subscribers()]
        if missing:
            log.info("no subscriber yet on %s; replaying anyway", ", ".join(missing))

    def run(self, stop: StopFlag) -> ReplayStats:
        self.wait_for_subscribers(stop)
        started = time.monotonic()
        pacer = Pacer(self.options.rate)
        try:
            while not stop.is_set():
                pacer.reset()
                if self.progress is not None:
                    self.progress.restart()
                self._one_pass(pacer, stop)
                self.stats.passes += 1
                if not self.options.loop or self.stats.total == 0:
                    break
        finally:
            self.stats.elapsed_s = time.monotonic() - started
            if self.progress is not None:
                self.progress.close()
        return self.stats

    def _one_pass(self, pacer: Pacer, stop: StopFlag) -> None:
        reorderer: Reorderer[Item] = Reorderer(self.options.reorder_window_ns)
        try:
            self._publish_ordered(reorderer, pacer, stop)
        finally:
            self.stats.late += reorderer.late

    def _publish_ordered(self, reorderer: Reorderer[Item], pacer: Pacer, stop: StopFlag) -> None:
        window = self.options.window
        t0: int | None = None

        def ordered() -> Iterator[tuple[int, Item]]:
            try:
                for it in self.source.items():
                    yield from reorderer.push(it.stamp_ns, it)
            except SourceError:
                yield from reorderer.flush()  # what was read before the damage still goes out
                raise
            yield from reorderer.flush()

        for t_ns, item in ordered():
            if stop.is_set():
                return
            if t0 is None and t_ns > 0:
                t0 = t_ns
            where = window.position(t_ns, t0) if t0 is not None else "before"
            static = item.key.rsplit("/", 1)[-1] == "tf_static"
            if where == "after":
                return
            if where == "before" and not (static or (window.start_s == 0 and t0 is None)):
                continue
            if where == "inside":
                delay = pacer.delay_s(t_ns)
                if delay > 0 and stop.wait(delay):
                    return
            self._publish(item)
            if self.progress is not None and t0 is not None:
                self.progress.update(max(0, t_ns - t0) / 1e9, len(item.encoded()))

    def _publish(self, item: Item) -> None:
        data = item.encoded()
        self._publisher(item.key, item.model).put_encoded(data)
        self.stats.published[item.key] += 1
        self.stats.bytes += len(data)
