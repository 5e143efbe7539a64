"""Camera model, rigid transforms and the transform buffer (common/geometry/transforms.py)."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from common.geometry.transforms import (
    ExtrapolationError,
    FrameTreeError,
    MissingTransformError,
    PinholeCamera,
    RigidTransform,
    TransformBuffer,
    interpolate,
)
from common.geometry.messages import (
    add_batch,
    batch_from_ros,
    camera_from_info,
    rigid_from_msg,
    transform_msg,
)
from common.messages.samples import camera_info, example_messages
from common.messages.schemas import TransformBatch

K = np.array([[525.0, 0.0, 319.5], [0.0, 525.0, 239.5], [0.0, 0.0, 1.0]])
PLUMB_BOB = np.array([-0.28, 0.09, 0.001, -0.0005, -0.01])
S = 1_000_000_000


def matrix(rot: Rotation, t: list[float]) -> np.ndarray:
    m = np.eye(4)
    m[:3, :3] = rot.as_matrix()
    m[:3, 3] = t
    return m


@pytest.mark.parametrize("D", [np.zeros(5), PLUMB_BOB], ids=["pinhole", "plumb_bob"])
def test_project_back_project_round_trip(D: np.ndarray) -> None:
    cam = PinholeCamera(K, 640, 480, D)
    rng = np.random.default_rng(0)
    px = np.column_stack([rng.uniform(0, 639, 200), rng.uniform(0, 479, 200)])
    z = rng.uniform(0.5, 8.0, 200)
    pts = cam.back_project(px, z)
    assert np.allclose(pts[:, 2], z)
    assert np.allclose(cam.project(pts), px, atol=1e-6)


def test_undistorted_projection_is_k_times_point() -> None:
    cam = PinholeCamera(K, 640, 480)
    assert not cam.distorted
    assert np.allclose(cam.project(np.array([[1.0, -0.5, 2.0]])), [[319.5 + 525 * 0.5, 239.5 - 525 * 0.25]])
    assert np.allclose(cam.rays(np.array([[319.5, 239.5]])), [[0.0, 0.0, 1.0]])


@pytest.mark.parametrize("D", [np.zeros(5), PLUMB_BOB], ids=["pinhole", "plumb_bob"])
def test_ray_jacobians_match_finite_differences(D: np.ndarray) -> None:
    cam = PinholeCamera(K, 640, 480, D)
    px = np.array([[10.0, 20.0], [320.0, 240.0], [600.0, 450.0]])
    jac = cam.ray_jacobians(px)
    h = 1e-3
    du = (cam.rays(px + [h, 0]) - cam.rays(px - [h, 0])) / (2 * h)
    dv = (cam.rays(px + [0, h]) - cam.rays(px - [0, h])) / (2 * h)
    assert np.allclose(jac[:, :, 0], du, atol=1e-6)
    assert np.allclose(jac[:, :, 1], dv, atol=1e-6)


def test_camera_from_info_and_bad_intrinsics() -> None:
    cam = camera_from_info(camera_info(640, 480))
    assert (cam.width, cam.height) == (640, 480) and cam.fx == 525.0
    with pytest.raises(ValueError, match="focal"):
        PinholeCamera(np.diag([0.0, 1.0, 1.0]), 640, 480)


def test_rigid_compose_inverse_and_apply_match_matrices() -> None:
    a = RigidTransform(Rotation.from_euler("xyz", [0.3, -0.2, 1.1]), np.array([1.0, 2.0, 3.0]))
    b = RigidTransform(Rotation.from_euler("zyx", [-0.7, 0.4, 0.1]), np.array([-0.5, 0.2, 0.9]))
    p = np.array([[0.3, -1.0, 2.0], [4.0, 5.0, -6.0]])
    ab = a @ b
    assert np.allclose(ab.matrix, a.matrix @ b.matrix)
    assert np.allclose(ab.apply(p), a.apply(b.apply(p)))
    assert np.allclose((a @ a.inverse()).matrix, np.eye(4))
    assert np.allclose(RigidTransform.from_quat(a.translation, 2.0 * a.quat_xyzw).matrix, a.matrix)


def test_covariance_rotation() -> None:
    tf = RigidTransform(Rotation.from_euler("z", 90, degrees=True), np.array([5.0, 0.0, 0.0]))
    cov = np.diag([0.04, 0.01, 0.09])
    out = tf.rotate_covariances(cov)
    # a 90 degree yaw swaps the x and y variances; translation does not change it
    assert np.allclose(out, np.diag([0.01, 0.04, 0.09]))
    r = Rotation.from_euler("xyz", [0.4, 0.5, 0.6])
    full = np.array([[0.05, 0.01, 0.0], [0.01, 0.02, 0.003], [0.0, 0.003, 0.08]])
    got = RigidTransform(r, np.zeros(3)).rotate_covariances(np.stack([full, full]))
    assert np.allclose(got[1], r.as_matrix() @ full @ r.as_matrix().T)


def test_interpolate_linear_translation_and_slerp() -> None:
    a = RigidTransform(Rotation.identity(), np.array([0.0, 0.0, 0.0]))
    b = RigidTransform(Rotation.from_euler("z", 90, degrees=True), np.array([2.0, -4.0, 1.0]))
    mid = interpolate(a, b, 0.25)
    assert np.allclose(mid.translation, [0.5, -1.0, 0.25])
    assert np.allclose(mid.rotation.as_euler("xyz", degrees=True), [0, 0, 22.5])


def robot_buffer(history_s: float = 10.0, tolerance_s: float = 0.05) -> tuple[TransformBuffer, dict[str, np.ndarray]]:
    """map <- odom <- base_link <- camera with known matrices at t = 1 s."""
    buf = TransformBuffer(history_s=history_s, tolerance_s=tolerance_s)
    mats = {
        "map_odom": matrix(Rotation.from_euler("z", 30, degrees=True), [1.0, -2.0, 0.0]),
        "odom_base": matrix(Rotation.from_euler("z", -75, degrees=True), [3.0, 0.5, 0.0]),
        "base_cam": matrix(
            Rotation.from_quat([-0.5, 0.5, -0.5, 0.5]) * Rotation.from_euler("x", 10, degrees=True), [0.1, 0.0, 1.2]
        ),
    }
    buf.set_transform("map", "odom", 1 * S, RigidTransform.from_matrix(mats["map_odom"]))
    buf.set_transform("odom", "base_link", 1 * S, RigidTransform.from_matrix(mats["odom_base"]))
    buf.set_transform("base_link", "camera", 0, RigidTransform.from_matrix(mats["base_cam"]), static=True)
    return buf, mats


def test_chain_lookup_matches_hand_computed() -> None:
    buf, m = robot_buffer()
    expected = m["map_odom"] @ m["odom_base"] @ m["base_cam"]
    got = buf.lookup("map", "camera", 1 * S)
    assert np.allclose(got.matrix, expected)
    # a point one metre in front of the camera, by hand
    p = expected @ np.array([0.0, 0.0, 1.0, 1.0])
    assert np.allclose(got.apply(np.array([0.0, 0.0, 1.0])), p[:3])
    # the reverse lookup, and between two branches sharing an ancestor
    assert np.allclose(buf.lookup("camera", "map", 1 * S).matrix, np.linalg.inv(expected))
    assert np.allclose(buf.lookup("odom", "camera", 1 * S).matrix, m["odom_base"] @ m["base_cam"])
    assert buf.latest_common_stamp("map", "camera") == 1 * S


def test_lookup_interpolates_between_stamps() -> None:
    buf = TransformBuffer()
    buf.set_transform("odom", "base_link", 1 * S, RigidTransform(Rotation.identity(), np.array([0.0, 0.0, 0.0])))
    buf.set_transform(
        "odom",
        "base_link",
        3 * S,
        RigidTransform(Rotation.from_euler("z", 60, degrees=True), np.array([4.0, 2.0, 0.0])),
    )
    buf.set_transform(
        "odom",
        "base_link",
        2 * S,
        RigidTransform(Rotation.from_euler("z", 20, degrees=True), np.array([1.0, 1.0, 0.0])),
    )
    got = buf.lookup("odom", "base_link", int(2.5 * S))
    assert np.allclose(got.translation, [2.5, 1.5, 0.0])
    assert np.isclose(got.rotation.as_euler("xyz", degrees=True)[2], 40.0)
    assert np.allclose(buf.lookup("odom", "base_link", 2 * S).translation, [1.0, 1.0, 0.0])
    assert np.allclose(
        buf.lookup("base_link", "odom", None).matrix, buf.lookup("odom", "base_link", 3 * S).inverse().matrix
    )


def test_missing_edge_names_the_gap() -> None:
    buf, _ = robot_buffer()
    buf2 = TransformBuffer()
    buf2.set_transform("base_link", "camera", 0, RigidTransform.identity(), static=True)
    buf2.set_transform("map", "odom", 0, RigidTransform.identity())
    with pytest.raises(MissingTransformError) as err:
        buf2.lookup("map", "camera", 0)
    assert err.value.edge == "map|odom -> base_link"
    assert "'base_link'" in str(err.value) and "(map, odom)" in str(err.value)
    with pytest.raises(MissingTransformError):
        buf.lookup("map", "unknown_frame", 1 * S)
    assert not buf.can_transform("map", "unknown_frame", 1 * S)


def test_extrapolation_beyond_tolerance_raises_within_tolerance_clamps() -> None:
    buf, m = robot_buffer(tolerance_s=0.05)
    buf.set_transform("map", "odom", 2 * S, RigidTransform.from_matrix(m["map_odom"]))
    buf.set_transform("odom", "base_link", 2 * S, RigidTransform.from_matrix(m["odom_base"]))
    near = buf.lookup("map", "camera", 2 * S + 40_000_000)
    assert np.allclose(near.matrix, m["map_odom"] @ m["odom_base"] @ m["base_cam"])
    with pytest.raises(ExtrapolationError) as err:
        buf.lookup("map", "camera", 2 * S + 60_000_000)
    assert err.value.future and err.value.edge in ("map -> odom", "odom -> base_link")
    with pytest.raises(ExtrapolationError) as past:
        buf.lookup("map", "camera", S - 100_000_000)
    assert not past.value.future
    assert "older than the oldest" in str(past.value)


def test_history_is_pruned_and_static_holds_forever() -> None:
    buf = TransformBuffer(history_s=1.0, tolerance_s=0.0)
    for k in range(30):
        buf.set_transform(
            "odom", "base_link", k * S // 10, RigidTransform(Rotation.identity(), np.array([k, 0.0, 0.0]))
        )
    buf.set_transform("base_link", "camera", 5 * S, RigidTransform.identity(), static=True)
    ((_, _, _, oldest, newest),) = [e for e in buf.edges() if e[1] == "base_link"]
    assert newest == 29 * S // 10 and oldest >= newest - S
    with pytest.raises(ExtrapolationError):
        buf.lookup("odom", "base_link", 1 * S)
    assert np.allclose(buf.lookup("base_link", "camera", 10**18).matrix, np.eye(4))


def test_frame_tree_errors() -> None:
    buf, _ = robot_buffer()
    with pytest.raises(FrameTreeError, match="already has parent"):
        buf.set_transform("map", "base_link", 0, RigidTransform.identity())
    with pytest.raises(FrameTreeError, match="cycle"):
        buf.set_transform("camera", "map", 0, RigidTransform.identity())
    with pytest.raises(FrameTreeError, match="static"):
        buf.set_transform("base_link", "camera", 0, RigidTransform.identity())
    with pytest.raises(ValueError):
        TransformBuffer(history_s=0.0)


def test_transform_messages_round_trip() -> None:
    batch = next(m for m in example_messages() if isinstance(m, TransformBatch))
    buf = TransformBuffer()
    assert add_batch(buf, batch) == 2
    tf = rigid_from_msg(batch.transforms[1])
    msg = transform_msg("base_link", "camera", 5, tf, static=True)
    assert np.allclose(rigid_from_msg(msg).matrix, tf.matrix)
    assert ("base_link", "camera", True) in [e[:3] for e in buf.edges()]


def test_batch_from_ros_tf_messages() -> None:
    from types import SimpleNamespace as NS

    def stamped(parent: str, child: str, stamp: NS, xyz: tuple[float, ...], q: tuple[float, ...]) -> NS:
        return NS(
            header=NS(frame_id=parent, stamp=stamp),
            child_frame_id=child,
            transform=NS(translation=NS(x=xyz[0], y=xyz[1], z=xyz[2]), rotation=NS(x=q[0], y=q[1], z=q[2], w=q[3])),
        )

    ros2 = NS(transforms=[stamped("odom", "base_link", NS(sec=12, nanosec=500), (1.0, 2.0, 0.0), (0, 0, 0.6, 0.8))])
    ros1 = NS(
        transforms=[stamped("/base_link", "/camera", NS(secs=3, nsecs=7), (0.1, 0.0, 1.2), (-0.5, 0.5, -0.5, 0.5))]
    )
    b2, b1 = batch_from_ros(ros2), batch_from_ros(ros1, static=True)
    t2, t1 = b2.transforms[0], b1.transforms[0]
    assert (t2.parent_frame, t2.child_frame, t2.stamp_ns, t2.static) == ("odom", "base_link", 12 * S + 500, False)
    assert np.allclose(t2.rotation_xyzw, [0, 0, 0.6, 0.8]) and b2.header.stamp_ns == 12 * S + 500
    assert (t1.parent_frame, t1.child_frame, t1.stamp_ns, t1.static) == ("base_link", "camera", 3 * S + 7, True)
    buf = TransformBuffer()
    add_batch(buf, b1)
    add_batch(buf, b2)
    assert buf.can_transform("odom", "camera", 12 * S + 500)


def test_a_transform_older_than_the_whole_history_starts_a_new_clock() -> None:
    buf = TransformBuffer(history_s=10.0, tolerance_s=0.05)
    s = 1_000_000_000
    for k in range(30):  # 30 s of odometry
        buf.set_transform("map", "base", 100 * s + k * s, RigidTransform.from_quat(np.array([k, 0.0, 0]), np.array([0, 0, 0, 1.0])))
    # a replay loops: its first transform is stamped 30 s earlier; it is kept, and the old ones go
    buf.set_transform("map", "base", 100 * s, RigidTransform.from_quat(np.array([-1.0, 0, 0]), np.array([0, 0, 0, 1.0])))
    buf.set_transform("map", "base", 101 * s, RigidTransform.from_quat(np.array([-2.0, 0, 0]), np.array([0, 0, 0, 1.0])))
    np.testing.assert_allclose(buf.lookup("map", "base", int(100.5 * s)).translation, [-1.5, 0, 0])
    with pytest.raises(ExtrapolationError):
        buf.lookup("map", "base", 120 * s)
    # a transform late by less than the history is a late transform, inserted in order
    buf.set_transform("map", "base", int(100.5 * s), RigidTransform.from_quat(np.array([9.0, 0, 0]), np.array([0, 0, 0, 1.0])))
    assert [st for _, c, _, st, _ in buf.edges() if c == "base"] == [100 * s]
