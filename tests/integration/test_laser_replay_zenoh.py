"""A real laser bag replayed through a real router into a live ``perception laser`` node: the people
it publishes on localized/front are the ones ``perception legs`` prints for the same scans; the
scans recorded meanwhile by ``perception record`` are listed by ``perception inspect`` and, replayed,
give the node's same people again."""

from __future__ import annotations

import json
import os
import subprocess
import sys
import time
from pathlib import Path
from typing import Any, Callable

import numpy as np
import pytest

from common.messages.keys import RELIABLE, Delivery, Keys
from common.messages.schemas import Header, LaserScan, LocalizedDetections, Transform, TransformBatch
from common.transport.base import Received, Subscription
from common.transport.router_process import RouterProcess
from common.transport.zenoh import ZenohTransport
from tests.helpers.recording import stop_recording, wait_recorded
from tests.helpers.wait import wait_until

pytestmark = pytest.mark.zenoh

KEYS = Keys(robot="itest")
FIFO = Delivery(latest=False, queue=4096, congestion="block")
BAG = Path("laser_legs") / "demo_stationary_simple_environment.bag"
#: a 3 s slice (30 scans at 10 Hz) in which people walk past (43 people in 28 of its scans)
START_S, END_S = 20.0, 23.0
TIMEOUT = 60.0


def _perception(*args: str) -> list[str]:
    return [sys.executable, "-m", "perception", "-q", *args]


def _collect(sub: Subscription[Any], n: int, timeout: float) -> list[Received[Any]]:
    deadline = time.monotonic() + timeout
    out: list[Received[Any]] = []
    while len(out) < n and time.monotonic() < deadline:
        if (r := sub.recv(timeout=0.2)) is not None:
            out.append(r)
    return out


def test_a_real_bag_through_the_laser_node_gives_what_legs_prints(
        shared_data: Path, router: RouterProcess, zenoh_client: Callable[[], ZenohTransport], tmp_path: Path) -> None:
    bag = shared_data / BAG
    if not bag.is_file():
        pytest.skip(f"the laser bag {bag} is not in the shared data")
    env = {**os.environ, "RUST_LOG": "error"}
    zenoh = ["--connect", router.endpoint, "--no-multicast-scouting"]
    log_path = tmp_path / "laser.log"
    log = log_path.open("wb")
    node = subprocess.Popen(_perception("laser", "--robot", "itest", *zenoh), stdout=log, stderr=subprocess.STDOUT,
                            env=env)
    recording = tmp_path / "scans.mcap"
    recorder = subprocess.Popen(_perception("record", "--robot", "itest", "-o", str(recording), "--keys",
                                            KEYS.scans("**"), *zenoh), stdout=subprocess.PIPE,
                                stderr=subprocess.PIPE, text=True, env=env)
    try:
        # what the leg detector finds in every scan of the bag, in the scanner's frame
        legs = subprocess.run(_perception("legs", str(bag), "--topic", "/scan", "--json"), capture_output=True,
                              text=True, timeout=TIMEOUT, env=env)
        assert legs.returncode == 0, legs.stderr
        expected = {row["stamp_ns"]: row for row in map(json.loads, legs.stdout.splitlines())}

        client = zenoh_client()
        people_sub = client.subscribe(KEYS.localized("front"), LocalizedDetections, FIFO)
        scans_sub = client.subscribe(KEYS.scans("front"), LaserScan, FIFO)
        tf_static = client.publisher(KEYS.tf_static(), TransformBatch, RELIABLE)

        def node_up() -> bool:
            assert node.poll() is None, log_path.read_text()
            return bool(client.alive(KEYS.alive("laser")))

        wait_until(node_up, TIMEOUT, interval=0.1, what="the laser node to come up")
        assert tf_static.wait_for_subscribers(TIMEOUT)
        # only the recorder listens on scans/probe: once it does, it records scans/front too
        assert client.publisher(KEYS.scans("probe"), LaserScan, FIFO).wait_for_subscribers(TIMEOUT)
        frame = next(iter(expected.values()))["frame"]
        # the scanner at the map's origin: the people in the map are the people in the scanner's frame
        tf_static.put(TransformBatch(header=Header(stamp_ns=1, source="test"), transforms=[Transform(
            parent_frame="map", child_frame=frame, stamp_ns=0, translation=np.zeros(3),
            rotation_xyzw=np.array([0.0, 0.0, 0.0, 1.0]), static=True)]))

        def replay(path: Path, *window: str) -> int:
            """Replay ``path`` in real time; the number of scans it published."""
            proc = subprocess.run(_perception("replay", str(path), "--robot", "itest", *window, "--wait-subscribers",
                                              "30", "--no-progress", *zenoh),
                                  capture_output=True, text=True, timeout=TIMEOUT, env=env)
            assert proc.returncode == 0 and "Traceback" not in proc.stderr, proc.stdout + proc.stderr
            return int(proc.stdout.split(f"{KEYS.scans('front')}: ", 1)[1].split()[0])

        n = replay(bag, "--start", str(START_S), "--end", str(END_S))
        assert 25 <= n <= 35
        scans = _collect(scans_sub, n, TIMEOUT)
        got = _collect(people_sub, n, TIMEOUT)
        assert len(scans) == n and len(got) == n, (len(scans), len(got), log_path.read_text())
        assert [r.msg.header.stamp_ns for r in got] == [r.msg.header.stamp_ns for r in scans]
        assert all(r.msg.header.source == "front" and r.msg.header.frame_id == frame for r in scans)
        # numbered by their place in the bag's /scan, as `perception legs` numbers them
        assert [r.msg.header.seq for r in scans] == [expected[r.msg.header.stamp_ns]["seq"] for r in scans]

        total = 0
        for r in got:
            msg: LocalizedDetections = r.msg
            row = expected[msg.header.stamp_ns]
            assert msg.header.frame_id == "map" and msg.camera_frame == frame and msg.detector == "laser-legs"
            assert len(msg.detections) == len(row["people"]), (msg.header.stamp_ns, msg.detections, row["people"])
            for det, person in zip(msg.detections, row["people"]):
                # `perception legs` prints 4 decimals: the node's values, rounded alike, are those
                assert abs(round(float(det.position[0]), 4) - person["x"]) <= 1e-6, (det.position, person)
                assert abs(round(float(det.position[1]), 4) - person["y"]) <= 1e-6, (det.position, person)
                assert abs(round(det.score, 4) - person["score"]) <= 1e-6, (det.score, person)
                assert det.position[2] == pytest.approx(0.9)  # the prior height above the floor
            total += len(msg.detections)
        assert total >= 20, "the slice was chosen for the people in it"

        # the recorder got the same scans: inspect lists them, and replayed they give the same people
        assert wait_recorded(client, KEYS, n, TIMEOUT) >= n
        stdout, stderr = stop_recording(recorder, TIMEOUT)
        assert recorder.returncode == 0, stderr
        assert f"{KEYS.scans('front')} [perception.LaserScan]: {n}" in stdout, stdout
        inspect = subprocess.run(_perception("inspect", str(recording)), capture_output=True, text=True,
                                 timeout=TIMEOUT, env=env)
        [row] = [line.split() for line in inspect.stdout.splitlines() if line.startswith(KEYS.scans("front"))]
        assert row[1:3] == ["perception.LaserScan", str(n)] and 9.0 < float(row[3]) < 11.0, inspect.stdout
        assert replay(recording) == n
        again = _collect(people_sub, n, TIMEOUT)
        assert [r.msg for r in again] == [r.msg for r in got]
    finally:
        for proc in (node, recorder):
            if proc.poll() is None:
                proc.terminate()
        try:
            assert node.wait(timeout=15) == 0, "the laser node must exit cleanly on SIGTERM"
        finally:
            for proc in (node, recorder):
                if proc.poll() is None:
                    proc.kill()
                proc.wait()
            log.close()

