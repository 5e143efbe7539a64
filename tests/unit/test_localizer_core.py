"""The localizer core on synthetic depth images with known people positions."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from common.geometry.transforms import PinholeCamera, RigidTransform
from services.localizer.core import (
    REJECT_EMPTY_BOX,
    REJECT_INVALID_BOX,
    REJECT_OUTSIDE_IMAGE,
    REJECT_TOO_FEW_PIXELS,
    DepthNoiseModel,
    LocalizerParams,
    localize,
)
from tests.fixtures.localizer_synthetic import Person, person_box, render_depth

K = np.array([[525.0, 0.0, 319.5], [0.0, 525.0, 239.5], [0.0, 0.0, 1.0]])
PLUMB_BOB = np.array([-0.28, 0.09, 0.001, -0.0005, -0.01])
#: the synthetic people are flat cut-outs at their centre's depth: the surface seen is their centre
PARAMS = LocalizerParams(body_half_depth_m=0.0)

# body centres (camera frame, y down) near the centre and near each corner of a 640x480 image
PEOPLE = {
    "centre": Person((0.05, 0.1, 3.0)),
    "top_left": Person((-2.1, -0.95, 4.5), height_m=1.7),
    "top_right": Person((2.1, -0.95, 4.5), height_m=1.7),
    "bottom_left": Person((-2.1, 0.95, 4.5), height_m=1.7),
    "bottom_right": Person((2.0, 0.9, 4.3), height_m=1.7),
}


def cameras() -> list[PinholeCamera]:
    return [PinholeCamera(K, 640, 480), PinholeCamera(K, 640, 480, PLUMB_BOB)]


@pytest.mark.parametrize("cam", cameras(), ids=["pinhole", "plumb_bob"])
@pytest.mark.parametrize("where", list(PEOPLE))
def test_person_position_within_1cm(cam: PinholeCamera, where: str) -> None:
    person = PEOPLE[where]
    depth = render_depth(cam, [person], wall_m=7.0)
    box = person_box(cam, person)
    assert 0 <= box[0] and box[2] < 640 and 0 <= box[1] and box[3] < 480, "the test box must lie inside the image"
    if where != "centre":  # near a corner: within 130 px of both image borders
        assert min(box[0], 639 - box[2]) < 130 and min(box[1], 479 - box[3]) < 130
    loc = localize(depth, cam, box[None], PARAMS)
    assert loc.rejected == {}
    assert np.linalg.norm(loc.positions[0] - np.array(person.center)) < 0.01
    assert np.isclose(loc.depth_m[0], person.center[2], atol=1e-6)
    # the wall fills part of the box: a high percentile lands on it
    high = localize(depth, cam, box[None], LocalizerParams(percentile=95.0, body_half_depth_m=0.0))
    assert np.isclose(high.positions[0, 2], 7.0)


@pytest.mark.parametrize("cam", cameras(), ids=["pinhole", "plumb_bob"])
def test_several_people_keep_their_indices(cam: PinholeCamera) -> None:
    people = [PEOPLE["centre"], PEOPLE["top_right"], PEOPLE["bottom_left"]]
    depth = render_depth(cam, people)
    boxes = np.array([person_box(cam, p) for p in people])
    loc = localize(depth, cam, boxes, PARAMS, indices=np.array([4, 7, 9]))
    assert loc.indices.tolist() == [4, 7, 9]
    assert np.allclose(loc.positions, [p.center for p in people], atol=0.01)


def test_millimetre_and_metre_encodings_agree() -> None:
    cam = PinholeCamera(K, 640, 480)
    person = Person((0.3, 0.0, 2.5))
    depth_m = render_depth(cam, [person])
    depth_mm = np.round(depth_m * 1000.0).astype(np.uint16)
    box = person_box(cam, person)[None]
    a = localize(depth_m, cam, box, PARAMS)
    b = localize(depth_mm, cam, box, PARAMS)
    assert np.allclose(a.positions, b.positions, atol=1e-6)
    assert np.allclose(b.positions[0], person.center, atol=0.01)
    # a depth camera reporting 0.1 mm units (depth_unit_m) gives the same position
    c = localize((depth_mm.astype(np.uint32) * 10).astype(np.uint32), cam, box, LocalizerParams(depth_unit_m=1e-4, body_half_depth_m=0.0))
    assert np.allclose(c.positions, a.positions, atol=1e-6)


def test_nan_and_zero_pixels_are_ignored_not_used() -> None:
    cam = PinholeCamera(K, 640, 480)
    person = Person((0.0, 0.0, 2.0))
    depth = render_depth(cam, [person])
    depth[::2, ::3] = np.nan  # holes
    depth[1::4, :] = 0.0
    loc = localize(depth, cam, person_box(cam, person)[None], PARAMS)
    assert np.allclose(loc.positions[0], person.center, atol=0.01)


def test_out_of_range_depth_is_excluded() -> None:
    cam = PinholeCamera(K, 640, 480)
    person = Person((0.0, 0.0, 2.0))
    depth = render_depth(cam, [person], wall_m=7.0)
    box = person_box(cam, person)[None]
    # everything closer than 2.5 m is out of range: only the wall is left
    loc = localize(depth, cam, box, LocalizerParams(min_depth_m=2.5, body_half_depth_m=0.0))
    assert np.isclose(loc.depth_m[0], 7.0)
    assert localize(depth, cam, box, LocalizerParams(min_depth_m=2.5, max_depth_m=6.0, body_half_depth_m=0.0)).rejected == {
        0: REJECT_TOO_FEW_PIXELS
    }


@pytest.mark.parametrize(
    ("box", "reason"),
    [
        ((300.0, 200.0, 300.0, 300.0), REJECT_EMPTY_BOX),  # zero width
        ((350.0, 200.0, 300.0, 300.0), REJECT_EMPTY_BOX),  # inverted x
        ((300.0, 300.0, 350.0, 200.0), REJECT_EMPTY_BOX),  # inverted y
        ((700.0, 100.0, 800.0, 300.0), REJECT_OUTSIDE_IMAGE),
        ((-200.0, 100.0, -10.0, 300.0), REJECT_OUTSIDE_IMAGE),
        ((100.0, 500.0, 200.0, 600.0), REJECT_OUTSIDE_IMAGE),
        ((np.nan, 100.0, 200.0, 300.0), REJECT_INVALID_BOX),
        ((100.0, 100.0, np.inf, 300.0), REJECT_INVALID_BOX),
        ((100.0, 100.0, 102.0, 102.0), REJECT_TOO_FEW_PIXELS),  # 4 pixels < min_valid_pixels
    ],
)
def test_bad_boxes_are_rejected_with_their_reason(box: tuple[float, ...], reason: str) -> None:
    cam = PinholeCamera(K, 640, 480)
    depth = np.full((480, 640), 3.0, dtype=np.float32)
    good = (250.0, 100.0, 390.0, 400.0)
    loc = localize(depth, cam, np.array([good, box]), PARAMS)
    assert loc.indices.tolist() == [0]
    assert loc.rejected == {1: reason}
    assert loc.rejected_counts() == {reason: 1}


@pytest.mark.parametrize("fill", [np.nan, 0.0], ids=["all_nan", "all_zero"])
def test_all_invalid_depth_rejects_every_box(fill: float) -> None:
    cam = PinholeCamera(K, 640, 480)
    depth = np.full((480, 640), fill, dtype=np.float32)
    loc = localize(depth, cam, np.array([[100.0, 100.0, 200.0, 400.0], [300.0, 50.0, 400.0, 450.0]]), PARAMS)
    assert len(loc) == 0 and loc.positions.shape == (0, 3) and loc.covs.shape == (0, 3, 3)
    assert loc.rejected_counts() == {REJECT_TOO_FEW_PIXELS: 2}
    mm = localize(np.zeros((480, 640), np.uint16), cam, np.array([[100.0, 100.0, 200.0, 400.0]]), PARAMS)
    assert mm.rejected == {0: REJECT_TOO_FEW_PIXELS}


def test_partly_outside_box_is_clipped() -> None:
    cam = PinholeCamera(K, 640, 480)
    depth = np.full((480, 640), 2.0, dtype=np.float32)
    loc = localize(depth, cam, np.array([[-50.0, 100.0, 100.0, 300.0]]), PARAMS)
    assert loc.rejected == {}
    assert np.allclose(loc.pixels[0], [50.0, 200.0])  # centre of the clipped box
    assert np.isclose(loc.positions[0, 2], 2.0)


def test_depth_and_camera_size_mismatch_raises() -> None:
    with pytest.raises(ValueError, match="depth image"):
        localize(np.zeros((240, 320), np.float32), PinholeCamera(K, 640, 480), np.zeros((0, 4)), PARAMS)


def test_covariance_axial_noise_grows_with_distance_squared() -> None:
    cam = PinholeCamera(K, 640, 480)
    noise = DepthNoiseModel(axial_a_m=0.0, axial_b_per_m=1.425e-3, pixel_sigma_px=2.0)
    params = LocalizerParams(noise=noise, body_half_depth_m=0.0)
    box = np.array([[309.5, 139.5, 329.5, 339.5]])  # centred on the principal point
    sig = []
    for z in (1.0, 2.0, 4.0):
        loc = localize(np.full((480, 640), z, np.float32), cam, box, params)
        cov = loc.covs[0]
        assert np.allclose(cov, cov.T) and np.all(np.linalg.eigvalsh(cov) > 0)
        sig.append(np.sqrt(np.diag(cov)))
        # on the optical axis: lateral sigma = z * pixel_sigma / f, axial = b z^2
        assert np.allclose(sig[-1], [z * 2.0 / 525.0, z * 2.0 / 525.0, 1.425e-3 * z * z])
    assert np.isclose(sig[2][2] / sig[0][2], 16.0)


def test_covariance_off_axis_couples_lateral_and_axial() -> None:
    cam = PinholeCamera(K, 640, 480)
    loc = localize(np.full((480, 640), 3.0, np.float32), cam, np.array([[540.0, 200.0, 600.0, 280.0]]), PARAMS)
    cov = loc.covs[0]
    ray = loc.positions[0] / np.linalg.norm(loc.positions[0])
    # the depth error acts along the ray, so the largest eigenvector is close to it
    w, v = np.linalg.eigh(cov)
    assert abs(float(v[:, -1] @ ray)) > 0.9
    assert cov[0, 2] > 0  # x and z are correlated for a point right of the axis


def test_transformed_rotates_positions_and_covariances() -> None:
    cam = PinholeCamera(K, 640, 480)
    person = Person((0.4, 0.2, 3.0))
    depth = render_depth(cam, [person])
    loc = localize(depth, cam, person_box(cam, person)[None], PARAMS)
    # optical frame (z forward, y down) -> a robot frame (x forward, z up) at 1.2 m, yawed by 30 degrees
    optical = Rotation.from_quat([-0.5, 0.5, -0.5, 0.5])
    tf = RigidTransform(Rotation.from_euler("z", 30, degrees=True) * optical, np.array([2.0, 1.0, 1.2]))
    out = loc.transformed(tf, "map")
    r = tf.rotation.as_matrix()
    assert out.frame == "map" and loc.frame == "camera"
    assert np.allclose(out.positions[0], r @ loc.positions[0] + [2.0, 1.0, 1.2])
    assert np.allclose(out.covs[0], r @ loc.covs[0] @ r.T)
    assert np.allclose(np.linalg.eigvalsh(out.covs[0]), np.linalg.eigvalsh(loc.covs[0]))
    # body centre 0.2 m below the optical axis -> 1.0 m above the floor
    assert np.isclose(out.body_center_z[0], 1.0, atol=0.01)


def test_params_validation() -> None:
    with pytest.raises(ValueError, match="percentile"):
        LocalizerParams(percentile=120.0)
    with pytest.raises(ValueError, match="min_depth_m"):
        LocalizerParams(min_depth_m=5.0, max_depth_m=1.0)
    with pytest.raises(ValueError):
        DepthNoiseModel(axial_b_per_m=-1.0)


@pytest.mark.parametrize("n", [1, 2, 7, 1000])
@pytest.mark.parametrize("q", [0.0, 25.0, 50.0, 99.5, 100.0])
def test_percentile_matches_numpy(n: int, q: float) -> None:
    from services.localizer.core.localize import _percentile

    values = np.random.default_rng(n).uniform(0.3, 9.0, n).astype(np.float32)
    assert np.isclose(_percentile(values, q), np.percentile(values, q), rtol=1e-6)
    ints = (values * 1000).astype(np.uint16)
    assert np.isclose(_percentile(ints, q), np.percentile(ints, q))


def test_a_person_half_hidden_behind_another_is_placed_at_their_own_depth() -> None:
    """A nearer person over half of the box fills its low percentiles: the box's depth puts the
    hidden person at the front person's range, beside them. The detector's own depth of the
    person (the depth detector measures it from their points) is taken instead."""
    cam = PinholeCamera(K, 640, 480)
    front, behind = Person((-0.1, 0.1, 2.0)), Person((0.35, 0.1, 4.0))
    depth = render_depth(cam, [front, behind], wall_m=7.0)
    boxes = np.stack([person_box(cam, front), person_box(cam, behind)])
    plain = localize(depth, cam, boxes, PARAMS)
    assert plain.depth_m[1] == pytest.approx(2.0)  # the front person's depth, the error being fixed
    loc = localize(depth, cam, boxes, PARAMS, depths=np.array([2.0, 4.02]))
    assert loc.depth_m[1] == pytest.approx(4.02) and list(loc.measured) == [False, True]
    assert np.linalg.norm(loc.positions[1] - np.array(behind.center)) < 0.05
    assert loc.depth_m[0] == pytest.approx(2.0)  # not farther than its box's: the box's depth stays
    # a farther depth by no more than occluder_gap_m is not an occluder's doing: the box's depth stays
    near = localize(depth, cam, boxes, PARAMS, depths=np.array([np.nan, 2.0 + 0.9 * PARAMS.occluder_gap_m]))
    assert not near.measured.any() and near.depth_m[1] == pytest.approx(2.0)
    # far behind the near person (the room seen past them, more often than a person): the box's depth stays
    far = localize(depth, cam, boxes, PARAMS, depths=np.array([np.nan, 2.0 + 1.1 * PARAMS.occluder_max_gap_m]))
    assert not far.measured.any() and far.depth_m[1] == pytest.approx(2.0)
    with pytest.raises(ValueError, match="occluder_gap_m"):
        LocalizerParams(occluder_gap_m=3.0, occluder_max_gap_m=2.0)
    assert list(localize(depth, cam, boxes, PARAMS).measured) == [False, False]  # one flag per box, without depths


def test_a_box_wholly_inside_a_nearer_persons_box_keeps_its_depth() -> None:
    """What a box wholly inside a nearer person's box shows is seen past that person, like the
    wall around them: its own depth is not taken, and it stays on that person (the tracker
    takes it for a second report of them)."""
    cam = PinholeCamera(K, 640, 480)
    front = Person((0.0, 0.1, 1.5))
    depth = render_depth(cam, [front], wall_m=6.0)
    outer = person_box(cam, front)
    inner = np.array([outer[0] + 5.0, outer[1] + 60.0, outer[0] + 60.0, outer[3] - 5.0])
    loc = localize(depth, cam, np.stack([outer, inner]), PARAMS, depths=np.array([1.5, 6.0]))
    assert not loc.measured.any() and loc.depth_m[1] == pytest.approx(1.5)
    with pytest.raises(ValueError, match="2 depths for 1 boxes|depths"):
        localize(depth, cam, outer[None], PARAMS, depths=np.array([1.5, 6.0]))


@pytest.mark.parametrize("cam", cameras(), ids=["pinhole", "plumb_bob"])
def test_the_centre_lies_half_a_torso_behind_the_surface_seen(cam: PinholeCamera) -> None:
    """A depth camera sees the front of a body: by default the point goes on along the line of
    sight by ``body_half_depth_m`` (0.11 m), at the image's centre as near its corners."""
    for where in ("centre", "top_left"):
        person = PEOPLE[where]
        depth = render_depth(cam, [person], wall_m=7.0)
        box = person_box(cam, person)[None]
        surface = localize(depth, cam, box, PARAMS).positions[0]
        deep = localize(depth, cam, box, LocalizerParams())
        step = deep.positions[0] - surface
        assert np.linalg.norm(step) == pytest.approx(0.11, abs=1e-9)
        assert np.allclose(step / 0.11, surface / np.linalg.norm(surface), atol=1e-9)  # along the ray
        assert deep.depth_m[0] == pytest.approx(deep.positions[0, 2])
    with pytest.raises(ValueError, match="body_half_depth_m"):
        LocalizerParams(body_half_depth_m=-0.1)
