"""perception ros2's laser scans on the in-memory bus: sensor_msgs/LaserScan on /scan (or any
topics, each to its own laser) becomes scans/{laser}; every bad scan is counted under its reason,
logged and skipped, and the next good one passes."""

from __future__ import annotations

import argparse
import logging
from typing import Any

import numpy as np
import pytest

from common.messages.keys import Delivery, Keys
from common.messages.schemas import LaserScan
from common.runtime.service import Counters
from common.transport.memory import MemoryBus
from services.ros2 import flags
from services.ros2.config import Ros2Config
from services.ros2.core.types import types_of
from services.ros2.participant import RosParticipant
from services.ros2.service import Ros2Service

KEYS = Keys()
T = types_of()
TYPE = "sensor_msgs/msg/LaserScan"
STAMP = 1_700_000_000_000_000_000
N = 271  # a 270-degree scanner at one degree


def scan_message(k: int = 0, frame_id: str = "laser", **fields: Any) -> Any:
    ranges = np.full(N, 4.0, np.float32)
    ranges[10:20] = np.nan  # no return: kept
    ranges[30] = np.inf
    base: dict[str, Any] = dict(header=T.header(STAMP + k * 100_000_000, frame_id), angle_min=-np.radians(135),
                                angle_max=np.radians(135), angle_increment=np.radians(1), time_increment=1e-4,
                                scan_time=0.1, range_min=0.05, range_max=20.0, ranges=ranges,
                                intensities=np.zeros(0, np.float32))
    base.update(fields)
    return T.cls(TYPE)(**base)


class Rig:
    def __init__(self, lasers: tuple[str, ...] = ("front",), **settings: Any) -> None:
        self.bus = MemoryBus()
        self.robot = RosParticipant(self.bus.transport(), T, domain_id=0, node_name="laser_driver")
        self.node = Ros2Service(self.bus.transport(), KEYS, Ros2Config(domain_id=0, camera_in=False, **settings),
                                Counters())
        app = self.bus.transport()
        self.subs = {name: app.subscribe(KEYS.scans(name), LaserScan, Delivery(latest=False, queue=64,
                                                                                congestion="drop"))
                     for name in lasers}

    def send(self, msg: Any, topic: str = "/scan") -> None:
        self.robot.publisher(topic, TYPE).put(msg)

    def got(self, laser: str = "front") -> list[LaserScan]:
        out = []
        while (g := self.subs[laser].try_recv()) is not None:
            out.append(g.msg)
        return out


def test_scan_becomes_scans_front_beam_for_beam() -> None:
    rig = Rig()
    for k in range(3):
        rig.send(scan_message(k))
    rig.node.poll(0.0)
    got = rig.got()
    assert [s.header.seq for s in got] == [1, 2, 3]
    assert [s.header.stamp_ns for s in got] == [STAMP, STAMP + 100_000_000, STAMP + 200_000_000]
    s = got[0]
    assert (s.header.frame_id, s.header.source, len(s.ranges)) == ("laser", "front", N)
    assert np.isnan(s.ranges[10:20]).all() and np.isinf(s.ranges[30]) and s.ranges[0] == 4.0
    assert (s.angle_min, s.angle_increment, s.range_max, s.scan_time) == pytest.approx(
        (-np.radians(135), np.radians(1), 20.0, 0.1))
    assert rig.node.counters.extra["scans"] == 3 and rig.node.counters.invalid == 0
    assert "/scan -> " in rig.node.describe() and rig.node.describe().split("/scan -> ")[1].startswith(
        KEYS.scans("front"))


def test_several_lasers_each_to_its_own_stream() -> None:
    rig = Rig(lasers=("front", "rear"), scans={"/front/scan": "front", "/rear/scan": "rear"})
    rig.send(scan_message(0, "front_laser"), "/front/scan")
    rig.send(scan_message(0, "rear_laser"), "/rear/scan")
    rig.send(scan_message(1, "rear_laser"), "/rear/scan")
    rig.send(scan_message(0), "/scan")  # not read
    rig.node.poll(0.0)
    assert [s.header.frame_id for s in rig.got("front")] == ["front_laser"]
    rear = rig.got("rear")
    assert [(s.header.frame_id, s.header.source, s.header.seq) for s in rear] == [("rear_laser", "rear", 1),
                                                                                  ("rear_laser", "rear", 2)]


def test_no_scans_reads_and_publishes_no_laser() -> None:
    rig = Rig(scans=[])
    rig.send(scan_message())
    rig.node.poll(0.0)
    assert not rig.got() and "scans" not in rig.node.counters.extra
    assert not [k for k in rig.bus.tokens if "LaserScan" in k and rig.node.ros.zid in k]


def test_the_node_reads_scan_in_the_ros2_graph() -> None:
    rig = Rig()
    mine = [k for k in rig.bus.tokens if f"/{rig.node.ros.zid}/" in k and "/MS/" in k]
    assert any("%scan/sensor_msgs::msg::dds_::LaserScan_/" + T.hash(TYPE) in k for k in mine), mine


@pytest.mark.parametrize("case, reason", [
    ("zero increment", "invalid_scan_increment"),
    ("length", "invalid_scan_length"),
    ("limits", "invalid_scan_range_limits"),
    ("intensities", "invalid_scan_intensities"),
    ("empty", "invalid_scan_empty"),
    ("nan angle", "invalid_scan_not_finite"),
    ("truncated", "invalid_cdr"),
    ("wrong type", "invalid_wrong_type"),
])
def test_a_bad_scan_is_counted_logged_and_survived(case: str, reason: str, caplog: pytest.LogCaptureFixture) -> None:
    rig = Rig()
    if case == "zero increment":
        rig.send(scan_message(angle_increment=0.0))
    elif case == "length":
        rig.send(scan_message(ranges=np.ones(100, np.float32)))
    elif case == "limits":
        rig.send(scan_message(range_min=30.0))
    elif case == "intensities":
        rig.send(scan_message(intensities=np.ones(5, np.float32)))
    elif case == "empty":
        rig.send(scan_message(ranges=np.zeros(0, np.float32)))
    elif case == "nan angle":
        rig.send(scan_message(angle_min=float("nan")))
    elif case == "truncated":
        rig.robot.publisher("/scan", TYPE).put_cdr(T.serialize(scan_message(), TYPE)[:60])
    elif case == "wrong type":
        other = RosParticipant(rig.bus.transport(), T, domain_id=0, node_name="lidar")
        other.publisher("/scan", "sensor_msgs/msg/PointCloud2").put(T.cls("sensor_msgs/msg/PointCloud2")(
            header=T.header(STAMP, "laser"), height=0, width=0, fields=[], is_bigendian=False, point_step=0,
            row_step=0, data=np.zeros(0, np.uint8), is_dense=True))
    with caplog.at_level(logging.WARNING, logger="services.ros2.service"):
        rig.node.poll(0.0)
    assert rig.node.counters.extra.get(reason, 0) == 1, rig.node.counters.extra
    assert rig.node.counters.invalid == 1 and not rig.got()
    assert any("/scan" in r.getMessage() for r in caplog.records), caplog.text
    rig.send(scan_message(1))
    rig.node.poll(1.0)
    assert [s.header.seq for s in rig.got()] == [1]  # the next good scan passes, numbered from 1


def test_a_clockwise_scanner_comes_out_counter_clockwise() -> None:
    rig = Rig()
    msg = scan_message()
    ranges = np.linspace(1.0, 3.0, N).astype(np.float32)
    rig.send(T.cls(TYPE)(**{**{f: getattr(msg, f) for f in msg.__dataclass_fields__}, "angle_min": np.radians(135),
                            "angle_max": -np.radians(135), "angle_increment": -np.radians(1), "ranges": ranges}))
    rig.node.poll(0.0)
    (s,) = rig.got()
    assert s.angle_increment == pytest.approx(np.radians(1)) and s.angle_min == pytest.approx(-np.radians(135))
    assert s.ranges[0] == pytest.approx(3.0) and s.ranges[-1] == pytest.approx(1.0)


def _config(*argv: str) -> Ros2Config:
    parser = argparse.ArgumentParser()
    flags.add_arguments(parser)
    over = {k: v for k, v in flags.overrides(parser.parse_args(list(argv))).items() if v is not None}
    return Ros2Config(domain_id=0, **over)


def test_the_scan_flags_and_settings() -> None:
    assert Ros2Config(domain_id=0).scan_topics() == [("/scan", "front")]
    assert _config().scans == ["/scan:front"]
    assert _config("--scan", "/base_scan").scan_topics() == [("/base_scan", "front")]
    assert _config("--scan", "/front/scan", "--scan", "/rear/scan:rear").scans == ["/front/scan:front",
                                                                                 "/rear/scan:rear"]
    assert _config("--no-scan").scans == []
    assert Ros2Config(domain_id=0, scans={"/s1": "left", "/s2": "right"}).scans == ["/s1:left", "/s2:right"]
    for bad, words in ((["/a", "/b"], "name each laser"), (["scan"], "absolute"), (["/a:b/c"], "key chunk"),
                       (["/a:x", "/a:y"], "twice")):
        with pytest.raises(ValueError, match=words):
            Ros2Config(domain_id=0, scans=bad)
    # a laser alone is something to do
    assert Ros2Config(domain_id=0, camera_in=False, tf_in=False, people_out=False).scans
    with pytest.raises(ValueError, match="nothing to do"):
        Ros2Config(domain_id=0, camera_in=False, tf_in=False, people_out=False, scans=[])
