"""perception doctor's laser checks on hand-made facts: each laser's scans/{laser} at a sane rate
(stamps that advance, beams that see something, none lost on the way), its frame linked to the
map through the transforms; the ROS 2 side's /scan topic and its unreadable scans; and the
collector reading LaserScan payloads."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from common.messages.codec import encode
from common.messages.schemas import Header, LaserScan
from services.ros2.core.types import types_of
from services.ros2.core.wire import GraphEntity, Qos, ros_to_dds
from tools.doctor.collect import Observer
from tools.doctor.core.checks import exit_code, render, run_checks
from tools.doctor.core.facts import Check, EdgeFacts, NodeFacts, Observation, ScanFacts, StreamFacts
from tests.helpers.doctor_facts import S, T0, healthy

T = types_of()
END = T0 + 3 * S
LASER = {"laser": "front", "target_frame": "map", "laser_frame": ""}


def with_laser(**scan: object) -> Observation:
    """The healthy pipeline with a 15 Hz laser on base_laser (fixed on base_link) and a laser node."""
    o = healthy()
    facts = dict(laser="front", count=45, frame_ids=["base_laser"], first_stamp_ns=T0, last_stamp_ns=END - S // 15,
                 first_recv_ns=T0, last_recv_ns=END, beams=541, scan_time_s=1 / 15, no_return=0.2)
    facts.update(scan)
    o.scans = {"front": ScanFacts(**facts)}  # type: ignore[arg-type]
    o.streams["scans/front"] = StreamFacts("scans/front", count=int(facts["count"]), first_ns=T0, last_ns=END)  # type: ignore[call-overload]
    o.edges.append(EdgeFacts("base_link", "base_laser", True, 3, T0, T0))
    o.nodes.append(NodeFacts("laser", "pc-9", host="pc", uptime_s=10.0, window_s=3.0, settings=dict(LASER),
                             subscribes=["scans/front", "tf", "tf_static"], publishes=["localized/front"]))
    o.nodes.append(NodeFacts("ros2", "pc-8", host="pc", uptime_s=10.0, window_s=3.0,
                             settings={"scans": "/scan:front", "camera_in": "false", "tf_in": "false",
                                       "people_out": "false", "map_topic": ""}, publishes=["scans/front"]))
    return o


def _laser(obs: Observation) -> dict[str, Check]:
    return {c.name: c for c in run_checks(obs) if c.section == "Laser"}


def test_a_healthy_laser() -> None:
    checks = _laser(with_laser())
    assert set(checks) == {"scans/front", "chain map ← base_laser"}
    assert all(c.status == "ok" for c in checks.values()), checks
    assert checks["scans/front"].figure == "15.0 Hz (541 beams, the scanner says 15 Hz, 20% without return) from ros2"
    assert checks["chain map ← base_laser"].figure == "map ← odom ← base_link ← base_laser at the scans' stamps"
    text = render(run_checks(with_laser()), "t")
    assert text.index("\nLaser\n") < text.index("\nTransforms\n")


def test_no_laser_no_laser_section() -> None:
    assert not _laser(healthy())


def test_a_scan_frame_missing_from_the_transforms_names_the_edge() -> None:
    o = with_laser(frame_ids=["laser_link"])
    c = _laser(o)["chain map ← laser_link"]
    assert c.status == "fail" and "no transform has laser_link as its child" in c.figure
    assert "laser_link" in c.fix and "tf_static" in c.fix and "scans" in c.fix
    assert exit_code(run_checks(o)) == 2


def test_a_laser_linked_to_odom_but_not_the_map() -> None:
    o = with_laser()
    o.edges = [e for e in o.edges if (e.parent, e.child) != ("map", "odom")]
    c = _laser(o)["chain map ← base_laser"]
    assert c.status == "fail" and "odom ← base_link ← base_laser, but nothing links odom to map" in c.figure
    assert "map → odom" in c.fix and "AMCL" in c.fix
    o.nodes = [n for n in o.nodes if n.service != "laser"]  # nobody places people yet: a warning
    assert _laser(o)["chain map ← base_laser"].status == "warn"


def test_a_stale_odometry_edge_behind_the_scans() -> None:
    o = with_laser()
    o.edges = [dataclasses.replace(e, last_stamp_ns=T0) if e.child == "odom" else e for e in o.edges]
    c = _laser(o)["chain map ← base_laser"]
    assert c.status == "fail" and "older than the scans" in c.figure and "map → odom" in c.figure


def test_the_laser_nodes_target_and_laser_frame() -> None:
    o = with_laser(frame_ids=[""])
    assert _laser(o)["chain map ← front"].status == "fail"
    assert "frame_id" in _laser(o)["chain map ← front"].fix
    for n in o.nodes:
        if n.service == "laser":
            n.settings.update(laser_frame="base_laser", target_frame="odom")
    c = _laser(o)["chain odom ← base_laser"]
    assert c.status == "ok" and c.figure.startswith("odom ← base_link ← base_laser")


@pytest.mark.parametrize("scan, words, fix", [
    (dict(count=3), "below 2 Hz", "10 Hz"),
    (dict(count=450), "more than one scanner", "own name"),
    (dict(scan_time_s=1 / 40), "lost on the way", "weak link"),
    (dict(backwards=5), "5 scans stamped at or before", "one publisher per laser"),
    (dict(no_return=0.99), "sees almost nothing", "range_max"),
    (dict(count=1), "too few", "longer"),
])
def test_an_insane_rate_or_a_blind_laser_warns(scan: dict[str, object], words: str, fix: str) -> None:
    c = _laser(with_laser(**scan))["scans/front"]
    assert c.status == "warn" and words in c.figure and fix in c.fix, c


def test_no_scans_for_a_laser_node_names_where_they_should_come_from() -> None:
    o = with_laser()
    o.scans, o.streams["scans/front"] = {}, StreamFacts("scans/front")
    c = _laser(o)["scans/front"]
    assert c.status == "fail" and "nothing in 3.0 s" in c.figure and "/scan" in c.fix and "ros2 topic hz" in c.fix
    o.nodes = [n for n in o.nodes if n.service != "ros2"]
    assert "perception ros2" in _laser(o)["scans/front"].fix
    assert "chain map ← front" not in _laser(o)  # no frame to judge


def _pub(zid: str, node: str, topic: str, type_name: str) -> GraphEntity:
    return GraphEntity(domain_id=0, zid=zid, node_id=0, entity_id=1, kind="MP", node_name=node, topic=topic,
                       dds_type=ros_to_dds(type_name), type_hash=T.hash(type_name), qos=Qos())


def _ros2(obs: Observation) -> dict[str, Check]:
    return {c.name: c for c in run_checks(obs) if c.section == "ROS 2"}


def test_the_ros2_side_of_the_scan() -> None:
    o = with_laser()
    me = GraphEntity(domain_id=0, zid="me", node_id=0, entity_id=0, kind="NN", node_name="people_perception")
    o.ros2_graph = [me, _pub("lidar", "urg_node", "/scan", "sensor_msgs/msg/LaserScan")]
    c = _ros2(o)["/scan"]
    assert c.status == "ok" and "urg_node" in c.figure
    o.ros2_graph = [me]
    c = _ros2(o)["/scan"]
    assert c.status == "warn" and "no publisher" in c.figure and "scans" in c.fix  # a laser node waits for it
    o.nodes = [n for n in o.nodes if n.service != "laser"]
    c = _ros2(o)["/scan"]
    assert c.status == "ok" and "no laser" in c.figure  # a robot without a laser: fine
    o.ros2_graph = [me, _pub("lidar", "velodyne", "/scan", "sensor_msgs/msg/PointCloud2")]
    assert _ros2(o)["/scan"].status == "fail" and "PointCloud2" in _ros2(o)["/scan"].figure
    ros2 = next(n for n in o.nodes if n.service == "ros2")
    ros2.counters["invalid_scan_length"] = 4
    c = _ros2(o)["ros2 scan length"]
    assert c.status == "fail" and "4 ROS 2 samples" in c.figure and "angle" in c.fix


def test_the_collector_reads_scans() -> None:
    observer = Observer()
    n = 100
    for k, stamp in enumerate((0, 1, 2, 2, 3)):  # one stamp repeated
        ranges = np.full(n, 3.0, np.float32)
        ranges[: 10 * (k + 1)] = np.nan
        scan = LaserScan(header=Header(stamp_ns=T0 + stamp * S // 10, frame_id="base_laser", source="front", seq=k),
                         angle_min=-1.0, angle_max=1.0, angle_increment=2.0 / (n - 1), scan_time=0.1, range_min=0.1,
                         range_max=10.0, ranges=ranges)
        observer.payload("pp/robot/perception/v1/scans/front", encode(scan), T0 + k * S // 10)
    obs = observer.observation(0.5)
    s = obs.scans["front"]
    assert (s.count, s.frame_ids, s.backwards, s.beams, s.scan_time_s) == (5, ["base_laser"], 1, n, pytest.approx(0.1))
    assert s.no_return == pytest.approx(0.3) and s.stamp_rate_hz() == pytest.approx(4 / 0.3)
    assert obs.streams["scans/front"].count == 5
    assert "scans/front" in {c.name for c in run_checks(obs) if c.section == "Laser"}
