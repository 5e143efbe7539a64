"""perception camera as a real process over a real router: a folder of images becomes
frames/head, frame k with seq k, and the node exits at the end of the file; a device or a file
that does not open stops it at start-up with one clear message (exit status 2, no traceback)."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path
from typing import Any

import cv2
import numpy as np
import pytest

from common.messages.keys import Delivery, Keys
from common.messages.schemas import RGBDFrame
from tests.helpers.wait import wait_until

pytestmark = pytest.mark.zenoh
KEYS = Keys(robot="camz")


def _camera(router: Any, *args: str) -> list[str]:
    return [sys.executable, "-m", "perception", "camera", *args, "--robot", KEYS.robot, "--mode", "client", "--connect",
            router.endpoint, "--no-multicast-scouting"]


def test_a_folder_through_the_camera_process(router: Any, zenoh_client: Any, tmp_path: Path) -> None:
    folder = tmp_path / "frames"
    folder.mkdir()
    for k in range(6):
        cv2.imwrite(str(folder / f"{k:03d}.jpg"), np.full((120, 160, 3), 30 * k, np.uint8))
    app = zenoh_client()
    frames = app.subscribe(KEYS.frames("head"), RGBDFrame, Delivery(latest=False, queue=64, congestion="drop"))
    env = {**os.environ, "RUST_LOG": "error"}
    # the first frame goes out once the node has started; give it a subscriber first
    proc = subprocess.Popen(_camera(router, str(folder), "--fps", "20", "--start-ns", "1700000000000000000"),
                            stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True, env=env)
    got: list[RGBDFrame] = []

    def drained() -> bool:
        while (g := frames.try_recv()) is not None:
            got.append(g.msg)
        return proc.poll() is not None

    wait_until(drained, timeout=60, what="the camera process to play the folder and exit")
    out = proc.communicate()[0]
    drained()
    assert proc.returncode == 0, out
    assert "rough" in out  # no calibration: the intrinsics come from a field of view, and it says so
    assert [f.header.seq for f in got] == list(range(1, 7)), out
    assert [f.header.stamp_ns for f in got] == [1_700_000_000_000_000_000 + k * 50_000_000 for k in range(6)]
    assert got[0].rgb.shape == (120, 160, 3) and got[0].camera_info.width == 160


@pytest.mark.parametrize("source, says", [
    ("97", "camera 97 does not open"),
    ("missing.mp4", "no such file"),
    ("notes.mp4", "not a video"),
])
def test_a_source_that_does_not_open_is_one_clear_error(router: Any, tmp_path: Path, source: str, says: str) -> None:
    (tmp_path / "notes.mp4").write_bytes(b"not a video" * 50)
    done = subprocess.run(_camera(router, source), capture_output=True, text=True, timeout=60, cwd=tmp_path,
                          env={**os.environ, "RUST_LOG": "error"})
    assert done.returncode == 2, done.stdout + done.stderr
    assert says in done.stderr and "Traceback" not in done.stderr
