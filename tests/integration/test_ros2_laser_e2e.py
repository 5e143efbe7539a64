"""End to end through ROS 2 with a base laser: a third party's rmw_zenoh implementation
(zenoh-ros2-sdk) is the robot (tests/helpers/ros2_laser_robot.py): it publishes the simulator's
head camera, /tf, /tf_static (with base_link -> base_laser) and /map, and /scan
(sensor_msgs/LaserScan: the legs of the people its laser can see). deploy/ros2.yaml runs the ros2
node, the detector, localizer, embedder, laser node and tracker as processes on one router (client
mode, loopback, no multicast, a free port), and the third party reads the people back as ROS4HRI
topics: /humans/bodies/tracked and /humans/bodies/<id>/position.

The scene: person 1 walks in front of the camera (confirmed: a body id appears), then round to the
robot's left, out of the image for about 7 s while the laser keeps seeing their legs, and back into
the image; the same body id stays on /humans/bodies/tracked all that time and its position follows
the legs. Person 2 paces behind the robot, seen by the laser alone: legs never confirm a person,
so no body is ever reported there.
"""

from __future__ import annotations

import json
import sys
import uuid
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from common.messages.keys import Keys
from common.transport.router_process import free_port
from tests.helpers.scored_launch import SERVICES, Scenario, ZenohClient, scored_run

pytest.importorskip("zenoh_ros2_sdk", reason="zenoh-ros2-sdk (the test extra) is not installed")
pytestmark = [pytest.mark.zenoh, pytest.mark.slow]

ROOT = Path(__file__).resolve().parents[2]
DURATION_S = 14.0
FPS = 10.0


def _person(frame: dict[str, Any], pid: int) -> dict[str, Any]:
    return next(p for p in frame["people"] if p["id"] == pid)


def test_a_person_the_camera_confirmed_stays_a_ros4hri_body_while_only_the_laser_sees_them(tmp_path: Path) -> None:
    port = free_port()
    record = tmp_path / "record.json"
    sc = Scenario(duration_s=DURATION_S, fps=FPS, max_speed=True)

    def robot(s: Scenario, keys: Keys) -> list[str]:
        return [sys.executable, "-m", "tests.helpers.ros2_laser_robot", "--connect", f"tcp/127.0.0.1:{port}",
                "--robot", keys.robot, "--domain-id", "0", "--record", str(record), "--duration", str(s.duration_s),
                "--fps", str(s.fps), "--width", str(s.width), "--height", str(s.height), "--max"]

    run = scored_run(ROOT / "deploy" / "ros2.yaml", port, ZenohClient(f"tcp/127.0.0.1:{port}"), tmp_path / "ros2",
                     f"rosl{uuid.uuid4().hex[:6]}", sc, env={"ROS_DOMAIN_ID": "0"}, feeder=robot,
                     services=(*SERVICES, "laser", "ros2"))
    assert run.launch_status == 0, run.log
    print("robot:", (tmp_path / "ros2" / "simulate.log").read_text().strip().splitlines()[-1])
    rec = json.loads(record.read_text())
    truth: list[dict[str, Any]] = rec["truth"]
    assert len(truth) == int(DURATION_S * FPS)
    tracked: dict[int, list[set[str]]] = {}
    for frame, ids in rec["tracked"]:
        tracked.setdefault(frame, []).append(set(ids))

    # the scene as the simulator saw it: person 1 in the image, then out of it with the laser alone
    # on them for 5 s or more, then back; person 2 never in the image, always in the laser's sight
    cam = [_person(f, 1)["camera"] for f in truth]
    first_out = cam.index(False)
    back = first_out + cam[first_out:].index(True)
    alone = [k for k in range(first_out, back) if _person(truth[k], 1)["laser"]]
    assert first_out >= 20 and len(alone) >= 50 and back < len(truth) - 20, (first_out, len(alone), back)
    assert not any(_person(f, 2)["camera"] for f in truth) and all(_person(f, 2)["laser"] for f in truth)

    # confirmed by the camera: a body id on /humans/bodies/tracked while person 1 is in the image
    in_view = sorted({b for k in range(first_out) for ids in tracked.get(k, []) for b in ids})
    assert len(in_view) == 1, f"bodies while person 1 was in the image: {in_view}"
    (body,) = in_view

    # out of the image, the laser alone on them: the same id, in nearly every frame's messages. Not
    # in every message: a track not detected in an update turns coasting until the next one that
    # detects it, so when the camera's frame (which cannot see them) reaches the tracker before the
    # scan of the same instant, that output has them coasting, and the ros2 node publishes
    # confirmed tracks only (include_coasting false): the id is left out of that one message
    # (5-13 % of them here, depending on the machine's timing)
    msgs = [ids for k in alone for ids in tracked.get(k, [])]
    assert len(msgs) >= 0.8 * len(alone), f"{len(msgs)} /humans/bodies/tracked messages over {len(alone)} frames"
    have = sum(body in ids for ids in msgs)
    print(f"{body} in {have} of {len(msgs)} /humans/bodies/tracked messages while only the laser saw them")
    assert have >= 0.75 * len(msgs), f"{body} in {have} of {len(msgs)} messages while only the laser saw them"
    present = [any(body in ids for ids in tracked.get(k, [])) for k in alone]
    gap = max(len(missing) for missing in "".join(".x"[p] for p in present).split("x"))
    assert sum(present) >= 0.9 * len(alone) and gap <= 5, f"{body} in {sum(present)} of {len(alone)} frames, " \
        f"missing for {gap} frames in a row"
    assert sum(present[-10:]) >= 8, f"{body} by the end of the stretch: {present[-10:]}"
    # ... and its position follows the legs (the torso between them), on /humans/bodies/<id>/position
    pos = [(frame, x, y) for b, frame, x, y in rec["positions"] if b == body and frame in set(alone)]
    assert len(pos) >= 0.8 * have, f"{len(pos)} position messages for {have} tracked ones"
    err = np.array([np.hypot(x - _person(truth[frame], 1)["x"], y - _person(truth[frame], 1)["y"]) for frame, x, y in pos])
    assert np.percentile(err, 90) < 0.35, f"position errors (m): median {np.median(err):.2f}, max {err.max():.2f}"
    walked = np.ptp(np.array([[x, y] for _, x, y in pos]), axis=0)
    assert np.hypot(*walked) > 1.5, f"the position hardly moved: {walked}"  # it went round with them

    # back in the image: still the same body
    later = [ids for k in range(back + 10, len(truth)) for ids in tracked.get(k, [])]
    assert later and sum(body in ids for ids in later) >= 0.75 * len(later), later[-5:]

    # person 2: the laser node found their legs, yet no body was ever reported near them
    near2 = [k for k, people in rec["laser_people"] if 0 <= k < len(truth)
             and any(np.hypot(x - _person(truth[k], 2)["x"], y - _person(truth[k], 2)["y"]) < 0.5 for x, y in people)]
    assert len(set(near2)) >= 0.5 * len(truth), f"the laser node found person 2 in {len(set(near2))} frames"
    for b, frame, x, y in rec["positions"]:
        if frame < len(truth):
            p2 = _person(truth[frame], 2)
            assert np.hypot(x - p2["x"], y - p2["y"]) > 1.0, f"{b} reported where only the laser saw person 2"
    # and no other body at all: legs alone never confirmed anyone
    assert {b for ids_list in tracked.values() for ids in ids_list for b in ids} == {body}
