"""A ROS 2 laser through perception ros2, as a real process on a real router: a third party's
implementation of rmw_zenoh's protocol (PyPI's zenoh-ros2-sdk) publishes sensor_msgs/LaserScan on
/scan, and scans/front comes out beam for beam; a scan the node cannot read is counted in its
status and the node goes on. Then the laser node, fed by it, finds the person the scan shows."""

from __future__ import annotations

import signal
import subprocess
import sys
import time
from typing import Any

import numpy as np
import pytest

from common.messages.keys import RELIABLE, SCANS
from common.messages.schemas import (Header, LaserScan, LocalizedDetections, ServiceStatus, Transform,
                                     TransformBatch)
from services.ros2.convert import tf_message
from tests.helpers.ros2_sdk import DOMAIN, KEYS, T, sdk
from tests.helpers.ros2_sdk import fields as _fields
from tests.helpers.ros2_sdk import ros2_node as _node
from tests.helpers.ros2_sdk import ros2_publisher as _pub
from tests.helpers.ros2_sdk import stop as _stop
from tests.helpers.ros2_sdk import wait_alive as _wait_alive

pytestmark = [pytest.mark.zenoh, pytest.mark.slow]
TYPE = "sensor_msgs/msg/LaserScan"
T0 = 1_700_000_000_000_000_000
N = 541  # a 270-degree scanner at half a degree


def _ranges(k: int, legs: bool = False) -> np.ndarray:
    """A wall 5 m around (range_max beyond it); with ``legs``, two legs 1.5 m straight ahead."""
    from tools.simulator.core.laser_scan import cast

    angles = np.radians(np.linspace(-135.0, 135.0, N))
    circles = np.array([[1.5, -0.12, 0.06], [1.5, 0.12, 0.06]]) if legs else np.zeros((0, 3))
    walls = np.array([[5.0, -5.0, 5.2, 5.0], [-5.2, -5.0, -5.0, 5.0], [-5.0, 5.0, 5.0, 5.2], [-5.0, -5.2, 5.0, -5.0]])
    ranges = cast(np.zeros(2), 0.0, angles, walls, circles, 20.0).astype(np.float32)
    ranges[k % 7 :: 50] = np.nan  # a few beams without return, kept as sent
    return ranges


def _scan(k: int, legs: bool = False, **fields: Any) -> dict[str, Any]:
    msg = T.cls(TYPE)(header=T.header(T0 + k * 100_000_000, "base_laser"), angle_min=float(np.radians(-135.0)),
                      angle_max=float(np.radians(135.0)), angle_increment=float(np.radians(0.5)), time_increment=1e-5,
                      scan_time=0.1, range_min=0.05, range_max=20.0, ranges=_ranges(k, legs),
                      intensities=np.zeros(0, np.float32))
    return {**_fields(msg), **fields}


def _statuses(app: Any) -> list[ServiceStatus]:
    return [m for _, m in app.query(KEYS.status(), timeout=2.0) if isinstance(m, ServiceStatus) and m.name == "ros2"]


def test_a_third_party_laser_scan_becomes_scans_front(router: Any, zenoh_client: Any, sdk_session: Any) -> None:
    app = zenoh_client()
    scans = app.subscribe(KEYS.scans("front"), LaserScan, SCANS)
    node = _node(router, "--no-camera", "--no-people")
    try:
        _wait_alive(app, node)
        laser = _pub(sdk_session, "/scan", TYPE)
        got: list[LaserScan] = []
        deadline = time.monotonic() + 30
        k = 0
        while len(got) < 3 and time.monotonic() < deadline:
            laser.publish(**_scan(k))
            k += 1
            time.sleep(0.1)  # the scanner's period
            while (g := scans.try_recv()) is not None:
                got.append(g.msg)
        assert len(got) >= 3, "no scans/front from the ROS 2 laser"
        for s in got:
            sent = (s.header.stamp_ns - T0) // 100_000_000
            assert s.header.stamp_ns == T0 + sent * 100_000_000 and s.header.source == "front"
            assert s.header.frame_id == "base_laser" and len(s.ranges) == N
            np.testing.assert_array_equal(s.ranges, _ranges(sent))  # NaN where NaN was sent
            assert s.angle_increment == pytest.approx(np.radians(0.5))
        assert [s.header.seq for s in got] == sorted(s.header.seq for s in got)

        # a scan whose ranges do not fit its angles: counted, not a crash; the next one passes
        laser.publish(**_scan(k, ranges=np.ones(100, np.float32)))
        end = time.monotonic() + 15
        counted = 0.0
        while time.monotonic() < end and not counted:
            counted = max((s.extra.get("invalid_scan_length", 0) for s in _statuses(app)), default=0)
        assert counted == 1
        laser.publish(**_scan(k + 1))
        assert (m := scans.recv(timeout=10.0)) is not None and m.msg.header.stamp_ns == T0 + (k + 1) * 100_000_000
        assert node.poll() is None

        # the graph, as the third party's `ros2 topic list` sees it: the node reads /scan
        _, host, port = sdk_session
        topics = dict(sdk.get_topic_names_and_types(domain_id=DOMAIN, router_ip=host, router_port=port, timeout=2.0))
        assert TYPE in topics.get("/scan", [])
        laser.close()
    finally:
        out = _stop(node)
    assert "Traceback" not in out and "/scan" in out


def test_the_laser_node_finds_legs_in_a_ros2_scan(router: Any, zenoh_client: Any, sdk_session: Any) -> None:
    """/scan and /tf_static from the third party, through perception ros2 and perception laser: the
    person standing 1.5 m in front of the scanner comes out on localized/front, in the map."""
    app = zenoh_client()
    people = app.subscribe(KEYS.localized("front"), LocalizedDetections, RELIABLE)
    node = _node(router, "--no-camera", "--no-people", "--map-topic", "")
    laser_node = subprocess.Popen([sys.executable, "-m", "perception", "laser", "--robot", KEYS.robot, "--mode",
                                   "client", "--connect", router.endpoint, "--no-multicast-scouting"],
                                  stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
    try:
        _wait_alive(app, node)
        laser, tf_static = _pub(sdk_session, "/scan", TYPE), _pub(sdk_session, "/tf_static", "tf2_msgs/msg/TFMessage")
        mount = TransformBatch(header=Header(stamp_ns=T0), transforms=[Transform(
            parent_frame="map", child_frame="base_laser", stamp_ns=T0, translation=np.array([1.0, 2.0, 0.2]),
            rotation_xyzw=np.array([0.0, 0.0, 0.0, 1.0]), static=True)])
        found: list[LocalizedDetections] = []
        deadline = time.monotonic() + 60
        k = 0
        while not [m for m in found if m.detections] and time.monotonic() < deadline:
            assert laser_node.poll() is None, laser_node.communicate()[0]
            tf_static.publish(**_fields(tf_message(T, mount)))
            laser.publish(**_scan(k, legs=True, header=T.header(time.time_ns(), "base_laser")))
            k += 1
            time.sleep(0.1)
            while (g := people.try_recv()) is not None:
                found.append(g.msg)
        seen = [m for m in found if m.detections]
        assert seen, f"no person on localized/front from {k} scans ({len(found)} empty messages)"
        (person, *_) = seen[-1].detections
        assert seen[-1].header.frame_id == "map" and seen[-1].camera_frame == "base_laser"
        assert np.linalg.norm(np.asarray(person.position[:2]) - [2.5 - 0.06, 2.0]) < 0.15
        laser.close()
        tf_static.close()
    finally:
        laser_node.send_signal(signal.SIGINT)
        laser_out, _ = laser_node.communicate(timeout=30)
        out = _stop(node)
    assert "Traceback" not in out + laser_out, out + laser_out

