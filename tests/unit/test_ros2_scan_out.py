"""The simulated ROS 2 robot's laser driver (``perception simulate --ros2 --laser``): the scan it
publishes on ``/scan`` (services/ros2/convert.py, ``scan_message``) is the scan the ros2 node reads
back, beam for beam."""

from __future__ import annotations

import numpy as np

from common.messages.keys import Keys
from common.messages.schemas import LaserScan
from services.ros2.convert import scan_message
from services.ros2.core.scans import checked_scan
from services.ros2.core.types import types_of
from tools.simulator.config import SimulatorConfig
from tools.simulator.source import SimulatedStream

TYPE = "sensor_msgs/msg/LaserScan"


def test_the_simulated_laser_driver_sends_what_the_ros2_node_reads() -> None:
    T = types_of("jazzy")
    _, pairs = SimulatedStream(SimulatorConfig(scenario="still", laser="front", fps=15, width=160, height=120,
                                               start_ns=10**18), Keys()).messages(0)
    [scan] = [m for _, m in pairs if isinstance(m, LaserScan)]
    wire = T.serialize(scan_message(T, scan), TYPE)
    back = LaserScan.from_ros(checked_scan(T.deserialize(wire, TYPE)), "front", scan.header.seq)
    assert back.header.stamp_ns == scan.header.stamp_ns and back.header.frame_id == "base_laser"
    assert np.array_equal(back.ranges, scan.ranges) and float(np.sum(scan.ranges > 0)) > 100
    f32 = np.float32  # the ROS message's geometry is float32
    assert [f32(getattr(back, k)) for k in ("angle_min", "angle_max", "angle_increment", "range_min", "range_max")] == [
        f32(getattr(scan, k)) for k in ("angle_min", "angle_max", "angle_increment", "range_min", "range_max")]
