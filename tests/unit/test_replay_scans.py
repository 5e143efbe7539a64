"""Laser scans in replay, record and inspect: the topic map of lasers, bags' sensor_msgs/LaserScan
to LaserScan on scans/{laser}, recordings of the scans/* stream, and what inspect lists."""

from __future__ import annotations

import dataclasses
from pathlib import Path

import numpy as np
import pytest

from common.messages.codec import decode
from common.messages.keys import SCANS, Keys
from common.messages.schemas import Header, LaserScan
from common.runtime.config import ConfigError
from perception.cli import main as cli
from tests.fixtures.scan_bags import ANGLE_INCREMENT, ANGLE_MIN, BEAMS, ranges, stamp, write_scan_bag
from tools.replay.bag_source import BagOptions
from tools.replay.config import load_topic_map
from tools.replay.core.mapping import laser_name, parse_scan_topic, plan_topics
from tools.replay.engine import delivery_for
from tools.replay.recorder import McapRecorder
from tools.replay.sources import open_source

KEYS = Keys()
SCAN_TYPE = "sensor_msgs/msg/LaserScan"


# ------------------------------------------------------------------------------ names


@pytest.mark.parametrize("topic, name", [
    ("/scan", "front"), ("/base_scan", "front"), ("scan", "front"),
    ("/rear_scan", "rear"), ("/scan_rear", "rear"), ("/rear/scan", "rear"), ("right_scan", "right"),
    ("/left_scan", "left"), ("/front/scan", "front"), ("/sick/scan_filtered", "sick_filtered"),
    ("/laser", "laser"), ("/robot 1/scan", "robot_1"),
])
def test_a_laser_is_named_after_its_topic(topic: str, name: str) -> None:
    assert laser_name(topic) == name


def test_scan_topic_flags() -> None:
    assert parse_scan_topic("/scan") == ("/scan", "front")
    assert parse_scan_topic("/left_scan=front") == ("/left_scan", "front")
    assert parse_scan_topic("right_scan") == ("/right_scan", "right")
    for bad in ("", "/", "/scan=", "/scan=a/b", "/scan=a=b", "/scan=*"):
        with pytest.raises(ValueError, match="TOPIC or TOPIC=NAME"):
            parse_scan_topic(bad)


# ------------------------------------------------------------------------------ topic map


def _routes(available: list[str], scans: list[str], lasers: dict[str, str] | None = None) -> dict[str, str]:
    plan = plan_topics(available, lasers=lasers, laser_topics=scans)
    return {t: r.laser for t, r in plan.routes.items() if r.role == "scan"}


def test_every_laser_topic_is_replayed_by_default() -> None:
    assert _routes(["/scan", "/tf"], ["/scan"]) == {"/scan": "front"}
    assert _routes(["/left_scan", "/rear_scan"], ["/left_scan", "/rear_scan"]) == {"/left_scan": "left",
                                                                                   "/rear_scan": "rear"}
    assert _routes(["right_scan"], ["right_scan"]) == {"right_scan": "right"}
    # only topics that carry scans: a /scan of another type is not a laser
    assert _routes(["/scan"], []) == {}


def test_scan_is_front_and_a_name_taken_twice_is_skipped() -> None:
    plan = plan_topics(["/scan", "/base_scan", "/front_scan"], laser_topics=["/scan", "/base_scan", "/front_scan"])
    assert plan.lasers() == {"front": "/scan"}
    assert "fed by /scan already" in plan.skipped["/base_scan"]
    assert "--scan-topic /front_scan=NAME" in plan.skipped["/front_scan"]
    assert _routes(["/base_scan", "/rear_scan"], ["/base_scan", "/rear_scan"]) == {"/base_scan": "front",
                                                                                   "/rear_scan": "rear"}


def test_named_lasers_replace_the_defaults() -> None:
    available = ["/left_scan", "/rear_scan", "right_scan"]
    plan = plan_topics(available, lasers={"front": "/left_scan", "back": "/right_scan", "x": "/missing"},
                       laser_topics=available)
    assert plan.lasers() == {"front": "/left_scan", "back": "right_scan"}  # a ROS 1 relative name matches
    assert plan.skipped["/missing"] == "named for laser 'x' but not in the bag"
    assert "not among the lasers named" in plan.skipped["/rear_scan"]
    assert plan_topics(available, lasers={}, laser_topics=available).lasers() == {}


def test_topic_map_file_and_flags(tmp_path: Path) -> None:
    f = tmp_path / "topics.yaml"
    f.write_text("lasers:\n  front: /scan\n  rear: /rear_scan\n")
    assert load_topic_map(f, "head", {}).lasers == {"front": "/scan", "rear": "/rear_scan"}
    assert load_topic_map(None, "head", {}).lasers is None  # the defaults
    # flags add to the file's, replacing a laser of the same name or topic
    cfg = load_topic_map(f, "head", {"scan": [("/scan", "left"), ("/top_scan", "rear")]})
    assert cfg.lasers == {"left": "/scan", "rear": "/top_scan"}
    with pytest.raises(ConfigError, match="laser 'a' is named for /x and /y"):
        load_topic_map(None, "head", {"scan": [("/x", "a"), ("/y", "a")]})
    for bad, why in (("lasers:\n  a/b: /scan\n", "laser name"), ("lasers:\n  a: scan\n", "must start with '/'"),
                     ("lasers:\n  a: /scan\n  b: /scan\n", "named for lasers 'a' and 'b'")):
        f.write_text(bad)
        with pytest.raises(ConfigError, match=why):
            load_topic_map(f, "head", {})


def test_scans_are_published_as_the_live_stream() -> None:
    assert delivery_for(LaserScan, False) == SCANS
    assert delivery_for(LaserScan, True) == dataclasses.replace(SCANS, congestion="block")


# ------------------------------------------------------------------------------ bags


@pytest.mark.parametrize("kind", ["ros1", "ros2-sqlite3", "ros2-mcap"])
def test_a_bag_s_scans_become_laser_scans(tmp_path: Path, kind: str) -> None:
    bag = write_scan_bag(tmp_path / ("b.bag" if kind == "ros1" else "b"), kind,  # type: ignore[arg-type]
                         {"/scan": "/base_laser", "/rear_scan": "rear_laser"}, n=4)
    with open_source(bag) as src:
        assert src.streams() == {KEYS.scans("front"): LaserScan, KEYS.scans("rear"): LaserScan}
        items = list(src.items())
        assert "/chatter" in src.skipped and not src.problems
    assert [it.key for it in items] == [KEYS.scans(n) for _ in range(4) for n in ("front", "rear")]
    for it in items:
        assert it.model is LaserScan and isinstance(it.message, LaserScan)
        assert it.stamp_ns == it.message.header.stamp_ns and it.log_ns == it.stamp_ns + 2_000_000
    for k, (laser, frame) in enumerate((("front", "base_laser"), ("rear", "rear_laser"))):
        scans = [it.message for it in items if it.key == KEYS.scans(laser)]
        for i, s in enumerate(scans):
            assert s.header == Header(stamp_ns=stamp(i, k * 1_000_000), frame_id=frame, seq=i, source=laser)
            np.testing.assert_array_equal(s.ranges, ranges(i, k))
            np.testing.assert_array_equal(s.intensities, np.full(BEAMS, 100.0 + i, np.float32))
            assert (s.angle_min, s.angle_increment) == pytest.approx((ANGLE_MIN, ANGLE_INCREMENT))
            assert (s.range_min, s.range_max, s.scan_time, s.time_increment) == pytest.approx((0.05, 20.0, 0.1, 1e-5))


def test_scans_equal_what_the_laser_s_own_reader_reads(tmp_path: Path) -> None:
    from services.laser.files import read_scans

    bag = write_scan_bag(tmp_path / "b.bag", topics={"/left_scan": "left_laser"}, n=3, intensities=False)
    with open_source(bag) as src:
        ours = [it.message for it in src.items()]
    theirs = [s for _, s in read_scans(bag)]
    assert ours and [s.model_copy(update={"header": s.header.model_copy(update={"source": "left"})})
                     for s in theirs] == ours
    assert all(s.intensities is None for s in ours)


def test_a_bad_scan_is_counted_and_the_others_replayed(tmp_path: Path) -> None:
    bag = write_scan_bag(tmp_path / "b.bag", n=4, bad=1)
    with open_source(bag) as src:
        seqs = [it.message.header.seq for it in src.items()]
        [(stream, why)] = list(src.problems)
    assert seqs == [0, 1, 2]  # consecutive: the rejected scan takes no number
    assert stream == "/scan" and why.startswith("laser scan rejected:") and "range_min" in why


def test_named_lasers_only(tmp_path: Path) -> None:
    bag = write_scan_bag(tmp_path / "b.bag", topics={"/left_scan": "l", "/rear_scan": "r"}, n=2)
    with open_source(bag, BagOptions(lasers={"front": "/rear_scan"})) as src:
        assert src.streams() == {KEYS.scans("front"): LaserScan}
        assert {it.message.header.frame_id for it in src.items()} == {"r"}
        assert "add --scan-topic /left_scan=NAME" in src.skipped["/left_scan"]


def test_inspect_lists_a_bag_s_laser_topics(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    bag = write_scan_bag(tmp_path / "b.bag", topics={"/scan": "l", "/rear_scan": "r"}, n=11)
    assert cli(["inspect", str(bag)]) == 0
    lines = {line.split()[0]: line.split() for line in capsys.readouterr().out.splitlines() if line.startswith("/")}
    # the rate: messages over the file's duration (the rear scans end 1 ms after the front's)
    assert lines["/scan"][1:3] == [SCAN_TYPE, "11"] and float(lines["/scan"][3]) == pytest.approx(10.0, abs=0.02)
    assert lines["/scan"][4:] == ["->", "scans/front"]
    assert lines["/rear_scan"][1:3] == [SCAN_TYPE, "11"] and lines["/rear_scan"][4:] == ["->", "scans/rear"]
    assert cli(["inspect", str(bag), "--scan-topic", "/rear_scan=back"]) == 0
    out = capsys.readouterr().out
    assert "-> scans/back" in out and "scans/front" not in out


# ------------------------------------------------------------------------------ recordings


def test_a_recording_of_scans_replays_and_inspects(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    bag = write_scan_bag(tmp_path / "b.bag", topics={"/scan": "l", "/rear_scan": "r"}, n=6)
    with open_source(bag) as src:
        items = list(src.items())
    path = tmp_path / "run.mcap"
    with McapRecorder(path) as rec:
        for it in items:
            rec.write(it.key, it.message, it.log_ns)
    with open_source(path) as rec_src:
        assert rec_src.streams() == {KEYS.scans("front"): LaserScan, KEYS.scans("rear"): LaserScan}
        got = [(it.key, decode(it.model, it.encoded())) for it in rec_src.items()]
    assert got == [(it.key, it.message) for it in items]
    assert cli(["inspect", str(path)]) == 0
    rows = {line.split()[0]: line.split() for line in capsys.readouterr().out.splitlines() if "scans/" in line}
    for laser in ("front", "rear"):
        row = rows[KEYS.scans(laser)]
        assert row[1:3] == ["perception.LaserScan", "6"] and float(row[3]) == pytest.approx(10.0, abs=0.05)
