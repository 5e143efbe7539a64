"""`perception simulate` as a real process publishing through a real router."""

from __future__ import annotations

import subprocess
import sys
from typing import Callable

import pytest

from common.messages.keys import FRAMES, RELIABLE, Keys
from common.transport.router_process import RouterProcess
from common.messages.schemas import PeopleGroundTruth, RGBDFrame
from common.transport.zenoh import ZenohTransport

pytestmark = pytest.mark.zenoh
KEYS = Keys(robot="simproc")


def test_simulate_process_publishes_frames_and_groundtruth(
    router: RouterProcess, zenoh_client: Callable[[], ZenohTransport]
) -> None:
    t = zenoh_client()
    frames = t.subscribe(KEYS.frames("head"), RGBDFrame, FRAMES)
    gt = t.subscribe(KEYS.groundtruth(), PeopleGroundTruth, RELIABLE)
    proc = subprocess.Popen(
        [
            sys.executable,
            "-m",
            "perception",
            "simulate",
            "--scenario",
            "still",
            "--duration",
            "0",
            "--fps",
            "10",
            "--width",
            "96",
            "--height",
            "72",
            "--robot",
            "simproc",
            "--mode",
            "client",
            "--connect",
            router.endpoint,
        ],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
    )
    try:
        got_frame = frames.recv(timeout=60.0)
        got_gt = gt.recv(timeout=60.0)
        assert got_frame is not None and got_gt is not None, proc.stderr.read() if proc.poll() is not None else ""
        assert got_frame.msg.rgb.shape == (72, 96, 3)
        assert {p.id for p in got_gt.msg.people} == {1, 2, 3}
        proc.terminate()
        assert proc.wait(timeout=30) == 0
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait(timeout=10)
