"""The localizer service driven through the in-memory transport."""

from __future__ import annotations

import logging
import threading
import time

import numpy as np
import pytest

from common.transport.memory import MemoryBus
from common.runtime.service import Shutdown
from common.messages.schemas import (
    Header,
    Transform,
    TransformBatch,
)
from services.localizer.config import LocalizerConfig, StaticTransformConfig
from tests.fixtures import localizer_scene as scene
from tests.fixtures.localizer_scene import T0, S
from tests.fixtures.localizer_synthetic import Person
from tests.helpers.localizer_rig import Rig

PEOPLE = [Person((0.3, 0.1, 2.5)), Person((-1.2, 0.0, 4.0))]


def test_localizes_in_the_map_frame(memory_bus: MemoryBus) -> None:
    rig = Rig(memory_bus)
    f = scene.frame(3, PEOPLE)
    rig.robot(f.header.stamp_ns)
    for seq in (1, 2):
        rig.frames.put(scene.frame(seq, PEOPLE))
    rig.frames.put(f)
    dets = scene.detections(f, PEOPLE, extra_boxes=((700.0, 10.0, 800.0, 100.0), (50.0, 60.0, 40.0, 70.0)))
    dets.detections[1] = dets.detections[1].model_copy(update={"posture": "sitting"})  # as the depth detector says
    dets.detections[0] = dets.detections[0].model_copy(update={"stature_m": 1.74})
    rig.dets.put(dets)
    [out] = rig.service.poll(time.monotonic())
    got = rig.out.recv(timeout=1.0)
    assert got is not None and got.msg == out
    assert [d.posture for d in out.detections] == [None, "sitting"]  # the detector's posture, passed on
    assert [d.stature_m for d in out.detections] == [1.74, None]  # and its stature
    assert out.header == Header(stamp_ns=f.header.stamp_ns, frame_id="map", seq=3, source="head")
    assert out.camera_frame == "camera"
    assert [d.index for d in out.detections] == [0, 1]
    for d, p in zip(out.detections, PEOPLE):
        # interpolated between the two robot poses: within 1 cm of the truth
        assert np.linalg.norm(d.position - scene.map_position(p, f.header.stamp_ns)) < 0.01
        assert d.depth_m == pytest.approx(p.center[2], abs=1e-3)
        assert np.all(np.linalg.eigvalsh(d.cov) > 0)
    assert out.rejected == {"outside_image": 1, "empty_box": 1}
    assert rig.counters.extra["rejected_outside_image"] == 1 and rig.counters.extra["boxes_localized"] == 2
    # the camera's view goes along, so the tracker can tell a person out of view from one missed
    assert out.view is not None and (out.view.width, out.view.height) == (f.camera_info.width, f.camera_info.height)
    cam_to_map = out.view.camera_to_frame
    for d, p in zip(out.detections, PEOPLE):
        assert np.allclose(cam_to_map[:3, :3] @ p.center + cam_to_map[:3, 3], d.position, atol=0.05)


def test_pairs_detections_with_their_own_frame(memory_bus: MemoryBus) -> None:
    rig = Rig(memory_bus)
    near, far = [Person((0.0, 0.0, 2.0))], [Person((0.0, 0.0, 5.0))]
    f1, f2 = scene.frame(1, near), scene.frame(2, far)
    rig.robot(f1.header.stamp_ns)
    rig.frames.put(f1)
    rig.frames.put(f2)  # the newer frame arrives before the detections of the older one
    rig.dets.put(scene.detections(f1, near))
    [out] = rig.service.poll(time.monotonic())
    assert out.header.seq == 1
    assert out.detections[0].depth_m == pytest.approx(2.0, abs=1e-3)


def test_detections_before_their_frame_wait_for_it(memory_bus: MemoryBus) -> None:
    rig = Rig(memory_bus, frame_wait_s=0.5)
    f = scene.frame(1, PEOPLE)
    rig.robot(f.header.stamp_ns)
    rig.dets.put(scene.detections(f, PEOPLE))
    assert rig.service.poll(100.0) == []
    rig.frames.put(f)
    assert len(rig.service.poll(100.1)) == 1
    assert rig.counters.dropped == 0


def test_lost_frame_is_dropped_and_counted(memory_bus: MemoryBus) -> None:
    rig = Rig(memory_bus)
    f1, f2 = scene.frame(1, PEOPLE), scene.frame(2, PEOPLE)
    rig.robot(f1.header.stamp_ns)
    rig.frames.put(f2)  # frame 1 never reached the localizer
    rig.dets.put(scene.detections(f1, PEOPLE))
    rig.dets.put(scene.detections(f2, PEOPLE))
    [out] = rig.service.poll(100.0)
    assert out.header.seq == 2
    assert rig.counters.extra["dropped_no_depth_frame"] == 1


def test_frame_never_arrives_times_out(memory_bus: MemoryBus) -> None:
    rig = Rig(memory_bus, frame_wait_s=0.5)
    f = scene.frame(1, PEOPLE)
    rig.dets.put(scene.detections(f, PEOPLE))
    assert rig.service.poll(10.0) == []
    assert rig.service.poll(10.4) == [] and rig.counters.dropped == 0
    assert rig.service.poll(10.6) == []
    assert rig.counters.extra["dropped_no_depth_frame"] == 1 and not rig.service.pending


def test_missing_transform_is_dropped_never_published_in_camera_frame(
    memory_bus: MemoryBus, caplog: pytest.LogCaptureFixture
) -> None:
    rig = Rig(memory_bus, transform_wait_s=0.25)
    rig.tf_static.put(scene.tf_static())  # base_link -> camera only: odom -> base_link is missing
    rig.tf.put(TransformBatch(header=Header(stamp_ns=T0), transforms=[scene.tf(T0).transforms[0]]))  # map -> odom
    caplog.set_level(logging.WARNING, logger="services.localizer.service")
    for seq in (1, 2, 3):
        f = scene.frame(seq, PEOPLE)
        rig.frames.put(f)
        rig.dets.put(scene.detections(f, PEOPLE))
    assert rig.service.poll(50.0) == []  # waiting for the transform
    assert rig.counters.dropped == 0
    assert rig.service.poll(50.3) == []
    assert rig.counters.extra["dropped_no_transform"] == 3
    assert rig.out.try_recv() is None
    warnings = [r.getMessage() for r in caplog.records if "no_transform" in r.getMessage()]
    assert len(warnings) == 1, "the missing edge is logged at most once per second"
    assert "map|odom -> base_link" in warnings[0]


def test_transform_arriving_late_within_the_wait_is_used(memory_bus: MemoryBus) -> None:
    rig = Rig(memory_bus, transform_wait_s=0.25)
    f = scene.frame(1, PEOPLE)
    rig.tf_static.put(scene.tf_static())
    rig.tf.put(scene.tf(f.header.stamp_ns - S // 10))  # localization lags behind the camera
    rig.frames.put(f)
    rig.dets.put(scene.detections(f, PEOPLE))
    assert rig.service.poll(7.0) == []
    rig.tf.put(scene.tf(f.header.stamp_ns + S // 20))
    [out] = rig.service.poll(7.2)
    assert np.linalg.norm(out.detections[0].position - scene.map_position(PEOPLE[0], f.header.stamp_ns)) < 0.01
    assert rig.counters.dropped == 0


def test_transform_older_than_history_is_dropped_at_once(memory_bus: MemoryBus) -> None:
    rig = Rig(memory_bus, tf_history_s=1.0)
    f = scene.frame(1, PEOPLE)
    rig.tf_static.put(scene.tf_static())
    rig.tf.put(scene.tf(f.header.stamp_ns + 5 * S))
    rig.frames.put(f)
    rig.dets.put(scene.detections(f, PEOPLE))
    assert rig.service.poll(1.0) == []
    assert rig.counters.extra["dropped_no_transform"] == 1 and not rig.service.pending


@pytest.mark.parametrize(
    ("make_frame", "config", "reason"),
    [
        (lambda: scene.frame(1, PEOPLE, with_depth=False), {"floor_without_depth": False}, "frame_without_depth"),
        (lambda: scene.frame(1, PEOPLE, frame_id=""), {}, "no_camera_frame"),
        (lambda: scene.frame(1, PEOPLE, frame_id="", with_depth=False), {}, "no_camera_frame"),
    ],
)
def test_unusable_frames_are_counted(memory_bus: MemoryBus, make_frame: object, config: dict[str, object],
                                     reason: str) -> None:
    rig = Rig(memory_bus, **config)
    f = make_frame()  # type: ignore[operator]
    rig.robot(f.header.stamp_ns)
    rig.frames.put(f)
    rig.dets.put(scene.detections(f, PEOPLE))
    assert rig.service.poll(time.monotonic()) == []
    assert rig.counters.extra[f"dropped_{reason}"] == 1


def test_size_mismatch_and_all_invalid_depth(memory_bus: MemoryBus) -> None:
    rig = Rig(memory_bus)
    f = scene.frame(1, [], mm=False)
    rig.robot(f.header.stamp_ns)
    bad = scene.detections(f, PEOPLE).model_copy(update={"image_width": 320, "image_height": 240})
    rig.frames.put(f)
    rig.dets.put(bad)
    assert rig.service.poll(time.monotonic()) == []
    assert rig.counters.extra["dropped_size_mismatch"] == 1
    # a frame whose depth is all zero: published, with every box rejected and counted
    f2 = scene.frame(2, [])
    f2 = f2.model_copy(update={"depth": f2.depth.model_copy(update={"data": bytes(640 * 480 * 2)})})
    rig.frames.put(f2)
    rig.dets.put(scene.detections(f2, PEOPLE))
    [out] = rig.service.poll(time.monotonic())
    assert out.detections == [] and out.rejected == {"too_few_valid_pixels": 2}


def test_metre_depth_frames(memory_bus: MemoryBus) -> None:
    rig = Rig(memory_bus)
    f = scene.frame(4, PEOPLE, mm=False)
    rig.robot(f.header.stamp_ns)
    rig.frames.put(f)
    rig.dets.put(scene.detections(f, PEOPLE))
    [out] = rig.service.poll(time.monotonic())
    assert np.linalg.norm(out.detections[1].position - scene.map_position(PEOPLE[1], f.header.stamp_ns)) < 0.01


def test_static_transforms_from_config_and_camera_target(memory_bus: MemoryBus) -> None:
    q = scene.BASE_CAMERA.quat_xyzw
    st = StaticTransformConfig(
        parent_frame="base_link",
        child_frame="camera",
        translation=tuple(scene.BASE_CAMERA.translation),
        rotation_xyzw=tuple(q),
    )
    rig = Rig(memory_bus, target_frame="base_link", static_transforms=[st])
    f = scene.frame(1, PEOPLE)
    rig.frames.put(f)
    rig.dets.put(scene.detections(f, PEOPLE))
    [out] = rig.service.poll(time.monotonic())
    assert out.header.frame_id == "base_link"
    assert np.allclose(out.detections[0].position, scene.BASE_CAMERA.apply(np.array(PEOPLE[0].center)), atol=0.01)
    rig2 = Rig(
        MemoryBus(), target_frame="camera"
    )  # asking for the camera frame gives camera-frame positions, labelled so
    rig2.frames.put(f)
    rig2.dets.put(scene.detections(f, PEOPLE))
    [cam] = rig2.service.poll(time.monotonic())
    assert cam.header.frame_id == "camera" and np.allclose(cam.detections[0].position, PEOPLE[0].center, atol=0.01)


def test_bad_transform_batches_are_counted(memory_bus: MemoryBus) -> None:
    rig = Rig(memory_bus)
    rig.robot(T0)
    cycle = Transform(
        parent_frame="camera",
        child_frame="map",
        stamp_ns=T0,
        translation=np.zeros(3),
        rotation_xyzw=np.array([0, 0, 0, 1.0]),
    )
    later = scene.tf(T0 + S).transforms
    rig.tf.put(TransformBatch(header=Header(stamp_ns=T0), transforms=[later[0], cycle, later[1]]))
    rig.service.poll(time.monotonic())
    assert rig.counters.extra["transforms_rejected"] == 1
    assert rig.service.buffer.latest_common_stamp("map", "camera") == T0 + S  # the good edges were kept


def test_pending_is_bounded(memory_bus: MemoryBus) -> None:
    rig = Rig(memory_bus, max_pending=2, frame_wait_s=5.0)
    for seq in (1, 2, 3):
        rig.dets.put(scene.detections(scene.frame(seq, []), []))
    rig.service.poll(0.0)
    assert rig.service.pending == 2 and rig.counters.extra["dropped_pending_overflow"] == 1


def test_run_loop_publishes_until_shutdown(memory_bus: MemoryBus) -> None:
    rig = Rig(memory_bus)
    shutdown = Shutdown()
    thread = threading.Thread(target=rig.service.run, args=(shutdown,), daemon=True)
    thread.start()
    try:
        f = scene.frame(1, PEOPLE)
        rig.robot(f.header.stamp_ns)
        rig.frames.put(f)
        rig.dets.put(scene.detections(f, PEOPLE))
        got = rig.out.recv(timeout=10.0)
        assert got is not None and len(got.msg.detections) == 2
    finally:
        shutdown.set()
        thread.join(timeout=10.0)
    assert not thread.is_alive()


def test_config_validation() -> None:
    with pytest.raises(ValueError, match="min_depth_m"):
        LocalizerConfig(min_depth_m=5.0, max_depth_m=2.0)
    with pytest.raises(ValueError, match="camera"):
        LocalizerConfig(camera="a/b")
    with pytest.raises(ValueError):
        LocalizerConfig(percentile=101)
