"""Watch a live system for the doctor: every stream of the robot, the services' status and
liveliness, for a given time."""

from __future__ import annotations

import os
import time
from typing import Any

from common.messages.keys import RELIABLE, Delivery, Keys
from common.messages.schemas import ServiceStatus
from common.transport.base import Subscription, Transport, wait_any
from services.ros2.core.wire import ADMIN_SPACE
from tools.doctor.collect import Observer

__all__ = ["watch"]

#: Frames are big: a short FIFO, drained continuously, whose overflow is only a lost sample.
FRAMES_FIFO = Delivery(latest=False, queue=16, congestion="drop")


def _query_status(transport: Transport, keys: Keys, observer: Observer, timeout: float) -> None:
    for _, msg in transport.query(keys.status(), timeout=timeout):
        if isinstance(msg, ServiceStatus):
            observer.status(msg)


def watch(transport: Transport, keys: Keys, duration_s: float, observer: Observer, *,
          query_timeout_s: float = 1.0) -> float:
    """Feed ``observer`` for ``duration_s`` seconds; returns the time actually watched (s).

    The services' statuses are asked for at the start and at the end, so their counters'
    changes cover the time watched; liveliness is followed throughout.
    """
    subs: list[Subscription[Any]] = [
        transport.subscribe(keys.frames("*"), None, FRAMES_FIFO),
        transport.subscribe(keys.scans("*"), None, FRAMES_FIFO),
        *(transport.subscribe(key, None, RELIABLE) for key in (
            keys.detections("*"), keys.localized("*"), keys.embeddings("*"), keys.tracks(), keys.tf(),
            keys.tf_static(), keys.status())),
    ]

    def on_alive(key: str, alive: bool) -> None:
        try:
            service, instance = keys.parse_alive(key)
        except ValueError:
            return
        observer.liveliness(service, instance, alive)

    unwatch = transport.watch_alive(keys.alive(), on_alive)
    try:
        _query_status(transport, keys, observer, query_timeout_s)
        start = time.monotonic()
        deadline = start + duration_s
        while (left := deadline - time.monotonic()) > 0:
            wait_any(subs, transport.notify, min(0.1, left))
            _drain(subs, observer)
        watched = time.monotonic() - start
        _drain(subs, observer)
        _query_status(transport, keys, observer, query_timeout_s)
        _ros2_graph(transport, observer, query_timeout_s)
        observer.others(keys.base, transport.alive("**/perception/v1/alive/*/*", timeout=query_timeout_s))
        return watched
    finally:
        unwatch()
        for sub in subs:
            sub.close()


def _ros2_graph(transport: Transport, observer: Observer, timeout: float) -> None:
    """The ROS 2 graph of the ros2 node's domain (else $ROS_DOMAIN_ID, else 0) on the router."""
    env = os.environ.get("ROS_DOMAIN_ID", "0")
    domain = observer.ros2_domain_to_watch(int(env) if env.isdigit() else 0)
    observer.ros2_graph(domain, transport.alive(f"{ADMIN_SPACE}/{domain}/**", timeout=timeout))


def _drain(subs: list[Subscription[Any]], observer: Observer) -> None:
    for sub in subs:
        while (got := sub.try_recv_raw()) is not None:
            observer.payload(*got)
