"""The localizer's floor paths (frames without depth): a box's foot point on the floor plane,
through the camera's pose or through an image-to-floor homography."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from common.geometry.transforms import PinholeCamera, RigidTransform
from common.runtime.cli_util import CliError
from services.localizer.core import (
    REJECT_ABOVE_HORIZON,
    REJECT_BEYOND_RANGE,
    REJECT_CAMERA_BELOW_FLOOR,
    REJECT_EMPTY_BOX,
    REJECT_FOOT_OUTSIDE_IMAGE,
    REJECT_INVALID_BOX,
    FloorHomography,
    FloorParams,
    camera_pose_from_homography,
    foot_points,
    homography_from_camera,
    localize_on_floor,
    localize_on_floor_homography,
)
from services.localizer.core.floor import foot_variances
from services.localizer.files import read_floor_homography

K = np.array([[525.0, 0.0, 319.5], [0.0, 525.0, 239.5], [0.0, 0.0, 1.0]])
PLUMB_BOB = np.array([-0.28, 0.09, 0.001, -0.0005, -0.01])
PARAMS = FloorParams()
#: optical axis along the frame's x (the camera looks along x, level)
LOOK_X = Rotation.from_quat([-0.5, 0.5, -0.5, 0.5])


def mounted(height_m: float = 1.2, tilt_deg: float = 10.0, yaw_deg: float = 30.0,
            at: tuple[float, float] = (1.0, -2.0)) -> RigidTransform:
    """camera -> map: ``height_m`` above the floor at ``at``, facing ``yaw_deg``, tilted down."""
    rot = Rotation.from_euler("z", yaw_deg, degrees=True) * Rotation.from_euler("y", tilt_deg, degrees=True) * LOOK_X
    return RigidTransform(rot, np.array([at[0], at[1], height_m]))


def boxes_for(cam: PinholeCamera, cam_to_map: RigidTransform, feet: np.ndarray, tall_px: float = 120.0) -> np.ndarray:
    """(N, 4) boxes whose foot points (bottom centres) are the images of the floor points ``feet`` (N, 3)."""
    px = cam.project(cam_to_map.inverse().apply(feet))
    return np.column_stack([px[:, 0] - 20.0, px[:, 1] - tall_px, px[:, 0] + 20.0, px[:, 1]])


def ahead(cam_to_map: RigidTransform, ranges: list[float], side_m: float = 0.5, floor_z: float = 0.0) -> np.ndarray:
    """Floor points at ``ranges`` in front of the camera (horizontally), ``side_m`` to its left."""
    fwd = cam_to_map.rotation_matrix[:, 2].copy()
    fwd[2] = 0.0
    fwd /= np.linalg.norm(fwd)
    left = np.array([-fwd[1], fwd[0], 0.0])
    c = cam_to_map.translation
    return np.array([[*(c[:2] + r * fwd[:2] + side_m * left[:2]), floor_z] for r in ranges])


# --------------------------------------------------------------------- the camera's pose


@pytest.mark.parametrize("distortion", [np.zeros(5), PLUMB_BOB], ids=["pinhole", "plumb_bob"])
@pytest.mark.parametrize("floor_z", [0.0, 0.4])
def test_a_foot_point_lands_where_the_person_stands(distortion: np.ndarray, floor_z: float) -> None:
    cam = PinholeCamera(K, 640, 480, distortion)
    pose = mounted(height_m=1.2 + floor_z)
    feet = ahead(pose, [2.2, 3.0, 5.0, 8.0], floor_z=floor_z)
    params = FloorParams(floor_z_m=floor_z)
    loc = localize_on_floor(cam, pose, boxes_for(cam, pose, feet), params, indices=np.array([4, 5, 6, 7]), frame="map")
    assert loc.frame == "map" and loc.indices.tolist() == [4, 5, 6, 7] and not loc.rejected
    want = feet + np.array([0.0, 0.0, params.centre_height_m])
    assert np.allclose(loc.positions, want, atol=1e-6)  # the body centre above the feet
    assert np.allclose(loc.body_center_z, floor_z + 0.9)
    assert np.allclose(loc.depth_m, pose.inverse().apply(feet)[:, 2], atol=1e-6)  # the feet's optical depth
    assert loc.valid_pixels.tolist() == [0, 0, 0, 0]
    assert np.all(np.linalg.eigvalsh(loc.covs) > 0)


def test_the_horizon() -> None:
    cam = PinholeCamera(K, 640, 480)
    level = RigidTransform(LOOK_X, np.array([0.0, 0.0, 1.2]))  # the horizon is the row v = cy
    rows = [239.5 - 30.0, 239.5, 239.5 + 1e-3, 239.5 + 30.0]
    boxes = np.array([[300.0, v - 100.0, 340.0, v] for v in rows])
    loc = localize_on_floor(cam, level, boxes, FloorParams(max_floor_range_m=1e6))
    assert loc.rejected == {0: REJECT_ABOVE_HORIZON, 1: REJECT_ABOVE_HORIZON}
    assert loc.indices.tolist() == [2, 3]
    # just below the horizon: far away (f h / dv), and very unsure along the line of sight
    assert loc.positions[0, 0] == pytest.approx(525.0 * 1.2 / 1e-3, rel=1e-6)
    assert loc.positions[1, 0] == pytest.approx(525.0 * 1.2 / 30.0)
    # every box above the horizon, through a distorted lens: all rejected, nothing to undistort
    distorted = PinholeCamera(K, 640, 480, PLUMB_BOB)
    none = localize_on_floor(distorted, level, boxes[:1], FloorParams())
    assert len(none) == 0 and none.rejected == {0: REJECT_ABOVE_HORIZON}


def test_the_range() -> None:
    cam = PinholeCamera(K, 640, 480)
    pose = mounted(tilt_deg=5.0)
    feet = ahead(pose, [9.5, 10.5, 14.0], side_m=0.0)
    boxes = boxes_for(cam, pose, feet)
    assert localize_on_floor(cam, pose, boxes, PARAMS).rejected == {1: REJECT_BEYOND_RANGE, 2: REJECT_BEYOND_RANGE}
    assert not localize_on_floor(cam, pose, boxes, FloorParams(max_floor_range_m=15.0)).rejected


def test_boxes_that_cannot_be_placed() -> None:
    cam = PinholeCamera(K, 640, 480)
    pose = mounted()
    good = boxes_for(cam, pose, ahead(pose, [3.0]))[0]
    boxes = np.array([
        good,
        [np.nan, 10.0, 50.0, 300.0],
        [50.0, 300.0, 40.0, 310.0],
        [100.0, 300.0, 160.0, 480.0],  # reaches the image's lower edge: the feet are cut off
        [630.0, 200.0, 700.0, 400.0],  # foot point right of the image
        [-80.0, 200.0, -20.0, 400.0],
    ])
    loc = localize_on_floor(cam, pose, boxes, PARAMS)
    assert loc.indices.tolist() == [0]
    assert loc.rejected == {1: REJECT_INVALID_BOX, 2: REJECT_EMPTY_BOX, 3: REJECT_FOOT_OUTSIDE_IMAGE,
                            4: REJECT_FOOT_OUTSIDE_IMAGE, 5: REJECT_FOOT_OUTSIDE_IMAGE}
    below = localize_on_floor(cam, pose, boxes, FloorParams(floor_z_m=1.5))
    assert below.rejected[0] == REJECT_CAMERA_BELOW_FLOOR and len(below) == 0
    empty = localize_on_floor(cam, pose, np.zeros((0, 4)), PARAMS)
    assert len(empty) == 0 and empty.positions.shape == (0, 3) and empty.covs.shape == (0, 3, 3)


def test_foot_points() -> None:
    px, reasons = foot_points(np.array([[10.0, 20.0, 30.0, 100.0]]))
    assert px.tolist() == [[20.0, 100.0]] and reasons == [None]


def test_covariance_of_a_level_camera_is_the_pixel_error_carried_to_the_floor() -> None:
    # camera level at height h looking along x: v - cy = f h / d, so dx/dv = d^2 / (f h); dy/du = d / f
    cam, h = PinholeCamera(K, 640, 480), 1.2
    level = RigidTransform(LOOK_X, np.array([0.0, 0.0, h]))
    ranges = np.array([3.0, 5.0, 8.0])
    boxes = boxes_for(cam, level, ahead(level, list(ranges), side_m=0.0))
    loc = localize_on_floor(cam, level, boxes, PARAMS)
    sx, sy = np.sqrt(loc.covs[:, 0, 0]), np.sqrt(loc.covs[:, 1, 1])
    s_u, s_v = np.sqrt(foot_variances(boxes[:, 3] - boxes[:, 1], PARAMS)).T
    assert np.allclose(sx, ranges**2 / (525.0 * h) * s_v, rtol=1e-6)
    assert np.allclose(sy, ranges / 525.0 * s_u, rtol=1e-6)
    assert np.allclose(loc.covs[:, 2, 2], PARAMS.centre_height_sigma_m**2)
    assert np.allclose(loc.covs[:, 2, :2], 0.0)


@pytest.mark.parametrize("distortion", [np.zeros(5), PLUMB_BOB], ids=["pinhole", "plumb_bob"])
def test_covariance_grows_with_distance_as_the_pixel_error_does(distortion: np.ndarray) -> None:
    cam = PinholeCamera(K, 640, 480, distortion)
    pose = mounted()
    feet = ahead(pose, [2.0, 3.0, 5.0, 7.0, 9.0], side_m=0.8)
    boxes = boxes_for(cam, pose, feet)
    loc = localize_on_floor(cam, pose, boxes, PARAMS)
    largest = np.linalg.eigvalsh(loc.covs[:, :2, :2])[:, -1]
    assert np.all(np.diff(largest) > 0)
    # the covariance is J diag(s_u^2, s_v^2) J^T with J the true d(x, y)/d(u, v): check J numerically
    for k in range(len(boxes)):
        jac = np.zeros((2, 2))
        for a, step in enumerate(np.eye(2) * 0.05):
            moved = boxes[k:k + 1] + np.array([step[0], 0.0, step[0], step[1]])
            back = boxes[k:k + 1] - np.array([step[0], 0.0, step[0], step[1]])
            plus = localize_on_floor(cam, pose, moved, PARAMS).positions[0, :2]
            minus = localize_on_floor(cam, pose, back, PARAMS).positions[0, :2]
            jac[:, a] = (plus - minus) / 0.1
        want = jac @ np.diag(foot_variances(boxes[k:k + 1, 3] - boxes[k:k + 1, 1], PARAMS)[0]) @ jac.T
        assert np.allclose(loc.covs[k, :2, :2], want, rtol=2e-3, atol=1e-9)


def test_the_foot_pixels_error_grows_with_the_box() -> None:
    # a pixel's share, and 5 % across, 4 % down of the box's height (measured on PETS09's HOG boxes)
    var = foot_variances(np.array([0.0, 50.0, 300.0]), FloorParams())
    assert np.allclose(np.sqrt(var), [[1.0, 1.0], [np.hypot(1, 2.5), np.hypot(1, 2.0)], [np.hypot(1, 15), np.hypot(1, 12)]])
    assert np.allclose(foot_variances(np.array([80.0]), FloorParams(foot_sigma_share_u=0.0, foot_sigma_share_v=0.0)), 1.0)


def test_floor_params_are_checked() -> None:
    with pytest.raises(ValueError, match="max_floor_range_m"):
        FloorParams(max_floor_range_m=0.0)
    with pytest.raises(ValueError, match="foot_sigma"):
        FloorParams(foot_sigma_v_px=0.0)
    with pytest.raises(ValueError, match="foot_sigma_share"):
        FloorParams(foot_sigma_share_u=1.0)
    with pytest.raises(ValueError, match="centre_height_m"):
        FloorParams(centre_height_m=-1.0)


# --------------------------------------------------------------------------- homography


def test_a_homography_built_from_a_known_camera_agrees_with_its_pose() -> None:
    cam = PinholeCamera(K, 640, 480)
    pose = mounted(height_m=1.4, tilt_deg=15.0)
    hom = homography_from_camera(cam, pose)
    feet = ahead(pose, [2.0, 3.0, 6.0, 9.0])
    boxes = boxes_for(cam, pose, feet)
    recovered = camera_pose_from_homography(hom, K)
    assert recovered.mismatch < 1e-9
    assert np.allclose(recovered.camera_to_floor.matrix, pose.matrix, atol=1e-9)
    by_pose = localize_on_floor(cam, pose, boxes, PARAMS)
    by_hom = localize_on_floor_homography(hom, boxes, PARAMS, 640, 480, recovered, frame="map")
    assert np.allclose(by_hom.positions, feet + [0.0, 0.0, 0.9], atol=1e-9)
    assert np.allclose(by_hom.covs, by_pose.covs, rtol=1e-6, atol=1e-12)  # the same Jacobian, two ways
    assert np.allclose(by_hom.depth_m, by_pose.depth_m, rtol=1e-9)
    # without the camera's pose: the same positions, no depth and no range check
    bare = localize_on_floor_homography(hom, boxes, FloorParams(max_floor_range_m=1.0), 640, 480)
    assert np.allclose(bare.positions, by_hom.positions) and np.all(np.isnan(bare.depth_m))


def test_homography_horizon_range_and_image() -> None:
    cam = PinholeCamera(K, 640, 480)
    level = RigidTransform(LOOK_X, np.array([0.0, 0.0, 1.2]))
    hom = homography_from_camera(cam, level)
    pose = camera_pose_from_homography(hom, K)
    boxes = np.array([[300.0, 100.0, 340.0, 200.0],  # above the horizon: w < 0
                      [300.0, 139.5, 340.0, 239.5],  # on it: w = 0
                      [300.0, 200.0, 340.0, 239.5 + 21.0],  # 30 m away
                      [300.0, 200.0, 340.0, 239.5 + 126.0],  # 5 m
                      [300.0, 300.0, 340.0, 480.0]])  # cut off
    loc = localize_on_floor_homography(hom, boxes, PARAMS, 640, 480, pose)
    assert loc.rejected == {0: REJECT_ABOVE_HORIZON, 1: REJECT_ABOVE_HORIZON, 2: REJECT_BEYOND_RANGE,
                            4: REJECT_FOOT_OUTSIDE_IMAGE}
    assert loc.positions[0, 0] == pytest.approx(5.0)


def test_a_homography_scales_to_the_same_view_at_another_size() -> None:
    cam = PinholeCamera(K, 640, 480)
    pose = mounted()
    hom = homography_from_camera(cam, pose)
    feet = ahead(pose, [2.0, 4.0])
    boxes = boxes_for(cam, pose, feet)
    half = localize_on_floor_homography(hom, boxes / 2.0, PARAMS, 320, 240)
    assert np.allclose(half.positions[:, :2], feet[:, :2], atol=1e-9)
    assert hom.for_image(640, 480) is hom
    with pytest.raises(ValueError, match="640x480.*640x360"):
        hom.for_image(640, 360)


def test_floor_homography_is_checked() -> None:
    with pytest.raises(ValueError, match="3x3"):
        FloorHomography(np.eye(2))
    with pytest.raises(ValueError, match="singular"):
        FloorHomography(np.zeros((3, 3)))
    with pytest.raises(ValueError, match="image_size"):
        FloorHomography(np.eye(3), (0, 480))


def test_read_floor_homography(tmp_path: Path) -> None:
    good = tmp_path / "h.json"
    good.write_text('{"H": [1, 0, 0, 0, 1, 0, 0, 0, 1], "image_size": [640, 480], "maps": "a note"}')
    hom = read_floor_homography(good)
    assert hom.image_size == (640, 480) and np.array_equal(hom.H, np.eye(3))
    for text, match in (('{"image_size": [640, 480]}', 'no "H"'), ('{"H": [1, 2, 3]}', "expected 9"),
                        ('{"H": [[1, 0, 0], [0, 1, 0], [0, 0, 1]], "image_size": 640}', "image_size")):
        bad = tmp_path / "bad.json"
        bad.write_text(text)
        with pytest.raises(CliError, match=match):
            read_floor_homography(bad)
    with pytest.raises(CliError, match="does not exist"):
        read_floor_homography(tmp_path / "none.json")


def test_pets09_homography_puts_the_ground_truth_feet_where_they_stood(shared_data: Path) -> None:
    root = shared_data / "pets09_dev"
    hom = read_floor_homography(root / "ground_homography.json")
    assert hom.image_size == (480, 360)
    gt = np.loadtxt(root / "gt.txt", delimiter=",", ndmin=2)
    gt = gt[gt[:, 6] > 0]
    xyxy = np.column_stack([gt[:, 2:4], gt[:, 2:4] + gt[:, 4:6]])  # 768x576 pixels, as gt.txt gives them
    loose = FloorParams(max_floor_range_m=1e3)
    for scale, size in ((0.625, (480, 360)), (1.0, (768, 576))):  # the frames' pixels, and the original ones
        loc = localize_on_floor_homography(hom, xyxy * scale, loose, *size)
        err = np.linalg.norm(loc.positions[:, :2] - gt[loc.indices, 7:9], axis=1)
        assert len(loc) > 0.95 * len(gt)  # all but the feet cut off by the lower edge
        assert set(loc.rejected.values()) <= {REJECT_FOOT_OUTSIDE_IMAGE}
        assert np.median(err) < 0.05  # the data's README: 0.025 m
        assert np.allclose(loc.positions[:, 2], 0.9)
        # PETS09 view 1 is about 30 m from the people: far enough that the floor error grows
        assert np.median(np.sqrt(np.linalg.eigvalsh(loc.covs[:, :2, :2])[:, -1])) > 0.1
