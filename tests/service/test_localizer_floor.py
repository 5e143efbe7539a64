"""The localizer service on frames without depth (an RGB-only camera): people on the floor,
through the robot's transforms or through a floor homography file."""

from __future__ import annotations

import json
import time
from pathlib import Path

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from common.geometry.transforms import PinholeCamera, RigidTransform
from common.messages.schemas import Detection, Detections, RGBDFrame
from common.runtime.cli_util import CliError
from common.transport.memory import MemoryBus
from services.localizer import flags
from services.localizer.config import LocalizerConfig, StaticTransformConfig
from services.localizer.core import FloorHomography, homography_from_camera
from tests.fixtures import localizer_scene as scene
from tests.fixtures.localizer_synthetic import Person
from tests.helpers.localizer_rig import Rig

#: a fixed camera 3 m up in a corner, facing 45 degrees, tilted 30 degrees down
FIXED = RigidTransform(Rotation.from_euler("z", 45, degrees=True) * Rotation.from_euler("y", 30, degrees=True)
                       * Rotation.from_quat([-0.5, 0.5, -0.5, 0.5]), np.array([2.0, 1.0, 3.0]))


def cam_to_map(stamp_ns: int) -> RigidTransform:
    """Where the robot's camera is in the map at ``stamp_ns``."""
    return scene.MAP_ODOM @ scene.odom_base(stamp_ns) @ scene.BASE_CAMERA


def on_floor(pose: RigidTransform, ranges: list[float], side_m: float = 0.3) -> np.ndarray:
    """Floor points (N, 3) of the map ``ranges`` metres in front of a camera at ``pose``."""
    fwd = pose.rotation_matrix[:2, 2] / np.linalg.norm(pose.rotation_matrix[:2, 2])
    left = np.array([-fwd[1], fwd[0]])
    return np.array([[*(pose.translation[:2] + r * fwd + side_m * left), 0.0] for r in ranges])


def boxes_at(pose: RigidTransform, feet: np.ndarray) -> list[tuple[float, float, float, float]]:
    """Boxes whose bottom centres are the images of ``feet`` seen from ``pose``."""
    px = scene.camera().project(pose.inverse().apply(feet))
    return [(u - 25.0, v - 150.0, u + 25.0, v) for u, v in px.tolist()]


def foot_pixels(pose: RigidTransform, feet: np.ndarray) -> np.ndarray:
    return scene.camera().project(pose.inverse().apply(feet))


def detections(f: RGBDFrame, boxes: list[tuple[float, float, float, float]], detector: str = "test") -> Detections:
    return Detections(header=f.header, image_width=640, image_height=480, detector=detector,
                      detections=[Detection(index=i, bbox_xyxy=b, score=0.9) for i, b in enumerate(boxes)])


def homography_file(tmp_path: Path, hom: FloorHomography, size: tuple[int, int] | None = None) -> Path:
    path = tmp_path / "floor.json"
    size = size or hom.image_size
    path.write_text(json.dumps({"H": hom.H.tolist(), "image_size": list(size) if size else None,
                                "maps": "foot pixel (u, v, 1) -> floor (x, y, w)"}))
    return path


def test_frames_without_depth_put_people_on_the_floor(memory_bus: MemoryBus) -> None:
    rig = Rig(memory_bus)
    f = scene.frame(3, [], with_depth=False)
    stamp = f.header.stamp_ns
    rig.robot(stamp)
    pose = cam_to_map(stamp)
    feet = on_floor(pose, [3.0, 6.0, 14.0])
    boxes = boxes_at(pose, feet)
    boxes += [(300.0, 10.0, 340.0, 60.0),  # the foot point above the horizon (the camera is tilted 10 degrees)
              (100.0, 300.0, 160.0, 480.0)]  # the feet cut off by the image's lower edge
    rig.frames.put(f)
    rig.dets.put(detections(f, boxes))
    [out] = rig.service.poll(time.monotonic())
    assert out.header.frame_id == "map" and out.header.seq == 3
    assert [d.index for d in out.detections] == [0, 1]
    for d, foot in zip(out.detections, feet):
        assert np.allclose(d.position, foot + [0.0, 0.0, 0.9], atol=1e-6)  # body centre above the feet
        assert d.valid_pixels == 0 and d.depth_m == pytest.approx(pose.inverse().apply(foot)[2], abs=1e-6)
        assert np.all(np.linalg.eigvalsh(d.cov) > 0)
    near, far = (np.linalg.eigvalsh(d.cov[:2, :2])[-1] for d in out.detections)
    assert far > 3 * near
    assert out.rejected == {"beyond_floor_range": 1, "foot_above_horizon": 1, "foot_outside_image": 1}
    extra = rig.counters.extra
    assert extra["rejected_beyond_floor_range"] == 1 and extra["rejected_foot_above_horizon"] == 1
    assert extra["rejected_foot_outside_image"] == 1 and extra["boxes_on_floor"] == 2
    assert out.view is not None and np.allclose(out.view.camera_to_frame, pose.matrix, atol=1e-9)
    assert out.view.max_range_m > 10.0


def test_through_a_floor_homography_no_transform_is_needed(memory_bus: MemoryBus, tmp_path: Path) -> None:
    hom = homography_from_camera(scene.camera(), FIXED)
    rig = Rig(memory_bus, floor_homography=homography_file(tmp_path, hom))
    f = scene.frame(1, [], with_depth=False)
    feet = on_floor(FIXED, [4.0, 8.0], side_m=-0.5)
    rig.frames.put(f)
    rig.dets.put(detections(f, boxes_at(FIXED, feet) + [(300.0, 5.0, 340.0, 40.0)]))
    [out] = rig.service.poll(time.monotonic())
    assert np.allclose([d.position for d in out.detections], feet + [0.0, 0.0, 0.9], atol=1e-6)
    assert out.rejected == {"beyond_floor_range": 1}  # 4 m and 8 m ahead on the floor, the top of the image ~11 m
    # the camera's K fits the homography: its pose, hence the view, comes from the two
    assert out.view is not None and np.allclose(out.view.camera_to_frame, FIXED.matrix, atol=1e-6)
    assert "homography_intrinsics_mismatch" not in rig.counters.extra
    # and the fixed camera's floor view, the same homography, is sent with it
    assert out.floor_view is not None and (out.floor_view.width, out.floor_view.height) == (640, 480)
    assert np.allclose(FloorHomography(out.floor_view.image_to_frame).to_floor(foot_pixels(FIXED, feet))[0],
                       feet[:, :2], atol=1e-6)


def test_each_detectors_foot_bias_is_taken_off(memory_bus: MemoryBus, tmp_path: Path) -> None:
    """Boxes that reach below the feet by a detector's known share of their height (``foot_bias``:
    HOG's by default, another's from the settings) land on the feet; a detector without one is
    taken as it comes."""
    hom = homography_from_camera(scene.camera(), FIXED)
    rig = Rig(memory_bus, foot_bias={"hog": {"v": 0.037}, "yolo-onnx": {"u": 0.02, "v": -0.01}},
              floor_homography=homography_file(tmp_path, hom))
    feet = on_floor(FIXED, [4.0, 8.0], side_m=-0.5)
    exact = boxes_at(FIXED, feet)
    for seq, (name, (bu, bv)) in enumerate({"hog": (0.0, 0.037), "yolo-onnx": (0.02, -0.01),
                                            "depth": (0.0, 0.0)}.items(), 1):
        f = scene.frame(seq, [], with_depth=False)
        bottoms = [(y2 - bv * y1) / (1.0 - bv) for _, y1, _, y2 in exact]  # below the feet by bv of the new height
        skewed = [(x1 + bu * (b - y1), y1, x2 + bu * (b - y1), b) for (x1, y1, x2, _), b in zip(exact, bottoms)]
        rig.frames.put(f)
        rig.dets.put(detections(f, skewed, detector=name))
        [out] = rig.service.poll(time.monotonic())
        assert np.allclose([d.position for d in out.detections], feet + [0.0, 0.0, 0.9], atol=1e-6), name
        assert [d.bbox_xyxy for d in out.detections] == [tuple(b) for b in skewed]  # the boxes go on as they came
    assert LocalizerConfig().foot_bias["hog"].v == pytest.approx(0.037)  # the default table has HOG's


def test_a_homography_for_another_resolution_is_scaled(memory_bus: MemoryBus, tmp_path: Path) -> None:
    hom = homography_from_camera(scene.camera(), FIXED)
    big = FloorHomography(hom.H @ np.diag([0.5, 0.5, 1.0]), (1280, 960))  # fitted on 1280x960 pixels
    rig = Rig(memory_bus, floor_homography=homography_file(tmp_path, big))
    f = scene.frame(1, [], with_depth=False)
    feet = on_floor(FIXED, [5.0])
    rig.frames.put(f)
    rig.dets.put(detections(f, boxes_at(FIXED, feet)))
    [out] = rig.service.poll(time.monotonic())
    assert np.allclose(out.detections[0].position, feet[0] + [0.0, 0.0, 0.9], atol=1e-6)


def test_homography_problems_are_counted(memory_bus: MemoryBus, tmp_path: Path) -> None:
    hom = homography_from_camera(scene.camera(), FIXED)
    rig = Rig(memory_bus, floor_homography=homography_file(tmp_path, hom, (640, 360)))
    f = scene.frame(1, [], with_depth=False)
    rig.frames.put(f)
    rig.dets.put(detections(f, boxes_at(FIXED, on_floor(FIXED, [5.0]))))
    assert rig.service.poll(time.monotonic()) == []
    assert rig.counters.extra["dropped_homography_size_mismatch"] == 1
    # a homography of a longer lens than the camera_info's: positions from it, but no view
    longer = scene.camera().K.copy()
    longer[:2, :2] *= 1.5
    other = homography_from_camera(PinholeCamera(longer, 640, 480), FIXED)
    rig2 = Rig(MemoryBus(), floor_homography=homography_file(tmp_path, other))
    feet = on_floor(FIXED, [5.0])
    px = PinholeCamera(longer, 640, 480).project(FIXED.inverse().apply(feet))[0]
    rig2.frames.put(f)
    rig2.dets.put(detections(f, [(px[0] - 20.0, px[1] - 100.0, px[0] + 20.0, px[1])]))
    [out] = rig2.service.poll(time.monotonic())
    assert np.allclose(out.detections[0].position, feet[0] + [0.0, 0.0, 0.9], atol=1e-6) and out.view is None
    assert rig2.counters.extra["homography_intrinsics_mismatch"] == 1
    assert out.floor_view is not None  # the homography alone still tells what the camera sees of the floor


def test_a_homography_in_another_frame(memory_bus: MemoryBus, tmp_path: Path) -> None:
    hom = homography_from_camera(scene.camera(), FIXED)
    shift = StaticTransformConfig(parent_frame="map", child_frame="world", translation=(10.0, -3.0, 0.0))
    rig = Rig(memory_bus, floor_homography=homography_file(tmp_path, hom), floor_homography_frame="world",
              static_transforms=[shift])
    f = scene.frame(1, [], with_depth=False)
    feet = on_floor(FIXED, [5.0])
    rig.frames.put(f)
    rig.dets.put(detections(f, boxes_at(FIXED, feet)))
    [out] = rig.service.poll(time.monotonic())
    assert out.header.frame_id == "map"
    assert np.allclose(out.detections[0].position, feet[0] + [10.0, -3.0, 0.9], atol=1e-6)
    # the floor view is in the positions' frame (map), not the homography's (world)
    assert out.floor_view is not None
    assert np.allclose(FloorHomography(out.floor_view.image_to_frame).to_floor(foot_pixels(FIXED, feet))[0],
                       feet[:, :2] + [10.0, -3.0], atol=1e-6)


def test_a_tilted_homography_frame_sends_no_floor_view(memory_bus: MemoryBus, tmp_path: Path) -> None:
    hom = homography_from_camera(scene.camera(), FIXED)
    tilt = StaticTransformConfig(parent_frame="map", child_frame="world", translation=(0.0, 0.0, 0.0),
                                 rotation_xyzw=tuple(Rotation.from_euler("x", 10, degrees=True).as_quat()))
    rig = Rig(memory_bus, floor_homography=homography_file(tmp_path, hom), floor_homography_frame="world",
              static_transforms=[tilt])
    f = scene.frame(1, [], with_depth=False)
    rig.frames.put(f)
    rig.dets.put(detections(f, boxes_at(FIXED, on_floor(FIXED, [5.0]))))
    [out] = rig.service.poll(time.monotonic())
    assert out.floor_view is None and len(out.detections) == 1  # its floor is not the map's: no floor view


def test_frames_with_depth_keep_the_depth_path(memory_bus: MemoryBus, tmp_path: Path) -> None:
    people = [Person((0.3, 0.1, 2.5))]
    rig = Rig(memory_bus, floor_homography=homography_file(tmp_path, homography_from_camera(scene.camera(), FIXED)))
    f = scene.frame(2, people)
    rig.robot(f.header.stamp_ns)
    rig.frames.put(f)
    rig.dets.put(scene.detections(f, people))
    [out] = rig.service.poll(time.monotonic())
    assert np.linalg.norm(out.detections[0].position - scene.map_position(people[0], f.header.stamp_ns)) < 0.01
    assert out.detections[0].valid_pixels > 0 and "boxes_on_floor" not in rig.counters.extra


def test_a_bad_homography_file_stops_the_start(tmp_path: Path) -> None:
    bad = tmp_path / "bad.json"
    bad.write_text('{"H": [[1, 0], [0, 1]]}')
    config = LocalizerConfig(floor_homography=bad)
    with pytest.raises(CliError, match="expected 9"):
        flags.prepare(config)
    with pytest.raises(CliError, match="does not exist"):
        flags.prepare(LocalizerConfig(floor_homography=tmp_path / "none.json"))
    assert flags.prepare(LocalizerConfig()) == {}
