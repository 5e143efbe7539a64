"""Subscriptions read on the reader's schedule (``Delivery(wake=False)``) over a real router:
samples wait in Zenoh's ring, the newest ``queue`` of them, and arrive in order with the
router's timestamp as their arrival time."""

from __future__ import annotations

import time
from typing import Callable

from common.messages.keys import RELIABLE, Delivery, Keys
from common.messages.schemas import Header, ServiceStatus
from common.transport.zenoh import ZenohTransport
from tests.helpers.wait import wait_until

KEYS = Keys(robot="polled")


def _status(seq: int) -> ServiceStatus:
    return ServiceStatus(header=Header(stamp_ns=time.time_ns(), source="t", seq=seq), name="tracker", instance="a")


def test_a_polled_subscription_keeps_the_newest_samples_in_order(zenoh_client: Callable[[], ZenohTransport]) -> None:
    pub_side, sub_side = zenoh_client(), zenoh_client()
    key = KEYS.status("tracker", "a")
    polled = sub_side.subscribe(key, ServiceStatus, Delivery(latest=False, queue=3, congestion="drop", wake=False))
    woken = sub_side.subscribe(key, ServiceStatus, RELIABLE)
    pub = pub_side.publisher(key, ServiceStatus, RELIABLE)
    assert pub.wait_for_subscribers(10)
    before = time.time_ns()
    for seq in range(5):
        pub.put(_status(seq))
    wait_until(lambda: woken.stats.received >= 5, 10.0, what="the pushed subscription to get the 5 samples")
    assert woken.stats.received == 5
    assert polled.pending() == 0  # nothing was pushed: it waits inside Zenoh
    got = []
    while (r := polled.try_recv()) is not None:
        got.append(r)
    assert [r.msg.header.seq for r in got] == [2, 3, 4]  # the ring kept the newest three
    assert all(before - 1_000_000_000 < r.recv_ns < time.time_ns() + 1_000_000_000 for r in got)
    assert polled.stats.received == 3
    pub.put(_status(5))

    def taken():  # type: ignore[no-untyped-def]
        newest, arrivals = polled.take_newest()
        return (newest, arrivals) if newest is not None else None

    newest, arrivals = wait_until(taken, 10.0, what="the polled subscription to hold the new sample")
    assert newest.msg.header.seq == 5 and len(arrivals) == 1
