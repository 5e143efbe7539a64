"""End to end through ROS 2: the simulator's frames, transforms and map, published as ROS 2 topics by a
third party's rmw_zenoh implementation (zenoh-ros2-sdk), go through deploy/ros2.yaml (the ros2
node and the four services on one router), and the people come back to that third party as
/humans/bodies/tracked. Table II on `still` must agree with the native path (deploy/single-pc.yaml
fed by perception simulate) within 0.05 MOTA.

Both runs are paced by the detector (each frame once the previous one is detected), so the same
frames reach the tracker whatever else the machine is doing.
"""

from __future__ import annotations

import json
import sys
import uuid
from pathlib import Path

import pytest

from common.messages.keys import Keys
from common.transport.router_process import free_port
from tests.helpers.scored_launch import SERVICES, Scenario, ZenohClient, scored_run

pytest.importorskip("zenoh_ros2_sdk", reason="zenoh-ros2-sdk (the test extra) is not installed")
pytestmark = [pytest.mark.zenoh, pytest.mark.slow]

ROOT = Path(__file__).resolve().parents[2]
SCORE_TOLERANCE = 0.05


def test_the_pipeline_through_ros2_scores_as_the_native_path(tmp_path: Path) -> None:
    sc = Scenario(max_speed=True)
    native_port, ros_port = free_port(), free_port()
    native = scored_run(ROOT / "deploy" / "single-pc.yaml", native_port, ZenohClient(f"tcp/127.0.0.1:{native_port}"),
                        tmp_path / "native", f"nat{uuid.uuid4().hex[:6]}", sc)

    def robot(s: Scenario, keys: Keys) -> list[str]:
        return [sys.executable, "-m", "tests.helpers.ros2_robot", "--connect", f"tcp/127.0.0.1:{ros_port}",
                "--robot", keys.robot, "--domain-id", "0", "--scenario", s.name, "--seed", str(s.seed), "--duration",
                str(s.duration_s), "--fps", str(s.fps), "--width", str(s.width), "--height", str(s.height), "--max"]

    ros = scored_run(ROOT / "deploy" / "ros2.yaml", ros_port, ZenohClient(f"tcp/127.0.0.1:{ros_port}"),
                     tmp_path / "ros2", f"ros{uuid.uuid4().hex[:6]}", sc, env={"ROS_DOMAIN_ID": "0"}, feeder=robot,
                     services=(*SERVICES, "ros2"))
    assert (ros.launch_status, native.launch_status) == (0, 0), ros.log + native.log
    r, n = ros.overall, native.overall
    summary = {k: (r[k], n[k]) for k in ("objects", "misses", "false_positives", "id_switches", "mota", "idf1")}
    print("ROS 2 path vs native path:", summary)
    assert r["objects"] == n["objects"] > 100, summary
    assert abs(r["mota"] - n["mota"]) <= SCORE_TOLERANCE, summary
    # the people came back to the third party's subscriber
    back = json.loads((tmp_path / "ros2" / "simulate.log").read_text().strip().splitlines()[-1])
    assert back["frames_sent"] == 200, back
    assert back["tracked_messages"] > 100, back
    assert max(back["bodies"].values()) > 50, back
    # the robot's map went the same way: /map, the ros2 node, static_map, the tracker
    assert "static map from ros2: 182 x 142 cells of 0.05 m" in (tmp_path / "ros2" / "launch.log").read_text()
