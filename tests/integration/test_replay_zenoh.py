"""Record and replay as real processes through a real router."""

from __future__ import annotations

import subprocess
import sys
import time
from pathlib import Path
from typing import Any, Callable

import numpy as np
import pytest

from common.messages.keys import Delivery, Keys
from common.transport.router_process import RouterProcess
from common.messages.samples import rgbd_frame
from common.messages.schemas import Detection, Detections, Header, Message, RGBDFrame, Transform, TransformBatch
from common.transport.base import Received, Subscription
from common.transport.zenoh import ZenohTransport
from tests.fixtures.replay_bags import SyntheticRun, write_bag
from tests.helpers.recording import stop_recording, wait_recorded
from tools.replay.recorder import McapRecorder
from tools.replay.sources import open_source

pytestmark = pytest.mark.zenoh

KEYS = Keys()
FIFO = Delivery(latest=False, queue=4096, congestion="block")
TIMEOUT = 90.0


def _perception(*args: str, router: RouterProcess) -> list[str]:
    return [sys.executable, "-m", "perception", "-q", *args, "--connect", router.endpoint]


def _replay(path: Path, router: RouterProcess, *extra: str) -> subprocess.CompletedProcess[str]:
    cmd = _perception("replay", str(path), "--wait-subscribers", "30", "--no-progress", *extra, router=router)
    proc = subprocess.run(cmd, capture_output=True, text=True, timeout=TIMEOUT)
    assert proc.returncode == 0, proc.stdout + proc.stderr
    assert "Traceback" not in proc.stderr
    return proc


def _collect(sub: Subscription[Any], n: int, skip: Callable[[Received[Any]], bool] = lambda r: False) -> list[Received[Any]]:
    """The next ``n`` messages (waiting up to TIMEOUT in total)."""
    deadline = time.monotonic() + TIMEOUT
    out: list[Received[Any]] = []
    while len(out) < n and time.monotonic() < deadline:
        r = sub.recv(timeout=0.5)
        if r is not None and not skip(r):
            out.append(r)
    return out


def _is_status(r: Received[Any]) -> bool:
    return "/status/" in r.key


@pytest.mark.parametrize("kind", ["ros1", "ros2-sqlite3", "ros2-mcap"])
def test_bag_replay_through_router(tmp_path: Path, router: RouterProcess,
                                   zenoh_client: Callable[[], ZenohTransport], kind: str) -> None:
    run = SyntheticRun(frames=20, period_ns=50_000_000)
    bag = write_bag(tmp_path / ("run.bag" if kind == "ros1" else "run"), run, kind)  # type: ignore[arg-type]
    with open_source(bag) as src:
        expected = [(it.key, it.message) for it in src.items()]
    expected.sort(key=lambda km: km[1].header.stamp_ns)  # stable: same-stamp order kept
    sub = zenoh_client().subscribe(KEYS.all(), None, FIFO)
    proc = _replay(bag, router)
    got = _collect(sub, len(expected), skip=_is_status)
    assert len(got) == len(expected), proc.stdout
    # same content, same per-key order
    for key in {k for k, _ in expected}:
        assert [r.msg for r in got if r.key == key] == [m for k, m in expected if k == key], key
    frames = [r for r in got if r.key == KEYS.frames("head")]
    assert len(frames) == run.frames and all(isinstance(r.msg, RGBDFrame) for r in frames)
    np.testing.assert_array_equal(frames[7].msg.rgb.to_array(), run.rgb(7))
    assert "skipped /chatter" in proc.stdout
    # relative timing: never early, and not far behind (generous: the machine is shared)
    stamp0, recv0 = frames[0].msg.header.stamp_ns, frames[0].recv_ns
    lags = [((r.recv_ns - recv0) - (r.msg.header.stamp_ns - stamp0)) / 1e9 for r in frames]
    assert min(lags) > -0.03, lags
    assert float(np.median(lags)) < 0.5, lags


def _transform_batch(stamp: int, x: float) -> TransformBatch:
    return TransformBatch(header=Header(stamp_ns=stamp, source="tf"), transforms=[Transform(
        parent_frame="odom", child_frame="base_link", stamp_ns=stamp, translation=np.array([x, 0.0, 0.0]),
        rotation_xyzw=np.array([0.0, 0.0, 0.0, 1.0]))])


def test_record_then_replay_is_lossless_and_ordered(tmp_path: Path, router: RouterProcess,
                                                    zenoh_client: Callable[[], ZenohTransport]) -> None:
    out = tmp_path / "run.mcap"
    recorder = subprocess.Popen(_perception("record", "--output", str(out), router=router),
                                stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    try:
        client = zenoh_client()
        pubs = {"frames": client.publisher(KEYS.frames("head"), RGBDFrame, FIFO),
                "det": client.publisher(KEYS.detections("head"), Detections, FIFO),
                "tf": client.publisher(KEYS.tf(), TransformBatch, FIFO)}
        for p in pubs.values():
            assert p.wait_for_subscribers(TIMEOUT), "the recorder did not subscribe"
        client.session.put(KEYS.detections("head"), b"not a perception message")  # counted, not recorded
        sent: list[tuple[str, Message]] = []
        t0 = 1_700_000_000_000_000_000
        for i in range(15):
            stamp = t0 + i * 20_000_000
            frame = rgbd_frame(64, 48, seq=i, stamp_ns=stamp, seed=i)
            det = Detections(header=frame.header, detections=[Detection(index=0, bbox_xyxy=(1.0, 2.0, 30.0, 40.0), score=0.5 + i / 100)])
            for key, pub, msg in ((pubs["tf"].key, pubs["tf"], _transform_batch(stamp, i * 0.1)),
                                  (pubs["frames"].key, pubs["frames"], frame), (pubs["det"].key, pubs["det"], det)):
                pub.put(msg)
                sent.append((key, msg))
        assert wait_recorded(client, KEYS, len(sent), TIMEOUT) >= len(sent)
        stdout, stderr = stop_recording(recorder, TIMEOUT)
    finally:
        if recorder.poll() is None:
            recorder.kill()
            recorder.wait()
    assert recorder.returncode == 0, stderr
    assert f"{KEYS.frames('head')} [perception.RGBDFrame]: 15" in stdout, stdout
    assert "1 invalid" in stdout, stdout
    sub = zenoh_client().subscribe(KEYS.all(), None, FIFO)
    _replay(out, router)
    got = _collect(sub, len(sent), skip=_is_status)
    assert [(r.key, r.msg) for r in got] == sent


def test_rate_two_takes_about_half_as_long(tmp_path: Path, router: RouterProcess,
                                           zenoh_client: Callable[[], ZenohTransport]) -> None:
    path = tmp_path / "tf.mcap"
    t0 = 1_700_000_000_000_000_000
    with McapRecorder(path) as rec:
        for i in range(11):  # 2 s of recorded time
            rec.write(KEYS.tf(), _transform_batch(t0 + i * 200_000_000, float(i)), t0 + i * 200_000_000)
    sub = zenoh_client().subscribe(KEYS.tf(), TransformBatch, FIFO)
    spans = {}
    for rate in ("1", "2"):
        _replay(path, router, "--rate", rate)
        got = _collect(sub, 11)
        assert len(got) == 11
        spans[rate] = (got[-1].recv_ns - got[0].recv_ns) / 1e9
    # the pacer never publishes early, so the lower bounds are firm; the upper ones allow for load
    assert 1.9 < spans["1"] < 3.5, spans
    assert 0.95 < spans["2"] < 1.7, spans


def test_a_bag_whose_images_cannot_be_converted_fails_naming_the_encoding(tmp_path: Path, router: RouterProcess) -> None:
    from rosbags.rosbag1 import Writer as Writer1
    from rosbags.typesys import Stores, get_typestore

    store = get_typestore(Stores.ROS1_NOETIC)
    T = store.types
    bag = tmp_path / "yuv.bag"
    with Writer1(bag) as w:
        conn = w.add_connection("/camera/rgb/image_raw", "sensor_msgs/msg/Image", typestore=store)
        for i in range(3):
            stamp = T["builtin_interfaces/msg/Time"](sec=100 + i, nanosec=0)
            img = T["sensor_msgs/msg/Image"](header=T["std_msgs/msg/Header"](seq=i, stamp=stamp, frame_id="cam"),
                                             height=2, width=2, encoding="yuv422", is_bigendian=0, step=4,
                                             data=np.zeros(8, np.uint8))
            w.write(conn, (100 + i) * 10**9, store.serialize_ros1(img, "sensor_msgs/msg/Image"))
    cmd = _perception("replay", str(bag), "--wait-subscribers", "0", "--no-progress", router=router)
    proc = subprocess.run(cmd, capture_output=True, text=True, timeout=TIMEOUT)
    assert proc.returncode == 2 and "Traceback" not in proc.stderr, proc.stderr
    assert f"perception: error: {bag}: nothing was replayed" in proc.stderr
    assert "image encoding 'yuv422' is not supported" in proc.stderr


def test_a_truncated_recording_is_replayed_up_to_the_cut_then_fails(tmp_path: Path, router: RouterProcess,
                                                                    zenoh_client: Callable[[], ZenohTransport]) -> None:
    path = tmp_path / "cut.mcap"
    t0 = 1_700_000_000_000_000_000
    with McapRecorder(path, compression="none", chunk_size=32_000) as rec:
        for i in range(40):
            rec.write(KEYS.frames("head"), rgbd_frame(64, 48, seq=i, stamp_ns=t0 + i * 1_000_000, seed=i), t0 + i * 1_000_000)
    path.write_bytes(path.read_bytes()[: path.stat().st_size * 2 // 3])
    sub = zenoh_client().subscribe(KEYS.frames("head"), None, FIFO)
    # --max: publishers block rather than drop, so a loaded machine loses no frame of the
    # 1 ms-spaced recording (at recorded speed, frames are dropped on congestion by design).
    cmd = _perception("replay", str(path), "--max", "--wait-subscribers", "30", "--no-progress", router=router)
    proc = subprocess.run(cmd, capture_output=True, text=True, timeout=TIMEOUT)
    assert proc.returncode == 2 and "Traceback" not in proc.stderr, proc.stderr
    assert f"perception: error: {path}: truncated after" in proc.stderr, proc.stderr
    replayed = int(proc.stdout.split("replayed ", 1)[1].split()[0])
    assert 0 < replayed < 40, proc.stdout
    got = _collect(sub, replayed)
    assert [r.msg.header.seq for r in got] == list(range(replayed))
