"""``perception detector`` as a real process behind a real router: frames in, detections and status out."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import time
from pathlib import Path
from typing import Callable

import pytest

from common.messages.keys import FRAMES, RELIABLE, Keys
from common.transport.router_process import RouterProcess
from common.messages.samples import rgbd_frame
from common.messages.schemas import Detections, RGBDFrame, ServiceStatus
from common.transport.zenoh import ZenohTransport

pytestmark = pytest.mark.zenoh
ROOT = Path(__file__).resolve().parents[2]


def test_detector_process_round_trip(router: RouterProcess, zenoh_client: Callable[[], ZenohTransport],
                                     tmp_path: Path) -> None:
    keys = Keys(robot="zdet")
    log = (tmp_path / "detector.log").open("wb")
    proc = subprocess.Popen(
        [sys.executable, "-m", "perception", "detector", "--robot", "zdet", "--camera", "head",
         "--connect", router.endpoint, "--no-multicast-scouting"],
        cwd=ROOT, stdout=log, stderr=subprocess.STDOUT, env={**os.environ, "RUST_LOG": "error"})
    try:
        client = zenoh_client()
        detections = client.subscribe(keys.detections("head"), Detections, RELIABLE)
        frames = client.publisher(keys.frames("head"), RGBDFrame, FRAMES)
        assert frames.wait_for_subscribers(60.0), (tmp_path / "detector.log").read_text()
        got = None
        deadline = time.monotonic() + 60.0
        seq = 0
        while got is None and time.monotonic() < deadline:
            seq += 1
            frames.put(rgbd_frame(320, 240, seq=seq))
            got = detections.recv(2.0)
        assert got is not None, (tmp_path / "detector.log").read_text()
        assert got.msg.detector == "hog" and 1 <= got.msg.header.seq <= seq
        assert (got.msg.image_width, got.msg.image_height) == (320, 240)
        statuses: list[ServiceStatus] = []
        deadline = time.monotonic() + 30.0
        # the status may have been taken before the detection went out: ask until it counts it
        while not (statuses and statuses[0].published >= 1) and time.monotonic() < deadline:
            statuses = [m for _, m in client.query(keys.status("detector"), timeout=2.0) if isinstance(m, ServiceStatus)]
            if not (statuses and statuses[0].published >= 1):
                time.sleep(0.2)
        assert statuses and statuses[0].published >= 1 and "inference_ms" in statuses[0].extra
    finally:
        proc.send_signal(signal.SIGTERM)
        try:
            code = proc.wait(20.0)
        finally:
            if proc.poll() is None:
                proc.kill()
            log.close()
    assert code == 0, (tmp_path / "detector.log").read_text()
