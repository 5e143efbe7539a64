"""Pure replay logic: stamp ordering, pacing, time windows, RGB-D pairing, topic mapping."""

from __future__ import annotations

import pytest
from hypothesis import given
from hypothesis import strategies as st

from tools.replay.core.mapping import parse_remap, plan_topics, remap_key
from tools.replay.core.timeline import Pacer, RateMeter, Reorderer, TimeWindow, reorder

MS = 1_000_000
S = 1_000_000_000


class FakeClock:
    def __init__(self) -> None:
        self.now = 5 * S

    def __call__(self) -> int:
        return self.now


# ------------------------------------------------------------------------- reorder


def test_reorder_sorts_items_late_within_the_window() -> None:
    arrivals = [(100, "a"), (300, "c"), (200, "b"), (400, "d"), (250, "x")]
    out = list(reorder(arrivals, window_ns=1000))
    assert [k for k, _ in out] == [100, 200, 250, 300, 400]
    assert [v for _, v in out] == ["a", "b", "x", "c", "d"]


def test_reorder_releases_as_the_window_passes_and_counts_late_items() -> None:
    r: Reorderer[str] = Reorderer(window_ns=10)
    assert r.push(100, "a") == []
    assert r.push(105, "b") == []
    assert r.push(120, "c") == [(100, "a"), (105, "b")]
    assert r.push(101, "late") == [(105, "late")]  # older than what went out: at once, counted
    assert r.late == 1
    assert r.flush() == [(120, "c")]


def test_unstamped_items_follow_the_latest_stamp() -> None:
    out = list(reorder([(0, "static0"), (1000, "a"), (0, "static1"), (2000, "b")], window_ns=10))
    assert [v for _, v in out] == ["static0", "a", "static1", "b"]
    assert out[0][0] == -1 and out[2][0] == 1000


@given(st.lists(st.tuples(st.integers(1, 10_000), st.integers(0, 50)), max_size=60))
def test_reorder_is_sorted_and_lossless_when_lateness_is_within_the_window(data: list[tuple[int, int]]) -> None:
    # arrival times increase; each stamp is at most 50 before its arrival
    items, t = [], 100
    for step, lag in data:
        t += step
        items.append((t - lag, len(items)))
    out = list(reorder(items, window_ns=60))
    assert sorted(v for _, v in out) == list(range(len(items)))
    keys = [k for k, _ in out]
    assert keys == sorted(keys)


# -------------------------------------------------------------------------- pacing


def test_pacer_keeps_the_recorded_gaps_and_scales_them_with_the_rate() -> None:
    for rate, expected in ((1.0, 0.5), (2.0, 0.25), (0.5, 1.0)):
        clock = FakeClock()
        pacer = Pacer(rate, clock)
        assert pacer.delay_s(10 * S) == 0.0  # the first message fixes the origin
        assert pacer.delay_s(10 * S + 500 * MS) == pytest.approx(expected)
        clock.now += int(expected * S) + 1
        assert pacer.delay_s(10 * S + 500 * MS) == 0.0


def test_pacer_never_waits_for_late_messages_or_in_max_mode() -> None:
    clock = FakeClock()
    pacer = Pacer(1.0, clock)
    pacer.delay_s(S)
    clock.now += 3 * S  # fell behind
    assert pacer.delay_s(2 * S) == 0.0
    assert pacer.delay_s(S // 2) == 0.0  # stamped before the origin
    fast = Pacer(None, clock)
    fast.delay_s(S)
    assert fast.delay_s(100 * S) == 0.0


def test_pacer_reset_starts_a_new_origin() -> None:
    clock = FakeClock()
    pacer = Pacer(1.0, clock)
    pacer.delay_s(S)
    clock.now += 10 * S
    pacer.reset()
    assert pacer.delay_s(S) == 0.0
    assert pacer.delay_s(2 * S) == pytest.approx(1.0)


def test_pacer_rejects_a_non_positive_rate() -> None:
    with pytest.raises(ValueError, match="rate"):
        Pacer(0.0)


def test_time_window() -> None:
    w = TimeWindow(1.0, 2.0)
    assert w.position(S + S // 2, S) == "before"
    assert w.position(2 * S + S // 2, S) == "inside"
    assert w.position(3 * S + 1, S) == "after"
    with pytest.raises(ValueError, match="--end"):
        TimeWindow(2.0, 1.0)
    with pytest.raises(ValueError, match="--start"):
        TimeWindow(-1.0)


def test_rate_meter() -> None:
    clock = FakeClock()
    meter = RateMeter(window_s=10.0, clock=clock)
    assert meter.rates() == (0.0, 0.0)
    for _ in range(11):
        meter.add(1000)
        clock.now += 100 * MS
    msgs, bps = meter.rates()
    assert msgs == pytest.approx(10.0, rel=0.01)
    assert bps == pytest.approx(11_000, rel=0.01)


# ------------------------------------------------------------------------- mapping


def test_default_topics_pick_the_preferred_camera_topics() -> None:
    plan = plan_topics(["/camera/rgb/image_raw", "/camera/rgb/image_color", "/camera/depth/image_raw",
                        "/camera/rgb/camera_info", "/tf", "/tf_static", "/odom", "/scan"])
    assert plan.cameras() == {"head": {"rgb": "/camera/rgb/image_color", "depth": "/camera/depth/image_raw",
                                       "camera_info": "/camera/rgb/camera_info"}}
    assert {t: r.role for t, r in plan.routes.items() if not r.camera} == {"/tf": "tf", "/tf_static": "tf_static", "/odom": "odom"}
    assert set(plan.skipped) == {"/camera/rgb/image_raw", "/scan"}
    assert "another rgb topic" in plan.skipped["/camera/rgb/image_raw"]


def test_realsense_defaults() -> None:
    plan = plan_topics(["/camera/color/image_raw", "/camera/aligned_depth_to_color/image_raw", "/camera/color/camera_info"])
    assert plan.cameras()["head"] == {"rgb": "/camera/color/image_raw", "depth": "/camera/aligned_depth_to_color/image_raw",
                                      "camera_info": "/camera/color/camera_info"}


def test_explicit_topics_replace_defaults_and_missing_ones_are_reported() -> None:
    plan = plan_topics(["/front/rgb", "/front/depth", "/front/info", "/tf", "/odom"],
                       cameras={"front": {"rgb": "/front/rgb", "depth": "/front/depth", "camera_info": "/front/info"},
                                "back": {"rgb": "/back/rgb"}},
                       lists={"odom": [], "tf": ["/tf", "/tf_extra"]})
    assert plan.cameras() == {"front": {"rgb": "/front/rgb", "depth": "/front/depth", "camera_info": "/front/info"}}
    assert "not in the bag" in plan.skipped["/back/rgb"] and "not in the bag" in plan.skipped["/tf_extra"]
    assert "/odom" in plan.skipped and plan.routes["/tf"].role == "tf"


def test_remap() -> None:
    rules = [parse_remap("pp/robot=pp/sim"), parse_remap("a/b/c=x")]
    assert remap_key("pp/robot/perception/v1/tf", rules) == "pp/sim/perception/v1/tf"
    assert remap_key("pp/robotic/x", rules) == "pp/robotic/x"
    assert remap_key("a/b/c", rules) == "x"
    for bad in ("nothing", "a=", "a/*=b"):
        with pytest.raises(ValueError, match="OLD=NEW"):
            parse_remap(bad)
