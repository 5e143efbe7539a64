"""The simulator's second camera, fixed on the base looking backwards (--back-camera), and the
``handover`` scenario: core geometry, messages, the in-memory transport, the localizer, the CLI."""

from __future__ import annotations

from itertools import pairwise
from pathlib import Path

import numpy as np
import pytest
from pydantic import ValidationError

from common.geometry.messages import rigid_from_msg
from common.messages.keys import FRAMES, RELIABLE, Keys
from common.transport.memory import MemoryBus
from common.messages.schemas import (
    Detection,
    Detections,
    LocalizedDetections,
    RGBDFrame,
    Transform,
    TransformBatch,
)
from perception.cli import main as cli_main
from services.localizer.config import LocalizerConfig
from services.localizer.service import LocalizerService
from tools.simulator.config import SimulatorConfig
from tools.simulator.core.cameras import BACK_CAMERA_OFFSET, back_camera
from tools.simulator.core.render import default_camera
from tools.simulator.core.scenarios import SCENARIOS, build_world
from tools.simulator.core.simulation import FrameData, Simulation
from tools.simulator.service import SimulatorService
from tools.simulator.source import SimulatedStream

KEYS = Keys()
START = 1_700_000_000_000_000_000
SMALL = default_camera(160, 120)


def _config(**kw: object) -> SimulatorConfig:
    base: dict[str, object] = {"scenario": "handover", "width": 160, "height": 120, "fps": 10.0,
                               "start_ns": START, "duration_s": 1.0, "depth_noise": False}
    base.update(kw)
    return SimulatorConfig(**base)  # type: ignore[arg-type]


def _pose(tf: Transform) -> np.ndarray:
    return rigid_from_msg(tf).matrix


def _pixel(map_camera: np.ndarray, point: np.ndarray) -> tuple[int, int, float]:
    """(u, v, z) of a map point in a camera with pose ``map_camera`` and intrinsics SMALL."""
    cam = (point - map_camera[:3, 3]) @ map_camera[:3, :3]
    return round(SMALL.fx * cam[0] / cam[2] + SMALL.cx), round(SMALL.fy * cam[1] / cam[2] + SMALL.cy), float(cam[2])


def _frame(t: float = 1.0) -> FrameData:
    """The handover scenario at ``t``: person 1 stands in front of the robot, person 2 behind it."""
    sim = Simulation(build_world("handover", seed=0), SMALL, fps=10, seed=0, depth_noise=False,
                     fixed_cameras=[back_camera("back")])
    return sim.frame(round(t * 10))


# ------------------------------------------------------------------ core


def test_the_back_camera_sits_on_the_base_looking_backwards() -> None:
    fd = _frame()
    view = fd.views["back"]
    base = fd.map_base
    # the optical axis is the base's -x, level; x right (the base's +y), y down
    np.testing.assert_allclose(view.map_camera[:3, 2], -base[:3, 0], atol=1e-12)
    np.testing.assert_allclose(view.map_camera[:3, 0], base[:3, 1], atol=1e-12)
    np.testing.assert_allclose(view.map_camera[:3, 1], [0.0, 0.0, -1.0], atol=1e-12)
    np.testing.assert_allclose(view.map_camera[:3, 3], (base @ np.append(BACK_CAMERA_OFFSET, 1.0))[:3], atol=1e-12)
    assert view.map_camera[2, 3] == pytest.approx(0.95)
    np.testing.assert_allclose(view.camera.base_mount @ view.camera.mount_optical, view.camera.base_optical)


def test_a_person_behind_the_robot_is_in_the_back_image_at_the_projected_pixel_not_in_the_head_image() -> None:
    fd = _frame()
    view = fd.views["back"]
    front, behind = fd.people  # person 1 in front, person 2 behind
    assert front.counted and not view.counted[0]
    assert view.counted[1] and not behind.counted and behind.in_view_fraction == 0.0
    assert view.visible[1] > 0.9
    # person 2's torso centre projects onto person 2's pixels, at the depth of their torso's front
    u, v, z = _pixel(view.map_camera, behind.position)
    assert 0 <= u < SMALL.width and 0 <= v < SMALL.height and z > 1.5
    assert view.render.owner[v, u] == 1
    assert z - 0.2 < view.render.depth_true[v, u] < z
    assert abs(view.render.depth_mm[v, u] / 1000.0 - view.render.depth_true[v, u]) < 1e-3  # depth_noise off
    # the head camera sees person 1 there and nothing of person 2; the back camera nothing of person 1
    assert not (fd.render.owner == 1).any() and (fd.render.owner == 0).any()
    assert not (view.render.owner == 0).any()
    uh, vh, zh = _pixel(fd.map_camera, front.position)
    assert fd.render.owner[vh, uh] == 0 and zh - 0.2 < fd.render.depth_true[vh, uh] < zh


def test_the_head_camera_does_not_depend_on_the_back_camera() -> None:
    one = Simulation(build_world("handover", seed=1), SMALL, fps=10, seed=1).frame(37)
    two = Simulation(build_world("handover", seed=1), SMALL, fps=10, seed=1, fixed_cameras=[back_camera()]).frame(37)
    assert np.array_equal(one.render.rgb, two.render.rgb) and np.array_equal(one.render.depth_mm, two.render.depth_mm)
    assert one.views == {} and set(two.views) == {"back"}
    assert [p.visible_fraction for p in one.people] == [p.visible_fraction for p in two.people]


def test_handover_people_walk_from_one_cameras_view_into_the_others() -> None:
    """Each person is seen by the head camera and by the back camera in turn, never by both at
    once, with a gap beside the robot at every crossing; at least four crossings each."""
    sim = Simulation(build_world("handover", seed=0), SMALL, fps=2, seed=0, fixed_cameras=[back_camera()])
    frames = [sim.frame(k) for k in range(round(SCENARIOS["handover"].duration_s * 2))]
    for k in range(2):
        seen = ["H" if fd.people[k].counted else "B" if fd.views["back"].counted[k] else "." for fd in frames]
        runs = [c for i, c in enumerate(seen) if i == 0 or c != seen[i - 1]]
        views = [c for c in runs if c != "."]
        crossings = sum(a != b for a, b in pairwise(views))
        assert crossings >= 4, "".join(seen)
        robot = frames[0].map_base[:2, 3]
        assert min(np.linalg.norm(fd.people[k].position[:2] - robot) for fd in frames) > 0.6


# ------------------------------------------------------------------ config


@pytest.mark.parametrize(
    "camera, back, match",
    [("front", "front", "differ from camera"), ("head", "head", "head_link"), ("head", "base", "base_link"),
     ("head", "a/b", "key chunk")],
)
def test_a_bad_back_camera_name_fails_with_a_reason(camera: str, back: str, match: str) -> None:
    with pytest.raises(ValidationError, match=match):
        SimulatorConfig(camera=camera, back_camera=back)


def test_without_the_back_camera_nothing_changes() -> None:
    one = SimulatedStream(_config(), KEYS)
    two = SimulatedStream(_config(back_camera="back"), KEYS)
    assert one.cameras == ("head",) and two.cameras == ("head", "back")
    pairs_one, pairs_two = one.messages(10)[1], two.messages(10)[1]  # tf_static goes out every 10th frame
    assert [k for k, _ in pairs_one] == [KEYS.tf_static(), KEYS.tf(), KEYS.groundtruth(), KEYS.frames("head")]
    assert [k for k, _ in pairs_two] == [k for k, _ in pairs_one] + [KEYS.frames("back")]
    head_one, head_two = SimulatedStream.frames_of(pairs_one)["head"], SimulatedStream.frames_of(pairs_two)["head"]
    assert head_one.rgb.data == head_two.rgb.data and head_one.depth.data == head_two.depth.data
    static_one, static_two = pairs_one[0][1], pairs_two[0][1]
    assert isinstance(static_one, TransformBatch) and isinstance(static_two, TransformBatch)
    assert static_two.transforms[: len(static_one.transforms)] == static_one.transforms


def test_groundtruth_counts_a_person_either_camera_sees() -> None:
    head_only = SimulatedStream.groundtruth_of(SimulatedStream(_config(), KEYS).messages(10)[1])
    both = SimulatedStream.groundtruth_of(SimulatedStream(_config(back_camera="back"), KEYS).messages(10)[1])
    assert [p.counted for p in head_only.people] == [True, False]  # person 2 stands behind the robot
    assert [p.counted for p in both.people] == [True, True]
    assert both.people[1].visible_fraction > 0.9
    assert both.people[0].visible_fraction == head_only.people[0].visible_fraction


# ------------------------------------------------------------------ transport


def test_both_cameras_are_published_with_their_sources_frames_and_static_transforms(memory_bus: MemoryBus) -> None:
    t = memory_bus.transport()
    frames = {c: t.subscribe(KEYS.frames(c), RGBDFrame, FRAMES) for c in ("head", "back")}
    tf = t.subscribe(KEYS.tf(), TransformBatch, RELIABLE)
    static = t.subscribe(KEYS.tf_static(), TransformBatch, RELIABLE)
    service = SimulatorService(memory_bus.transport(), KEYS, _config(back_camera="back"))
    assert KEYS.frames("back") in service.publishers
    edges: dict[tuple[str, str], np.ndarray] = {}
    for seq in range(3):
        service.step()
        got = {c: sub.recv(timeout=5.0) for c, sub in frames.items()}
        assert all(g is not None for g in got.values())
        head, back = got["head"].msg, got["back"].msg  # type: ignore[union-attr]
        stamp = START + seq * 100_000_000
        assert (head.header.source, head.header.frame_id) == ("head", "camera")
        for h in (back.header, back.rgb.header, back.depth.header, back.camera_info.header):
            assert (h.stamp_ns, h.seq, h.source, h.frame_id) == (stamp, seq, "back", "back_optical")
        assert (head.header.stamp_ns, head.header.seq) == (stamp, seq)
        assert back.rgb.shape == (120, 160, 3) and back.depth.shape == (120, 160)
        np.testing.assert_array_equal(back.camera_info.K, head.camera_info.K)
        msg = tf.recv(timeout=5.0)
        assert msg is not None
        edges |= {(i.parent_frame, i.child_frame): _pose(i) for i in msg.msg.transforms}
        if seq == 0:
            first = static.recv(timeout=5.0)
            assert first is not None and all(i.static for i in first.msg.transforms)
            edges |= {(i.parent_frame, i.child_frame): _pose(i) for i in first.msg.transforms}
        chain = (edges[("map", "odom")] @ edges[("odom", "base_link")] @ edges[("base_link", "back_link")]
                 @ edges[("back_link", "back_optical")])
        np.testing.assert_allclose(chain, service.stream.simulation.frame(seq).views["back"].map_camera, atol=1e-6)
    assert frames["back"].stats.received == frames["head"].stats.received == 3


def test_the_localizer_places_a_back_camera_detection_on_the_person(memory_bus: MemoryBus) -> None:
    """The unchanged localizer, run with ``camera: back``, puts a box around person 2 (behind the
    robot) where they stand in the map."""
    config = _config(back_camera="back", width=320, height=240)
    sim = SimulatorService(memory_bus.transport(), KEYS, config)
    localizer = LocalizerService(memory_bus.transport(), KEYS, LocalizerConfig(camera="back"))
    detections = memory_bus.transport().publisher(KEYS.detections("back"), Detections, RELIABLE)
    out = memory_bus.transport().subscribe(KEYS.localized("back"), LocalizedDetections, RELIABLE)
    published = sim.step()
    fd = sim.stream.simulation.frame(0)
    frame = SimulatedStream.frames_of(published)["back"]
    rows, cols = np.nonzero(fd.views["back"].render.owner == 1)  # person 2's pixels
    box = (float(cols.min()), float(rows.min()), float(cols.max() + 1), float(rows.max() + 1))
    detections.put(Detections(header=frame.header, detections=[Detection(index=0, bbox_xyxy=box, score=0.9)],
                              image_width=320, image_height=240, detector="truth"))
    localizer.poll(0.1)
    got = out.recv(timeout=5.0)
    localizer.close()
    assert got is not None and got.msg.header.frame_id == "map" and len(got.msg.detections) == 1
    truth = SimulatedStream.groundtruth_of(published).people[1].position
    assert np.linalg.norm(got.msg.detections[0].position[:2] - truth[:2]) < 0.25


def test_cli_back_camera_writes_both_frames_channels_and_a_two_row_snapshot(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    out = tmp_path / "run.mcap"
    args = ["simulate", "--scenario", "handover", "--back-camera", "back", "--width", "64", "--height", "48"]
    assert cli_main([*args, "--duration", "0.4", "--fps", "5", "--output", str(out)]) == 0
    assert "head: 2" in (printed := capsys.readouterr().out) and "back: 2" in printed
    png = tmp_path / "snap.png"
    assert cli_main([*args, "--snapshot", str(png)]) == 0
    import cv2

    assert cv2.imread(str(png)).shape == (96, 128, 3)
