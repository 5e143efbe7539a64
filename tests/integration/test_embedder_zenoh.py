"""`perception embedder` as a real process behind a Zenoh router."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import time
from pathlib import Path
from typing import Callable

import numpy as np
import pytest

from common.messages.keys import FRAMES, RELIABLE, Keys
from common.transport.router_process import RouterProcess
from common.messages.schemas import Detections, Embeddings, RGBDFrame
from common.transport.zenoh import ZenohTransport
from services.embedder.core.colour import DIM as COLOUR_DIM
from tests.fixtures.embedder_scene import BOX_GREEN, BOX_RED, detections, frame

pytestmark = pytest.mark.zenoh


def _cuda() -> bool:
    try:
        import onnxruntime
    except ImportError:
        return False
    return "CUDAExecutionProvider" in onnxruntime.get_available_providers()


@pytest.mark.parametrize("backend", ["colour", pytest.param("onnx-cuda", marks=pytest.mark.skipif(
    not _cuda(), reason="needs onnxruntime-gpu with an NVIDIA GPU (CUDAExecutionProvider not available)"))])
def test_embedder_process_round_trip(router: RouterProcess, zenoh_client: Callable[[], ZenohTransport],
                                     backend: str, tmp_path: Path) -> None:
    """The node on the colour descriptor, and (on a GPU machine) on a Re-ID-sized ONNX network
    with ``--providers CUDAExecutionProvider``: the node refuses to start if CUDA does not."""
    keys = Keys(robot="embtest")
    client = zenoh_client()
    out = client.subscribe(keys.embeddings("head"), Embeddings, RELIABLE)
    env = {**os.environ, "RUST_LOG": "error"}
    extra: list[str] = []
    if backend == "onnx-cuda":
        from tests.fixtures.embedder_onnx_models import conv_model

        extra = ["--backend", "onnx", "--model", str(conv_model(tmp_path / "reid_like.onnx")),
                 "--providers", "CUDAExecutionProvider"]
    proc = subprocess.Popen([sys.executable, "-m", "perception", "embedder", "--robot", "embtest",
                             "--connect", router.endpoint, *extra], env=env, stdout=subprocess.PIPE,
                            stderr=subprocess.STDOUT)
    try:
        deadline = time.monotonic() + 60
        while not client.alive(keys.alive("embedder"), timeout=1.0):
            assert proc.poll() is None, proc.stdout.read().decode() if proc.stdout else ""
            assert time.monotonic() < deadline, "the embedder did not come up within 60 s"
        frames = client.publisher(keys.frames("head"), RGBDFrame, FRAMES)
        dets = client.publisher(keys.detections("head"), Detections, RELIABLE)
        got = None
        for seq in range(20):  # resend until the subscriptions have matched
            f = frame(seq=seq, stamp_ns=1_000_000_000 + seq * 33_000_000)
            frames.put(f)
            dets.put(detections(f, [BOX_RED, BOX_GREEN]))
            got = out.recv(timeout=3.0)
            if got is not None:
                break
        assert got is not None, "no embeddings came back"
        assert got.msg.indices.tolist() == [0, 1]
        if backend == "colour":
            assert got.msg.model.name == "colour" and got.msg.vectors.shape == (2, COLOUR_DIM)
        else:
            assert got.msg.model.name == "reid_like" and got.msg.vectors.shape == (2, 512)
            assert np.all(np.isfinite(got.msg.vectors))
    finally:
        proc.send_signal(signal.SIGINT)
        try:
            code = proc.wait(timeout=30)
        except subprocess.TimeoutExpired:
            proc.kill()
            raise
    assert code == 0
