"""The in-memory transport: same delivery semantics as Zenoh, without a router."""

from __future__ import annotations

import threading

import msgpack
import pytest

from common.messages.keys import FRAMES, RELIABLE, Delivery, Keys
from common.transport.memory import MemoryBus, key_matches
from common.runtime.service import Counters, ServiceRuntime
from common.messages.samples import example_messages, rgbd_frame
from common.messages.schemas import Detections, RGBDFrame, ServiceStatus, Tracks
from common.transport.base import wait_any

KEYS = Keys(robot="r1")
DETS = next(m for m in example_messages() if isinstance(m, Detections))


@pytest.mark.parametrize(
    ("pattern", "key", "expected"),
    [
        ("a/b/c", "a/b/c", True),
        ("a/*/c", "a/b/c", True),
        ("a/*", "a/b/c", False),
        ("a/**", "a/b/c", True),
        ("a/**/c", "a/c", True),
        ("a/**/c", "a/x/y/c", True),
        ("**", "a", True),
        ("a/b", "a/b/c", False),
    ],
)
def test_key_matching(pattern: str, key: str, expected: bool) -> None:
    assert key_matches(pattern, key) is expected


def test_fifo_delivers_in_order_and_counts_overflow(memory_bus: MemoryBus) -> None:
    a, b = memory_bus.transport(), memory_bus.transport()
    sub = b.subscribe(KEYS.detections("*"), Detections, Delivery(latest=False, queue=3, congestion="block"))
    pub = a.publisher(KEYS.detections("head"), Detections, RELIABLE)
    for seq in range(5):
        pub.put(DETS.model_copy(update={"header": DETS.header.model_copy(update={"seq": seq})}))
    got = [sub.recv(0.1) for _ in range(4)]
    assert [g.msg.header.seq for g in got[:3] if g] == [2, 3, 4]
    assert got[3] is None
    assert sub.stats.received == 5 and sub.stats.dropped == 2
    assert got[0] is not None and got[0].key == KEYS.detections("head")


def test_latest_only_keeps_the_newest_frame(memory_bus: MemoryBus) -> None:
    a, b = memory_bus.transport(), memory_bus.transport()
    sub = b.subscribe(KEYS.frames("head"), RGBDFrame, FRAMES)
    pub = a.publisher(KEYS.frames("head"), RGBDFrame, FRAMES)
    for seq in range(4):
        pub.put(rgbd_frame(16, 12, seq=seq))
    got = sub.recv(0.1)
    assert got is not None and got.msg.header.seq == 3
    assert sub.recv(0.01) is None
    assert sub.stats.dropped == 3


def test_invalid_payload_is_counted_and_skipped(memory_bus: MemoryBus) -> None:
    t = memory_bus.transport()
    sub = t.subscribe(KEYS.tracks(), Tracks, RELIABLE)
    inbox = memory_bus.subscribers[0][1]
    inbox.push(KEYS.tracks(), b"\x00garbage")
    inbox.push(KEYS.tracks(), msgpack.packb({"schema": "perception.Tracks", "version": 9, "body": {}}))
    good = next(m for m in example_messages() if isinstance(m, Tracks))
    t.publisher(KEYS.tracks(), Tracks, RELIABLE).put(good)
    got = sub.recv(0.1)
    assert got is not None and got.msg == good
    assert sub.stats.invalid == 2
    assert sub.last_error is not None and "version 9" in str(sub.last_error)


def test_publisher_rejects_the_wrong_type(memory_bus: MemoryBus) -> None:
    pub = memory_bus.transport().publisher(KEYS.tracks(), Tracks, RELIABLE)
    with pytest.raises(TypeError, match="takes Tracks"):
        pub.put(DETS)  # type: ignore[arg-type]


def test_wait_any_wakes_on_the_first_message(memory_bus: MemoryBus) -> None:
    a, b = memory_bus.transport(), memory_bus.transport()
    s1 = b.subscribe(KEYS.tracks(), Tracks, RELIABLE)
    s2 = b.subscribe(KEYS.detections("head"), Detections, RELIABLE)
    assert not wait_any([s1, s2], b.notify, 0.01)
    timer = threading.Timer(0.05, lambda: a.publisher(KEYS.detections("head"), Detections, RELIABLE).put(DETS))
    timer.start()
    assert wait_any([s1, s2], b.notify, 5.0)
    assert s2.try_recv() is not None and s1.try_recv() is None


def test_subscriber_without_model_accepts_any_message(memory_bus: MemoryBus) -> None:
    a, b = memory_bus.transport(), memory_bus.transport()
    sub = b.subscribe(KEYS.all(), None, RELIABLE)
    for msg in example_messages():
        a.publisher(f"{KEYS.base}/x", type(msg), RELIABLE).put(msg)
    assert [sub.recv(0.1).msg for _ in example_messages()] == example_messages()  # type: ignore[union-attr]


def test_liveliness_status_and_queries(memory_bus: MemoryBus) -> None:
    svc, watcher = memory_bus.transport(), memory_bus.transport()
    events: list[tuple[str, bool]] = []
    watcher.watch_alive(KEYS.alive(), lambda k, alive: events.append((k, alive)))
    counters = Counters()
    runtime = ServiceRuntime("tracker", svc, KEYS, instance="i1", counters=counters, period_s=60)
    sub = svc.subscribe(KEYS.detections("head"), Detections, RELIABLE)
    runtime.watch(sub)
    with runtime:
        assert watcher.alive(KEYS.alive()) == [KEYS.alive("tracker", "i1")]
        watcher.publisher(KEYS.detections("head"), Detections, RELIABLE).put(DETS)
        counters.drop("stale", 2)
        replies = watcher.query(KEYS.status())
        assert len(replies) == 1
        status = replies[0][1]
        assert isinstance(status, ServiceStatus)
        assert (status.name, status.instance, status.received, status.dropped) == ("tracker", "i1", 1, 2)
        assert status.extra["dropped_stale"] == 2
        svc.close()
    assert watcher.alive(KEYS.alive()) == []
    assert events == [(KEYS.alive("tracker", "i1"), True), (KEYS.alive("tracker", "i1"), False)]


def test_puts_without_subscriber_are_counted(memory_bus: MemoryBus) -> None:
    a, b = memory_bus.transport(), memory_bus.transport()
    pub = a.publisher(KEYS.tracks(), Tracks, RELIABLE)
    good = next(m for m in example_messages() if isinstance(m, Tracks))
    pub.put(good)
    b.subscribe(KEYS.tracks(), Tracks, RELIABLE)
    pub.put(good)
    assert (pub.published, pub.unmatched) == (2, 1)
    runtime = ServiceRuntime("tracker", a, KEYS, instance="i1")
    runtime.watch(pub)
    assert runtime.status().extra["published_unmatched"] == 1


def test_closing_stops_delivery(memory_bus: MemoryBus) -> None:
    a, b = memory_bus.transport(), memory_bus.transport()
    sub = b.subscribe(KEYS.tracks(), Tracks, RELIABLE)
    pub = a.publisher(KEYS.tracks(), Tracks, RELIABLE)
    assert pub.has_subscribers()
    b.close()
    assert not pub.has_subscribers()
    assert sub.recv(0.01) is None
