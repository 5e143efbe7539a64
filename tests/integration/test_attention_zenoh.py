"""perception attention as a real process over a real router: tracks in, HeadCommand out;
perception look sets and refuses targets."""

from __future__ import annotations

import os
import signal
import threading
import subprocess
import sys
import time

import numpy as np

from common.messages.keys import FRAMES, RELIABLE, Keys
from common.geometry.poses import OPTICAL_FROM_BODY, make_pose, rot_y
from common.messages.samples import rgbd_frame
from common.messages.schemas import HeadCommand, Header, RGBDFrame, TrackState, Tracks, TransformBatch
from tools.simulator.messages import transform

KEYS = Keys(robot="attz")


def test_attention_process_commands_the_head_and_answers_look(router, zenoh_client) -> None:  # type: ignore[no-untyped-def]
    zen = ["--robot", KEYS.robot, "--mode", "client", "--connect", router.endpoint, "--no-multicast-scouting"]
    env = {**os.environ, "RUST_LOG": "error"}
    node = subprocess.Popen([sys.executable, "-m", "perception", "-q", "attention", "--target", "nearest", *zen],
                            stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True, env=env)
    t = zenoh_client()
    tf_static = t.publisher(KEYS.tf_static(), TransformBatch, RELIABLE)
    tf = t.publisher(KEYS.tf(), TransformBatch, RELIABLE)
    frames = t.publisher(KEYS.frames("head"), RGBDFrame, FRAMES)
    tracks = t.publisher(KEYS.tracks(), Tracks, RELIABLE)
    commands = t.subscribe(KEYS.head_command(), HeadCommand, RELIABLE)
    stop = threading.Event()

    def publish() -> None:
        while not stop.wait(0.1):
            stamp = time.time_ns()
            tf_static.put(TransformBatch(header=Header(stamp_ns=stamp), transforms=[
                transform("head_link", "camera", make_pose(OPTICAL_FROM_BODY, (0.06, 0, 0.08)), stamp, static=True)]))
            tf.put(TransformBatch(header=Header(stamp_ns=stamp), transforms=[
                transform("map", "base_link", np.eye(4), stamp),
                transform("base_link", "head_link", make_pose(rot_y(0.1), (0.05, 0.0, 1.15)), stamp)]))
            frames.put(rgbd_frame(320, 240, stamp_ns=stamp))
            tracks.put(Tracks(header=Header(stamp_ns=stamp, frame_id="map"), tracks=[TrackState(
                id=3, status="confirmed", position=np.array([2.5, 1.0, 1.1]), velocity=np.zeros(3),
                covariance=np.eye(6), last_update_ns=stamp, hits=5, age_s=1.0)]))

    feeder = threading.Thread(target=publish, daemon=True)
    feeder.start()
    try:
        got: HeadCommand | None = None
        deadline = time.monotonic() + 30
        while got is None and time.monotonic() < deadline:
            if (m := commands.recv(timeout=0.2)) is not None and m.msg.mode == "track":
                got = m.msg
        assert got is not None and got.target_id == 3 and got.pan_rate > 0

        def look(*args: str) -> subprocess.CompletedProcess[str]:
            return subprocess.run([sys.executable, "-m", "perception", "-q", "look", *args, *zen, "--timeout", "5"],
                                  capture_output=True, text=True, timeout=60, env=env)

        unknown = look("42")
        assert unknown.returncode == 1 and "unknown track ID 42" in unknown.stdout and "3" in unknown.stdout
        chosen = look("3")
        assert chosen.returncode == 0 and "looking at ID 3" in chosen.stdout
    finally:
        stop.set()
        feeder.join(5)
        node.send_signal(signal.SIGINT)
        out, _ = node.communicate(timeout=30)
    assert node.returncode == 0, out
