"""The embedder service through the in-memory transport."""

from __future__ import annotations

import time

import numpy as np
import pytest

from common.messages.samples import camera_info
from common.messages.schemas import Detection, Detections, Header, Image, RGBDFrame
from services.embedder.config import EmbedderConfig
from services.embedder.core import ColourDescriptor
from tests.fixtures.embedder_scene import BOX_GREEN, BOX_RED, detections, frame, scene
from tests.helpers.embedder_rig import Rig


def test_pairs_frame_and_detections_and_maps_indices() -> None:
    rig = Rig()
    f = frame(seq=7, stamp_ns=1_000_000_000)
    rig.frames.put(f)
    boxes = [BOX_RED, (50.0, 50.0, 50.0, 90.0), (300.0, 0.0, 400.0, 100.0), BOX_GREEN]
    rig.dets.put(detections(f, boxes, first_index=3))
    assert len(rig.service.poll(time.monotonic())) == 1
    (msg,) = rig.received()
    assert msg.header == f.header
    assert msg.indices.tolist() == [3, 6]  # the empty box (4) and the one outside (5) are skipped
    assert rig.counters.extra["empty_boxes"] == 2
    assert msg.model.name == "colour" and msg.model.dim == 224 and msg.model.thresholds is not None
    direct = ColourDescriptor().embed([scene(7)[10:138, 20:84], scene(7)[20:148, 150:214]])
    np.testing.assert_allclose(msg.vectors, direct, atol=1e-6)


def test_detections_before_their_frame_wait_for_it() -> None:
    rig = Rig()
    f = frame(seq=1, stamp_ns=5_000_000_000)
    rig.dets.put(detections(f, [BOX_RED]))
    assert len(rig.service.poll(time.monotonic())) == 0
    rig.frames.put(f)
    assert len(rig.service.poll(time.monotonic())) == 1
    assert rig.received()[0].indices.tolist() == [0]


def test_empty_detections_publish_empty_embeddings() -> None:
    rig = Rig()
    f = frame(seq=2, stamp_ns=10)
    rig.frames.put(f)
    rig.dets.put(detections(f, []))
    rig.service.poll(time.monotonic())
    (msg,) = rig.received()
    assert msg.indices.shape == (0,) and msg.vectors.shape[0] == 0


def test_boxes_in_another_resolution_are_rescaled() -> None:
    rig = Rig()
    f = frame(seq=3, stamp_ns=10)
    rig.frames.put(f)
    half = tuple(v / 2 for v in BOX_GREEN)
    rig.dets.put(detections(f, [half], size=(120, 80)))  # detector ran on a half-size image
    rig.service.poll(time.monotonic())
    (msg,) = rig.received()
    np.testing.assert_allclose(msg.vectors[0], ColourDescriptor().embed([scene(3)[20:148, 150:214]])[0], atol=1e-6)
    assert rig.counters.extra["rescaled_frames"] == 1


def test_undecodable_image_is_counted_not_fatal() -> None:
    rig = Rig()
    header = Header(stamp_ns=10, frame_id="camera", seq=4, source="head")
    bad = RGBDFrame(header=header, rgb=Image(header=header, encoding="jpeg", dtype="uint8", shape=(160, 240, 3),
                                             data=b"not a jpeg"), camera_info=camera_info(240, 160, 10))
    rig.frames.put(bad)
    rig.dets.put(detections(bad, [BOX_RED]))
    assert len(rig.service.poll(time.monotonic())) == 0
    assert rig.counters.invalid == 1
    good = frame(seq=5, stamp_ns=20)
    rig.frames.put(good)
    rig.dets.put(detections(good, [BOX_RED]))
    assert len(rig.service.poll(time.monotonic())) == 1


class SlowBackend:
    """Wraps a backend; while the first frame is being embedded, the camera moves on by 2 s."""

    def __init__(self, rig_frames: object, later: RGBDFrame) -> None:
        self.inner = ColourDescriptor()
        self.card = self.inner.card
        self.publisher = rig_frames
        self.later = later
        self.calls = 0

    def embed(self, crops: list[np.ndarray]) -> np.ndarray:
        self.calls += 1
        if self.calls == 1:
            self.publisher.put(self.later)  # type: ignore[attr-defined]
        return self.inner.embed(crops)


def test_stale_work_is_dropped_not_queued() -> None:
    bus_frames = [frame(seq=i, stamp_ns=i * 100_000_000) for i in range(1, 4)]
    later = frame(seq=30, stamp_ns=3_000_000_000)
    rig = Rig(config=EmbedderConfig(max_lag_s=0.5))
    backend = SlowBackend(rig.frames, later)
    rig.service.backend = backend  # type: ignore[assignment]
    for f in bus_frames:
        rig.service.add_frame(f)
        rig.dets.put(detections(f, [BOX_RED]))
    assert len(rig.service.poll(time.monotonic())) == 1
    assert backend.calls == 1  # frames 2 and 3 were 2.8 s behind the camera when their turn came
    assert rig.counters.extra["dropped_stale"] == 2 and rig.counters.dropped == 2
    rig.dets.put(detections(later, [BOX_GREEN]))
    assert len(rig.service.poll(time.monotonic())) == 1
    assert [m.header.seq for m in rig.received()] == [1, 30]


def test_frame_buffer_is_bounded() -> None:
    rig = Rig(config=EmbedderConfig(frame_buffer=2, max_lag_s=100))
    fs = [frame(seq=i, stamp_ns=i) for i in range(4)]
    for f in fs:
        rig.service.add_frame(f)
    rig.dets.put(detections(fs[0], [BOX_RED]))  # its frame fell out of the buffer
    rig.dets.put(detections(fs[3], [BOX_RED]))
    assert len(rig.service.poll(time.monotonic())) == 1
    assert rig.received()[0].header.seq == 3


def test_onnx_backend_needs_a_path() -> None:
    from pydantic import ValidationError

    with pytest.raises(ValidationError, match="onnx.path"):
        EmbedderConfig(backend="onnx")


def test_run_loop_serves_until_shutdown() -> None:
    import threading

    from common.runtime.service import Shutdown

    rig = Rig()
    shutdown = Shutdown()
    worker = threading.Thread(target=rig.service.run, args=(shutdown,), daemon=True)
    worker.start()
    try:
        for seq in range(3):
            f = frame(seq=seq, stamp_ns=seq * 33_000_000)
            rig.frames.put(f)
            rig.dets.put(detections(f, [BOX_RED, BOX_GREEN]))
            got = rig.out.recv(timeout=10.0)
            assert got is not None and got.msg.header.seq == seq and got.msg.indices.tolist() == [0, 1]
    finally:
        shutdown.set()
        worker.join(timeout=10.0)
    assert not worker.is_alive()
    rig.service.close()
    assert rig.service.frames_sub.closed and rig.service.pub.closed


def test_duplicate_detection_indices_are_rejected() -> None:
    rig = Rig()
    f = frame(seq=9, stamp_ns=10)
    rig.frames.put(f)
    dets = Detections(header=f.header.model_copy(), detections=[
        Detection(index=0, bbox_xyxy=BOX_RED, score=0.9), Detection(index=0, bbox_xyxy=BOX_GREEN, score=0.9)])
    rig.dets.put(dets)
    assert len(rig.service.poll(time.monotonic())) == 0
    assert rig.counters.invalid == 1


def test_configured_thresholds_replace_the_card_ones() -> None:
    from services.embedder.config import ThresholdsConfig, build_backend

    backend = build_backend(EmbedderConfig(thresholds=ThresholdsConfig(t_lower=0.2, t_upper=0.7, t_recover=0.3)))
    rig = Rig(backend=backend)
    t = rig.service.card.thresholds
    assert t is not None and (t.t_lower, t.t_upper, t.t_recover) == (0.2, 0.7, 0.3)
