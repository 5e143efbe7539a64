"""What every running service shares: shutdown on signals, counters, health reporting."""

from __future__ import annotations

import logging
import os
import re
import signal
import socket
import threading
import time
from dataclasses import dataclass, field
from types import FrameType
from typing import Any

from common.messages.keys import STATUS, Keys
from common.messages.schemas import Header, ServiceStatus
from common.transport.base import BasePublisher, BaseSubscription, Transport

__all__ = ["Counters", "ServiceRuntime", "Shutdown", "instance_id", "package_version"]

log = logging.getLogger(__name__)


def package_version() -> str:
    from importlib.metadata import PackageNotFoundError, version

    try:
        return version("people-perception")
    except PackageNotFoundError:
        return "0+unknown"


def instance_id(pid: int | None = None) -> str:
    """``host-pid`` (this process's pid by default), usable as one key chunk."""
    return re.sub(r"[^A-Za-z0-9_.-]", "_", f"{socket.gethostname()}-{os.getpid() if pid is None else pid}")


class Shutdown:
    """A stop flag set by SIGINT/SIGTERM while in its ``with`` block.

    The handlers only set the flag, so the main loop can close subscribers and then the
    Zenoh session in order; an unclosed session would keep the process alive. A second
    signal while stopping raises ``KeyboardInterrupt`` as a last resort.
    """

    def __init__(self) -> None:
        self.event = threading.Event()
        self._previous: dict[int, Any] = {}

    def _handle(self, signum: int, frame: FrameType | None) -> None:
        if self.event.is_set():
            raise KeyboardInterrupt
        log.info("received %s, shutting down", signal.Signals(signum).name)
        self.event.set()

    def __enter__(self) -> Shutdown:
        if threading.current_thread() is threading.main_thread():
            for sig in (signal.SIGINT, signal.SIGTERM):
                self._previous[sig] = signal.signal(sig, self._handle)
        return self

    def __exit__(self, *exc: object) -> None:
        for sig, handler in self._previous.items():
            signal.signal(sig, handler)
        self._previous.clear()

    def is_set(self) -> bool:
        return self.event.is_set()

    def set(self) -> None:
        self.event.set()

    def wait(self, timeout: float | None = None) -> bool:
        """Sleep until stopped or ``timeout`` s pass (in slices, so signals get through)."""
        deadline = None if timeout is None else time.monotonic() + timeout
        while not self.event.is_set():
            remaining = 0.2 if deadline is None else min(0.2, deadline - time.monotonic())
            if remaining <= 0:
                break
            self.event.wait(remaining)
        return self.event.is_set()


@dataclass
class Counters:
    """A service's own counts, beyond what its subscriptions and publishers count.

    ``dropped``/``invalid`` are for inputs the service itself discards (stale, unpaired,
    missing transform, rejected); ``extra`` holds named counters and gauges.
    """

    dropped: int = 0
    invalid: int = 0
    extra: dict[str, float] = field(default_factory=dict)
    _lock: threading.Lock = field(default_factory=threading.Lock, repr=False)

    def count(self, name: str, n: float = 1) -> None:
        with self._lock:
            self.extra[name] = self.extra.get(name, 0) + n

    def gauge(self, name: str, value: float) -> None:
        with self._lock:
            self.extra[name] = value

    def drop(self, reason: str, n: int = 1) -> None:
        with self._lock:
            self.dropped += n
            self.extra[f"dropped_{reason}"] = self.extra.get(f"dropped_{reason}", 0) + n


class ServiceRuntime:
    """Liveliness token, periodic :class:`ServiceStatus` and a status queryable.

    Received/dropped/invalid sum the subscriptions' stats and the service's
    :class:`Counters`; published sums the publishers. The status also lists the keys
    subscribed and published, and the ``settings`` it was given. A node passes its ``io``
    (:class:`common.runtime.node.NodeIO`), whose declared subscriptions and publishers are read
    live; tools without a node add theirs with :meth:`watch`.
    """

    def __init__(self, name: str, transport: Transport, keys: Keys, *, period_s: float = 1.0,
                 instance: str | None = None, counters: Counters | None = None, io: Any = None,
                 settings: dict[str, str] | None = None) -> None:
        self.name = name
        #: The service's settings as text, reported in every status (:func:`common.runtime.node.settings_summary`).
        self.settings = dict(settings or {})
        self.instance = instance or instance_id()
        self.transport = transport
        self.keys = keys
        self.period_s = period_s
        self.counters = counters if counters is not None else Counters()
        self.subscriptions: list[BaseSubscription] = io.subscriptions if io is not None else []
        self.publishers: list[BasePublisher] = io.publishers if io is not None else []
        self._started = time.monotonic()
        self._stop = threading.Event()
        self._thread: threading.Thread | None = None
        self._version = package_version()
        self._host = socket.gethostname()

    def watch(self, *items: BaseSubscription | BasePublisher) -> None:
        for item in items:
            (self.subscriptions if isinstance(item, BaseSubscription) else self.publishers).append(item)

    def status(self) -> ServiceStatus:
        c = self.counters
        with c._lock:
            extra = dict(c.extra)
            dropped, invalid = c.dropped, c.invalid
        unmatched = sum(p.unmatched for p in self.publishers)
        if unmatched:
            extra["published_unmatched"] = unmatched
        return ServiceStatus(
            header=Header(stamp_ns=time.time_ns(), source=self.name),
            name=self.name,
            instance=self.instance,
            host=self._host,
            pid=os.getpid(),
            version=self._version,
            uptime_s=time.monotonic() - self._started,
            received=sum(s.stats.received for s in self.subscriptions),
            published=sum(p.published for p in self.publishers),
            dropped=dropped + sum(s.stats.dropped for s in self.subscriptions),
            invalid=invalid + sum(s.stats.invalid for s in self.subscriptions),
            extra=extra,
            subscribes=sorted({s.key for s in self.subscriptions}),
            publishes=sorted({p.key for p in self.publishers}),
            settings=self.settings,
        )

    def start(self) -> None:
        key = self.keys.status(self.name, self.instance)
        self._status_pub = self.transport.publisher(key, ServiceStatus, STATUS)
        self.transport.serve(key, lambda _key, _params: [self.status()])
        self.transport.declare_token(self.keys.alive(self.name, self.instance))
        self._thread = threading.Thread(target=self._loop, name=f"{self.name}-status", daemon=True)
        self._thread.start()
        log.info("%s started as %s", self.name, self.instance)

    def _loop(self) -> None:
        while not self._stop.wait(self.period_s):
            if self.transport.closed:
                return
            self._status_pub.put(self.status())

    def stop(self) -> None:
        self._stop.set()
        if self._thread is not None:
            # the transport closes next: a thread still inside a Zenoh put then, or at interpreter
            # exit, can abort the process; a put drops rather than blocks (STATUS), so this is quick
            self._thread.join(timeout=10.0)
            if self._thread.is_alive():
                log.warning("%s: the status thread did not stop", self.name)

    def __enter__(self) -> ServiceRuntime:
        self.start()
        return self

    def __exit__(self, *exc: object) -> None:
        self.stop()
