"""The tracker as a real process over a real router: tracks, the track query, and
identities that survive killing and restarting the tracker."""

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

from common.messages.keys import RELIABLE, Keys
from common.transport.router_process import RouterProcess
from common.messages.schemas import Embeddings, Header, LocalizedDetection, LocalizedDetections, ModelCard, Tracks
from common.transport.zenoh import ZenohTransport
from tests.helpers.wait import wait_until

pytestmark = pytest.mark.zenoh

KEYS = Keys(robot="trackertest")
DIM = 16
LOOK = np.linspace(-1.0, 1.0, DIM)
LOOK /= np.linalg.norm(LOOK)
ROOT = Path(__file__).resolve().parents[2]


def start_tracker(router: RouterProcess, memory: Path, log: Path) -> subprocess.Popen[bytes]:
    cmd = [sys.executable, "-m", "perception", "tracker", "--connect", router.endpoint, "--no-multicast-scouting",
           "--robot", KEYS.robot, "--memory", str(memory)]
    env = {**os.environ, "RUST_LOG": "error"}
    return subprocess.Popen(cmd, stdout=log.open("ab"), stderr=subprocess.STDOUT, cwd=ROOT, env=env)


def feed_person(client: ZenohTransport, tracks_sub, seqs: range, stamp0: int) -> Tracks:  # type: ignore[no-untyped-def]
    """Publish one person's frames; wait for each frame's Tracks; return the last."""
    loc_pub = client.publisher(KEYS.localized("head"), LocalizedDetections, RELIABLE)
    emb_pub = client.publisher(KEYS.embeddings("head"), Embeddings, RELIABLE)
    assert loc_pub.wait_for_subscribers(20.0) and emb_pub.wait_for_subscribers(20.0)
    card = ModelCard(name="colour", dim=DIM, normalized=True)
    last = None
    for seq in seqs:
        header = Header(stamp_ns=stamp0 + seq * 33_333_333, frame_id="map", seq=seq, source="head")
        det = LocalizedDetection(index=0, bbox_xyxy=(0, 0, 10, 10), score=0.9, position=np.array([2.0, 0.5, 1.0]),
                                 cov=np.eye(3) * 0.01, depth_m=2.0)
        emb_pub.put(Embeddings(header=header, model=card, indices=np.array([0], np.int32),
                               vectors=LOOK[None].astype(np.float32)))
        loc_pub.put(LocalizedDetections(header=header, detections=[det]))
        deadline = time.monotonic() + 20.0
        while True:
            got = tracks_sub.recv(timeout=max(0.0, deadline - time.monotonic()))
            assert got is not None, f"no Tracks for frame {seq}"
            if got.msg.header.seq == seq:
                last = got.msg
                break
    loc_pub.close()
    emb_pub.close()
    assert last is not None
    return last


def stop(proc: subprocess.Popen[bytes]) -> int:
    proc.send_signal(signal.SIGTERM)
    return proc.wait(timeout=30)


def test_tracker_process_tracks_answers_queries_and_keeps_ids_across_restart(
        router: RouterProcess, zenoh_client: Callable[[], ZenohTransport], tmp_path: Path) -> None:
    memory = tmp_path / "id-memory.npz"
    client = zenoh_client()
    tracks_sub = client.subscribe(KEYS.tracks(), Tracks, RELIABLE)
    proc = start_tracker(router, memory, tmp_path / "tracker.log")
    try:
        wait_until(lambda: bool(client.alive(KEYS.alive("tracker"))), 30.0, what="the tracker's liveliness token")
        last = feed_person(client, tracks_sub, range(0, 5), 1_700_000_000_000_000_000)
        assert [t.id for t in last.tracks] == [1] and last.appearance_available
        replies = client.query(KEYS.track_query() + "?id=1", timeout=10.0)
        assert len(replies) == 1 and isinstance(replies[0][1], Tracks)
        np.testing.assert_allclose(replies[0][1].tracks[0].position[:2], [2.0, 0.5], atol=0.05)
        assert replies[0][1].tracks[0].status == "confirmed"
        assert client.query(KEYS.track_query() + "?id=7", timeout=10.0)[0][1].tracks == []
        # the live track's gallery is written within memory_save_period_s (2 s) ...
        wait_until(memory.exists, 30.0, what="the ID memory file")
    finally:
        proc.kill()  # ... so even a crash (SIGKILL) keeps the identity
        proc.wait(timeout=30)
    wait_until(lambda: not client.alive(KEYS.alive("tracker")), 30.0, what="the token to vanish")

    # a restarted tracker, seeing the same person much later, gives the same ID
    proc = start_tracker(router, memory, tmp_path / "tracker.log")
    try:
        wait_until(lambda: bool(client.alive(KEYS.alive("tracker"))), 30.0, what="the restarted tracker's token")
        last = feed_person(client, tracks_sub, range(1000, 1004), 1_700_000_100_000_000_000)
        assert [t.id for t in last.tracks] == [1]
    finally:
        code = stop(proc)
    assert code == 0, (tmp_path / "tracker.log").read_text()
