"""The simulator's 2-D laser on the base: scans at the scanner's rate, its mount on tf_static, the
ground truth of whom it could see, and the beams' owners (tools/simulator/core/laser_scan.py)."""

from __future__ import annotations

import numpy as np

from common.messages.keys import Keys
from common.messages.schemas import LaserScan, PeopleGroundTruth, TransformBatch
from tools.simulator.config import SimulatorConfig
from tools.simulator.core.laser_scan import cast_hits
from tools.simulator.source import SimulatedStream

KEYS = Keys()


def stream(fps: float, laser: str | None = "front") -> SimulatedStream:
    return SimulatedStream(SimulatorConfig(scenario="still", laser=laser, fps=fps, width=160, height=120,
                                           start_ns=10**18), KEYS)


def test_each_beam_knows_the_leg_it_hit() -> None:
    angles = np.radians([0.0, 90.0, 180.0])
    circles = np.array([[2.0, 0.0, 0.1], [0.0, 3.0, 0.1]])
    walls = np.array([[-5.0, -1.0, -4.0, 1.0]])  # a box 4 m behind
    ranges, owner = cast_hits(np.zeros(2), 0.0, angles, walls, circles, 10.0)
    assert np.allclose(ranges, [1.9, 2.9, 4.0]) and owner.tolist() == [0, 1, -1]


def test_scans_come_at_the_scanners_rate_with_its_mount_and_whom_it_saw() -> None:
    s = stream(30.0)
    scans, seen = [], []
    for seq in range(6):
        fd, pairs = s.messages(seq)
        scans += [m for k, m in pairs if k == KEYS.scans("front")]
        gt = next(m for _, m in pairs if isinstance(m, PeopleGroundTruth))
        seen.append([p.laser_seen for p in gt.people])
        if seq == 0:
            static = next(m for k, m in pairs if k == KEYS.tf_static())
            assert isinstance(static, TransformBatch)
            assert ("base_link", "base_laser") in {(t.parent_frame, t.child_frame) for t in static.transforms}
    assert len(scans) == 3  # 15 Hz against the camera's 30
    scan = scans[0]
    assert isinstance(scan, LaserScan) and scan.header.frame_id == "base_laser" and scan.header.source == "front"
    assert len(scan.ranges) == 1441 and 0.3 < float(np.mean(scan.ranges > 0)) <= 1.0  # walls all round, dropouts
    assert all(isinstance(v, bool) for row in seen for v in row) and any(v for row in seen for v in row)
    # without a laser: no scans and no verdict
    fd, pairs = stream(15.0, None).messages(0)
    assert not [k for k, _ in pairs if "scans" in k] and all(p.laser_seen is None for p in fd.people)


def test_the_scanner_is_configured_as_the_robot_s() -> None:
    s = SimulatedStream(SimulatorConfig(scenario="still", laser="front", fps=30, width=160, height=120,
                                        start_ns=10**18, laser_fov_deg=270.0, laser_step_deg=0.5,
                                        laser_rate_hz=10.0), KEYS)
    scans = [m for seq in range(6) for k, m in s.messages(seq)[1] if k == KEYS.scans("front")]
    assert len(scans) == 2 and len(scans[0].ranges) == 541  # every third frame; 270 degrees in 0.5
    assert abs(scans[0].angle_min + np.radians(135)) < 1e-9
