"""The detector service through the in-memory transport: headers, latest-only frames, counted failures."""

from __future__ import annotations

import threading
import time

import numpy as np
import pytest
from pydantic import ValidationError

from common.messages.keys import FRAMES, RELIABLE, Keys
from common.transport.memory import MemoryBus
from common.runtime.service import Counters, ServiceRuntime
from common.messages.samples import camera_info, rgbd_frame
from common.geometry.poses import OPTICAL_FROM_BODY, make_pose, rot_y
from common.messages.schemas import Detections, Header, Image, RGBDFrame, TransformBatch
from services.detector.config import DetectorConfig, build_detector
from services.detector.core.boxes import DetectorError
from services.detector.core.ground import initial_plane
from services.detector.service import DetectorService
from tests.fixtures.detector_synthetic import Block, render_depth, scene_intrinsics, with_head
from tests.helpers.fixed_detector import FixedDetector
from tools.simulator.messages import transform

KEYS = Keys(robot="testbot")


def step(service: DetectorService, timeout: float) -> Detections | None:
    """Wait up to ``timeout`` s for a frame, then poll once; the published message or None."""
    service.io.wait(timeout)
    out = service.poll(time.monotonic())
    return out[0] if out else None


def make(bus: MemoryBus, config: DetectorConfig | None = None, detector: object | None = None):  # type: ignore[no-untyped-def]
    config = config or DetectorConfig(camera="head")
    counters = Counters()
    service = DetectorService(bus.transport(), KEYS, config, counters, detector=detector)  # type: ignore[arg-type]
    client = bus.transport()
    frames = client.publisher(KEYS.frames(config.camera), RGBDFrame, FRAMES)
    out = client.subscribe(KEYS.detections(config.camera), Detections, RELIABLE)
    return service, counters, frames, out


def test_detections_carry_the_frame_header(memory_bus: MemoryBus) -> None:
    service, counters, frames, out = make(memory_bus, detector=FixedDetector())
    frame = rgbd_frame(320, 240, seq=17, stamp_ns=1_700_000_000_123_456_789)
    frames.put(frame)
    step(service, 5.0)
    got = out.recv(5.0)
    assert got is not None
    msg = got.msg
    assert msg.header == frame.header
    assert (msg.image_width, msg.image_height) == (320, 240)
    assert msg.detector == "fixed" and msg.inference_ms is not None and msg.inference_ms >= 0
    assert [d.index for d in msg.detections] == [0, 1]
    assert msg.detections[0].bbox_xyxy == (10.0, 20.0, 50.0, 120.0) and msg.detections[0].score == pytest.approx(0.9)
    assert [d.posture for d in msg.detections] == ["standing", "sitting"]  # the backend's postures go along
    assert [d.depth_m for d in msg.detections] == [2.5, 4.0]  # and each person's own depth
    assert [d.stature_m for d in msg.detections] == [1.78, None]  # and the standing one's stature (NaN: None)
    assert counters.extra["frames_processed"] == 1 and "inference_ms" in counters.extra


def test_real_hog_backend_end_to_end(memory_bus: MemoryBus) -> None:
    service, _, frames, out = make(memory_bus)
    frames.put(rgbd_frame(320, 240, seq=3))
    assert step(service, 5.0) is not None
    got = out.recv(5.0)
    assert got is not None and got.msg.detector == "hog" and got.msg.header.seq == 3


def test_slow_model_only_sees_the_newest_frame(memory_bus: MemoryBus) -> None:
    detector = FixedDetector(block_first=True)
    service, counters, frames, out = make(memory_bus, detector=detector)
    runtime = ServiceRuntime("detector", memory_bus.transport(), KEYS, counters=counters, io=service.io)
    stop = threading.Event()

    def loop() -> None:
        while not stop.is_set():
            step(service, 0.2)

    worker = threading.Thread(target=loop, daemon=True)
    frames.put(rgbd_frame(160, 120, seq=1))
    worker.start()
    try:
        assert detector.entered.wait(10.0)
        for seq in range(2, 7):  # arrive while the model is busy with frame 1
            frames.put(rgbd_frame(160, 120, seq=seq))
        detector.release.set()
        seqs = []
        while 6 not in seqs:
            got = out.recv(10.0)
            assert got is not None, f"no detections after {seqs}"
            seqs.append(got.msg.header.seq)
    finally:
        stop.set()
        worker.join(5.0)
    assert seqs == [1, 6]
    assert detector.calls == 2
    assert counters.extra["dropped_stale"] == 4
    status = runtime.status()
    assert status.dropped == 4 and status.received == 6 and status.published == 2


def test_depth_backend_counts_frames_without_depth(memory_bus: MemoryBus) -> None:
    config = DetectorConfig(backend="depth")
    service, counters, frames, out = make(memory_bus, config)
    header = Header(stamp_ns=5, seq=1, source="head", frame_id="camera")
    rgb_only = RGBDFrame(header=header, rgb=Image.from_array(np.zeros((120, 160, 3), np.uint8), "rgb8", header),
                         camera_info=camera_info(160, 120))
    frames.put(rgb_only)
    assert step(service, 5.0) is None
    assert counters.extra["dropped_no_depth"] == 1
    assert out.try_recv() is None


def test_depth_backend_end_to_end(memory_bus: MemoryBus) -> None:
    config = DetectorConfig(backend="depth", depth={"camera_height_m": 1.2})  # type: ignore[arg-type]
    service, _, frames, out = make(memory_bus, config)
    K = scene_intrinsics(320, 240)
    depth, rgb = render_depth(with_head(Block(1.0, 3.0, 0.5, 1.8, 0.3)), K, 320, 240, 1.2, 0.0)  # off-axis: its side shows (a box seen square-on is flat)
    header = Header(stamp_ns=9, seq=2, source="head", frame_id="camera")
    info = camera_info(320, 240)
    info.K[:] = K
    frame = RGBDFrame(header=header, rgb=Image.from_array(rgb, "rgb8", header),
                      depth=Image.from_array(np.nan_to_num(depth * 1000).astype(np.uint16), "16UC1", header),
                      camera_info=info)
    frames.put(frame)
    step(service, 5.0)
    got = out.recv(5.0)
    assert got is not None and got.msg.detector == "depth" and len(got.msg.detections) == 1
    assert got.msg.detections[0].posture == "standing"  # 1.8 m tall on the floor: Basso/Munaro's standing rule
    # its own depth, from its points: the front face, 2.85 m along the optical axis (the block is 0.3 m deep)
    assert got.msg.detections[0].depth_m == pytest.approx(2.85, abs=0.08)
    assert got.msg.detections[0].stature_m == pytest.approx(1.8, abs=0.04)  # its top above the floor


def test_undecodable_image_is_counted_and_skipped(memory_bus: MemoryBus) -> None:
    service, counters, frames, out = make(memory_bus, detector=FixedDetector())
    header = Header(stamp_ns=1, seq=1, source="head")
    broken = RGBDFrame(header=header, camera_info=camera_info(64, 48),
                       rgb=Image(header=header, encoding="jpeg", dtype="uint8", shape=(48, 64, 3), data=b"not a jpeg"))
    frames.put(broken)
    assert step(service, 5.0) is None
    assert counters.extra["dropped_bad_image"] == 1
    frames.put(rgbd_frame(64, 48, seq=2))  # and it keeps going
    assert step(service, 5.0) is not None


def test_wrong_message_type_is_counted_invalid(memory_bus: MemoryBus) -> None:
    service, _, _, _ = make(memory_bus, detector=FixedDetector())
    wrong = memory_bus.transport().publisher(KEYS.frames("head"), Image, FRAMES)
    header = Header(stamp_ns=1)
    wrong.put(Image.from_array(np.zeros((4, 4, 3), np.uint8), "rgb8", header))
    assert step(service, 0.5) is None
    assert service.frames.stats.invalid == 1


def test_detector_errors_are_counted(memory_bus: MemoryBus) -> None:
    class Failing(FixedDetector):
        def detect(self, rgb, depth=None, camera=None):  # type: ignore[no-untyped-def]
            raise DetectorError("image must be non-empty")

    service, counters, frames, _ = make(memory_bus, detector=Failing())
    frames.put(rgbd_frame(64, 48))
    assert step(service, 5.0) is None
    assert counters.extra["dropped_detector_error"] == 1


def test_config_refuses_depth_without_depth() -> None:
    with pytest.raises(ValidationError, match="depth_available"):
        DetectorConfig(backend="depth", depth_available=False)
    with pytest.raises(ValidationError, match="yolo.model"):
        DetectorConfig(backend="yolo-onnx")
    with pytest.raises(ValidationError, match="darknet.cfg"):
        DetectorConfig(backend="darknet", darknet={"cfg": "a.cfg"})  # type: ignore[arg-type]
    with pytest.raises(ValidationError, match="min_height_m"):
        DetectorConfig(depth={"min_height_m": 2.5})  # type: ignore[arg-type]
    with pytest.raises(ValidationError):
        DetectorConfig(hog={"upsampling": 2})  # type: ignore[arg-type]


def test_missing_model_fails_at_build(tmp_path) -> None:  # type: ignore[no-untyped-def]
    config = DetectorConfig(backend="yolo-onnx", yolo={"model": tmp_path / "absent.onnx"})  # type: ignore[arg-type]
    with pytest.raises(DetectorError, match="absent.onnx does not exist"):
        build_detector(config)


def _depth_frame(stamp_ns: int, seq: int, tilt_deg: float) -> RGBDFrame:
    K = scene_intrinsics(320, 240)
    depth, rgb = render_depth(with_head(Block(1.0, 3.0, 0.5, 1.8, 0.3)), K, 320, 240, 1.2, tilt_deg)
    header = Header(stamp_ns=stamp_ns, seq=seq, source="head", frame_id="camera")
    info = camera_info(320, 240)
    info.K[:] = K
    return RGBDFrame(header=header, rgb=Image.from_array(rgb, "rgb8", header),
                     depth=Image.from_array(np.nan_to_num(depth * 1000).astype(np.uint16), "16UC1", header),
                     camera_info=info)


def test_depth_backend_takes_the_floor_from_the_transforms(memory_bus: MemoryBus) -> None:
    # the head pitches 20 deg down; the config says level. The transforms base_link -> camera give
    # the floor at the frame's stamp; a frame with no transform near its stamp is counted and the
    # detector tracks the floor alone
    config = DetectorConfig(backend="depth", depth={"camera_height_m": 1.2, "tilt_deg": 0.0})  # type: ignore[arg-type]
    service, counters, frames, out = make(memory_bus, config)
    assert service.buffer is not None and "floor from base_link" in service.describe()
    stamp = 10**18
    head = make_pose(rot_y(np.deg2rad(20.0)) @ OPTICAL_FROM_BODY, (0.0, 0.0, 1.2))
    memory_bus.transport().publisher(KEYS.tf(), TransformBatch, RELIABLE).put(TransformBatch(
        header=Header(stamp_ns=stamp), transforms=[transform("base_link", "camera", head, stamp)]))
    frames.put(_depth_frame(stamp, 1, 20.0))
    step(service, 5.0)
    got = out.recv(5.0)
    assert got is not None and len(got.msg.detections) == 1
    assert counters.extra["floor_from_transforms"] == 1 and "floor_estimated" not in counters.extra
    truth = initial_plane(1.2, 20.0)
    plane = service.detector.plane  # type: ignore[attr-defined]
    assert plane.angle_to(truth) < np.deg2rad(0.5) and abs(plane.offset - 1.2) < 0.02
    frames.put(_depth_frame(stamp + 10**9, 2, 20.0))  # 1 s later: no transform that recent
    step(service, 5.0)
    assert out.recv(5.0) is not None
    assert counters.extra["floor_estimated"] == 1


def test_floor_frame_off_or_a_backend_without_a_floor_reads_no_transforms(memory_bus: MemoryBus) -> None:
    off, _, _, _ = make(memory_bus, DetectorConfig(backend="depth", floor_frame=""))
    hog, _, _, _ = make(memory_bus, DetectorConfig(backend="hog"))
    assert off.buffer is None and hog.buffer is None
