"""Colour and depth paired by stamp (common/runtime/pairing.py), as the ROS 2 node pairs a live
camera's topics (arrival time, a queue) and replay pairs a recording's (its own stamps, the end)."""

from __future__ import annotations

from common.runtime.pairing import Pair, StampPairer

MS = 1_000_000


def test_a_live_camera_waits_for_the_nearest_depth_and_releases_stragglers() -> None:
    p: StampPairer[str, str] = StampPairer(20 * MS, wait_s=0.5, queue=2)
    p.add_depth(90 * MS, "d90")
    p.add_colour(100 * MS, "c100", now=0.0)
    assert p.ready(0.0) == []  # a nearer depth image may still come
    p.add_depth(103 * MS, "d103")
    assert p.ready(0.01) == [Pair(100 * MS, "c100", "d103")]
    assert p.stale_depth == 1  # d90: nearer ones were taken
    p.add_colour(200 * MS, "c200", now=0.02)
    p.add_depth(260 * MS, "d260")
    (pair,) = p.ready(0.03)
    assert pair.depth is None and pair.why == "no_depth_near"
    p.add_colour(300 * MS, "c300", now=0.04)
    assert p.ready(0.1) == []
    (pair,) = p.ready(0.6)  # waited 0.5 s: d260 is too old for it
    assert pair.depth is None and pair.why == "no_depth"
    assert (p.paired, p.unpaired) == (1, 2)


def test_a_colour_image_that_waited_still_takes_a_near_depth_that_came_before_it() -> None:
    p: StampPairer[str, str] = StampPairer(20 * MS, wait_s=0.5)
    p.add_depth(95 * MS, "d95")
    p.add_colour(100 * MS, "c100", now=0.0)
    assert p.ready(0.4) == []
    assert p.ready(0.5) == [Pair(100 * MS, "c100", "d95")]  # no later depth came: the near earlier one


def test_a_full_queue_releases_the_oldest_colour_image() -> None:
    p: StampPairer[str, str] = StampPairer(20 * MS, wait_s=10.0, queue=2)
    for k in range(3):
        p.add_colour(k * 100 * MS, f"c{k}")
    assert p.ready() == [Pair(0, "c0", None, "no_depth")]


def test_depth_out_of_order_is_kept_in_stamp_order_and_bounded() -> None:
    p: StampPairer[str, str] = StampPairer(20 * MS, depth_queue=2)
    p.add_depth(110 * MS, "d110")
    p.add_depth(101 * MS, "d101")
    p.add_colour(100 * MS, "c100")
    assert p.ready() == [Pair(100 * MS, "c100", "d101")]
    p.add_depth(300 * MS, "d300")
    p.add_depth(400 * MS, "d400")
    assert p.stale_depth == 1  # the third kept pushed the oldest out


def test_a_recording_picks_the_nearest_depth_within_tolerance() -> None:
    p: StampPairer[str, str] = StampPairer(10 * MS, hold_ns=1000 * MS)
    p.add_colour(100 * MS, "rgb0")
    p.add_depth(95 * MS, "d-5")
    assert p.ready() == []  # before: a nearer one may still come
    p.add_depth(102 * MS, "d+2")
    assert p.ready() == [Pair(100 * MS, "rgb0", "d+2")]
    assert p.stale_depth == 1


def test_a_recording_without_a_depth_in_tolerance_gives_colour_alone() -> None:
    p: StampPairer[str, str] = StampPairer(10 * MS, hold_ns=1000 * MS)
    p.add_colour(100 * MS, "rgb0")
    p.add_depth(150 * MS, "far")
    assert p.ready() == [Pair(100 * MS, "rgb0", None, "no_depth_near")]
    p.add_colour(149 * MS, "rgb1")
    assert p.ready() == [Pair(149 * MS, "rgb1", "far")]
    assert (p.paired, p.unpaired) == (1, 1)


def test_the_end_of_a_recording_releases_everything() -> None:
    p: StampPairer[str, str] = StampPairer(10 * MS, hold_ns=1000 * MS)
    p.add_depth(100 * MS, "d0")
    p.add_colour(101 * MS, "rgb0")
    assert p.ready() == []
    p.add_depth(500 * MS, "d-unused")
    assert p.ready(final=True) == [Pair(101 * MS, "rgb0", "d0")]
    assert p.stale_depth == 1 and not len(p)


def test_a_recording_gives_up_on_missing_depth_after_the_hold_time() -> None:
    p: StampPairer[str, str] = StampPairer(10 * MS, hold_ns=300 * MS)
    out = []
    for i in range(5):
        p.add_colour(i * 100 * MS, f"rgb{i}")
        out += p.ready()
    assert [(x.stamp_ns, x.depth, x.why) for x in out] == [(0, None, "no_depth")]
    assert [x.stamp_ns for x in p.ready(final=True)] == [100 * MS, 200 * MS, 300 * MS, 400 * MS]


def test_without_a_depth_stream_each_colour_image_goes_at_once() -> None:
    p: StampPairer[str, str] = StampPairer(expect_depth=False)
    p.add_colour(5, "a")
    assert p.ready() == [Pair(5, "a", None, "no_depth_stream")]
