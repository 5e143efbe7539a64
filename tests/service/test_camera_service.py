"""The camera node on the in-memory transport: a folder's frames with seq k and stamp
start + (k - 1) / fps, paced in real time or by the detector, the end of a file, and a live
stream that is lost and reopened with backoff."""

from __future__ import annotations

from pathlib import Path

import cv2
import numpy as np

from common.messages.keys import RELIABLE, Delivery, Keys
from common.messages.schemas import Detections, RGBDFrame
from common.runtime.service import Counters
from common.transport.memory import MemoryBus
from services.camera.config import CameraConfig
from services.camera.core.sources import Capture, SourceError, StreamLost
from services.camera.service import CameraService

KEYS = Keys()
START = 1_700_000_000_000_000_000


def _folder(path: Path, n: int) -> Path:
    path.mkdir()
    for k in range(n):
        cv2.imwrite(str(path / f"{k:03d}.png"), np.full((48, 64, 3), 10 * k, np.uint8))
    return path


class Rig:
    def __init__(self, config: CameraConfig, **kw: object) -> None:
        bus = MemoryBus()
        self.node = CameraService(bus.transport(), KEYS, config, Counters(), **kw)  # type: ignore[arg-type]
        app = bus.transport()
        self.frames = app.subscribe(KEYS.frames("head"), RGBDFrame, Delivery(latest=False, queue=100, congestion="drop"))
        self.detections = app.publisher(KEYS.detections("head"), Detections, RELIABLE)

    def got(self) -> list[RGBDFrame]:
        out = []
        while (g := self.frames.try_recv()) is not None:
            out.append(g.msg)
        return out


def test_a_folder_in_real_time_with_seq_and_stamps_by_frame_number(tmp_path: Path) -> None:
    rig = Rig(CameraConfig(source=str(_folder(tmp_path / "f", 4)), fps=10.0, start_ns=START, hfov_deg=90.0))
    rig.node.poll(100.0)
    assert abs(rig.node.deadline(100.0) - 0.1) < 1e-9  # the next frame is due 1 / fps later
    rig.node.poll(100.05)  # not yet
    rig.node.poll(100.1)
    rig.node.poll(100.2)
    rig.node.poll(100.3)
    rig.node.poll(100.4)  # the end of the folder
    got = rig.got()
    assert [f.header.seq for f in got] == [1, 2, 3, 4]
    assert [f.header.stamp_ns - START for f in got] == [0, 100_000_000, 200_000_000, 300_000_000]
    assert got[0].header.frame_id == "head_optical" and got[0].header.source == "head" and got[0].depth is None
    assert abs(got[0].camera_info.K[0, 0] - 32.0) < 1e-9  # 64 px across 90 degrees
    assert rig.node.finished


def test_max_pace_waits_for_the_detector(tmp_path: Path) -> None:
    rig = Rig(CameraConfig(source=str(_folder(tmp_path / "f", 3)), pace="max", start_ns=START, max_wait_s=5.0))
    rig.node.poll(0.0)
    rig.node.poll(1.0)
    first = rig.got()
    assert [f.header.seq for f in first] == [1], "the second frame waits for the first one's detections"
    rig.detections.put(Detections(header=first[0].header))
    rig.node.poll(1.1)
    assert [f.header.seq for f in rig.got()] == [2]
    rig.node.poll(7.0)  # no answer for max_wait_s: go on, counted
    assert [f.header.seq for f in rig.got()] == [3]
    assert rig.node.counters.extra["detector_timeouts"] == 1


class Flaky:
    """A live source that stops after two frames; reopening works on the second try."""

    fps = 30.0
    is_file = False
    intrinsics = None
    name = "flaky"

    def __init__(self, frames: int) -> None:
        self.left = frames
        self.closed = False

    def read(self) -> Capture | None:
        if self.left == 0:
            raise StreamLost("flaky stopped delivering frames")
        self.left -= 1
        return Capture(np.zeros((48, 64, 3), np.uint8), None, START + self.left, 0)

    def close(self) -> None:
        self.closed = True


def test_a_lost_stream_is_reported_and_reopened_with_backoff() -> None:
    opened = {"n": 0}

    def opener() -> Flaky:
        opened["n"] += 1
        if opened["n"] == 1:
            raise SourceError("camera 0 does not open")
        return Flaky(2)

    rig = Rig(CameraConfig(source="0", retry_initial_s=0.5), source=Flaky(2), opener=opener)
    for t in (0.0, 0.1, 0.2):
        rig.node.poll(t)
    assert [f.header.seq for f in rig.got()] == [1, 2]
    extra = rig.node.counters.extra
    assert extra["stream_lost"] == 1 and extra["connected"] == 0
    rig.node.poll(0.5)  # too early
    rig.node.poll(0.71)  # first reopen fails: the wait doubles
    assert extra["reopen_failed"] == 1 and opened["n"] == 1
    rig.node.poll(1.5)
    rig.node.poll(1.72)
    assert extra["reconnects"] == 1 and extra["connected"] == 1
    rig.node.poll(1.8)
    # the reopening poll reads at once; a live stream's seq goes on counting
    assert [f.header.seq for f in rig.got()] == [3, 4]


def test_the_depth_of_an_rgbd_source_and_its_intrinsics() -> None:
    from services.camera.core.sources import Intrinsics

    class RgbD:
        fps = 30.0
        is_file = False
        name = "rgbd"
        intrinsics = Intrinsics(64, 48, np.array([[60.0, 0, 32], [0, 60.0, 24], [0, 0, 1]]), np.zeros(0), "none")

        def read(self) -> Capture:
            return Capture(np.zeros((48, 64, 3), np.uint8), np.full((48, 64), 1500, np.uint16), START, 0)

        def close(self) -> None:
            pass

    rig = Rig(CameraConfig(backend="realsense", source=""), source=RgbD())
    rig.node.poll(0.0)
    (f,) = rig.got()
    assert f.depth is not None and f.depth.encoding == "16UC1" and abs(float(np.nanmean(f.depth.depth_m())) - 1.5) < 1e-6
    assert f.camera_info.K[0, 0] == 60.0 and f.header.stamp_ns == START
