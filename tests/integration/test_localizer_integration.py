"""The localizer as a real ``perception localizer`` process, over a real router."""

from __future__ import annotations

import os
import subprocess
import sys
import time
from collections.abc import Callable
from pathlib import Path

import numpy as np
import pytest

from common.messages.keys import FRAMES, RELIABLE, Keys
from common.transport.router_process import RouterProcess
from common.messages.schemas import (
    Detections,
    LocalizedDetections,
    RGBDFrame,
    ServiceStatus,
    TransformBatch,
)
from common.transport.zenoh import ZenohTransport
from tests.fixtures import localizer_scene as scene
from tests.fixtures.localizer_synthetic import Person
from tests.helpers.wait import wait_until

KEYS = Keys(robot="itest")


@pytest.mark.zenoh
def test_localizer_process_over_router(
    router: RouterProcess, zenoh_client: Callable[[], ZenohTransport], tmp_path: Path
) -> None:
    log = (tmp_path / "localizer.log").open("wb")
    proc = subprocess.Popen(
        [
            sys.executable,
            "-m",
            "perception",
            "localizer",
            "--robot",
            "itest",
            "--connect",
            router.endpoint,
            "--no-multicast-scouting",
            "--transform-wait",
            "1.0",
        ],
        stdout=log,
        stderr=subprocess.STDOUT,
        env={**os.environ, "RUST_LOG": "error",
             "PERCEPTION_LOCALIZER__BODY_HALF_DEPTH_M": "0"},  # the synthetic people are flat cut-outs
    )
    try:
        client = zenoh_client()
        out = client.subscribe(KEYS.localized("head"), LocalizedDetections, RELIABLE)
        frames = client.publisher(KEYS.frames("head"), RGBDFrame, FRAMES)
        dets = client.publisher(KEYS.detections("head"), Detections, RELIABLE)
        tf = client.publisher(KEYS.tf(), TransformBatch, RELIABLE)
        tf_static = client.publisher(KEYS.tf_static(), TransformBatch, RELIABLE)
        deadline = time.monotonic() + 60.0

        def localizer_up() -> bool:
            assert proc.poll() is None, (tmp_path / "localizer.log").read_text()
            return bool(client.alive(KEYS.alive("localizer")))

        wait_until(localizer_up, 60.0, interval=0.1, what="the localizer to come up")
        assert dets.wait_for_subscribers(30.0) and frames.wait_for_subscribers(30.0)

        people = [Person((0.4, 0.1, 3.0))]
        got = None
        seq = 0
        while got is None and time.monotonic() < deadline:  # frames may be dropped under load: resend
            seq += 1
            f = scene.frame(seq, people)
            tf_static.put(scene.tf_static())
            tf.put(scene.tf(f.header.stamp_ns - scene.S // 10))
            tf.put(scene.tf(f.header.stamp_ns + scene.S // 10))
            frames.put(f)
            dets.put(scene.detections(f, people))
            got = out.recv(timeout=2.0)
        assert got is not None, (tmp_path / "localizer.log").read_text()
        msg = got.msg
        assert msg.header.frame_id == "map" and msg.header.source == "head"
        truth = scene.map_position(people[0], msg.header.stamp_ns)
        assert np.linalg.norm(msg.detections[0].position - truth) < 0.01

        statuses = [m for _, m in client.query(KEYS.status("localizer"), timeout=5.0) if isinstance(m, ServiceStatus)]
        assert statuses and statuses[0].extra.get("boxes_localized", 0) >= 1
    finally:
        proc.terminate()
        try:
            assert proc.wait(timeout=15) == 0, "the localizer must exit cleanly on SIGTERM"
        finally:
            if proc.poll() is None:
                proc.kill()
            log.close()
