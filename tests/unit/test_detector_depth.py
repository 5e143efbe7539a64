"""depth backend (Basso/Munaro): ground plane, clustering, person-height filter, boxes, on rendered scenes."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from services.detector.core.boxes import DetectorError, iou_matrix
from services.detector.core.depth import DepthClusterDetector, DepthParams, cluster_points, voxel_grid
from services.detector.core.ground import GroundParams, initial_plane, refine_plane
from services.detector.core.seated import SeatedParams
from tests.fixtures.detector_synthetic import Block, render_depth, scene_intrinsics, with_head, with_heads

W, H = 640, 480
CAMERA_HEIGHT = 1.2
PEOPLE = [Block(-0.8, 3.5, 0.5, 1.75, 0.3), Block(0.9, 4.5, 0.45, 1.60, 0.3)]
TABLE = Block(0.0, 2.6, 1.0, 0.75, 0.6)
SITTING = Block(1.3, 2.8, 0.5, 1.15, 0.5)
OCCLUDED = 1.05  # occluded_max_bottom_m turned on (off by default)


def expected_box(block: Block, K: np.ndarray, tilt_deg: float) -> np.ndarray:
    """Image box of a block's 8 corners (what a perfect detector would draw)."""
    t = np.deg2rad(tilt_deg)
    x_c, y_c, z_c = np.array([1.0, 0, 0]), np.array([0, -np.cos(t), -np.sin(t)]), np.array([0, -np.sin(t), np.cos(t)])
    xs = [block.x - block.width / 2, block.x + block.width / 2]
    ys = [0.0, block.height]
    zs = [block.z - block.depth / 2, block.z + block.depth / 2]
    corners = np.array([[x, y, z] for x in xs for y in ys for z in zs]) - [0.0, CAMERA_HEIGHT, 0.0]
    cam = corners @ np.column_stack([x_c, y_c, z_c])
    u = K[0, 0] * cam[:, 0] / cam[:, 2] + K[0, 2]
    v = K[1, 1] * cam[:, 1] / cam[:, 2] + K[1, 2]
    return np.array([u.min(), v.min(), u.max(), v.max()])


def scene(blocks: list[Block], tilt_deg: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    K = scene_intrinsics(W, H)
    depth, rgb = render_depth(blocks, K, W, H, CAMERA_HEIGHT, tilt_deg)
    return rgb, depth, K


@pytest.mark.parametrize("tilt", [0.0, 15.0])
def test_finds_two_people_not_the_table(tilt: float) -> None:
    rgb, depth, K = scene([*with_heads(PEOPLE), TABLE], tilt)
    det = DepthClusterDetector(DepthParams(camera_height_m=CAMERA_HEIGHT, tilt_deg=tilt))
    for _ in range(2):  # the plane is carried from frame to frame
        boxes, scores = det.detect(rgb, depth, K)
    assert len(boxes) == 2
    truth = np.array([expected_box(p, K, tilt) for p in PEOPLE])
    iou = iou_matrix(boxes, truth)
    assert iou.max(axis=0).min() > 0.7, iou
    assert iou_matrix(boxes, expected_box(TABLE, K, tilt)[None]).max() < 0.1
    assert np.all((scores > 0) & (scores <= 1))
    np.testing.assert_allclose(np.sort(det.heights), [1.60, 1.75], atol=0.08)
    assert det.plane_inliers > 100
    np.testing.assert_allclose(det.plane.offset, CAMERA_HEIGHT, atol=0.02)


def test_each_person_has_their_own_depth_even_partly_hidden_behind_another() -> None:
    """``depths``: each person's depth from their own points (their front), what the localizer
    reads in a box, here for a person partly hidden behind a nearer one."""
    front, behind = Block(-0.8, 3.0, 0.5, 1.75, 0.3), Block(-0.7, 4.5, 0.5, 1.7, 0.3)
    rgb, depth, K = scene(with_heads([front, behind]), 0.0)
    det = DepthClusterDetector(DepthParams(camera_height_m=CAMERA_HEIGHT))
    for _ in range(2):
        boxes, _ = det.detect(rgb, depth, K)
    assert len(boxes) == len(det.depths) == 2
    by_x = sorted(zip(boxes[:, 0].tolist(), det.depths.tolist()))
    # the front faces, 0.15 m before the blocks' centres (the 25th percentile of the points' z)
    np.testing.assert_allclose([z for _, z in by_x], [front.z - 0.15, behind.z - 0.15], atol=0.08)


def test_each_standing_persons_stature_is_their_top_and_unknown_when_the_image_cuts_it() -> None:
    """``statures``: a standing person's top above the floor (the tracker's soft biometric); NaN
    where the image's upper edge cuts the head (a person close to the camera)."""
    short, tall = Block(-0.8, 3.0, 0.5, 1.62, 0.3), Block(0.6, 3.5, 0.5, 1.88, 0.3)
    rgb, depth, K = scene(with_heads([short, tall]), 0.0)
    det = DepthClusterDetector(DepthParams(camera_height_m=CAMERA_HEIGHT))
    for _ in range(2):
        boxes, _ = det.detect(rgb, depth, K)
    assert len(boxes) == len(det.statures) == 2
    by_x = sorted(zip(boxes[:, 0].tolist(), det.statures.tolist()))
    np.testing.assert_allclose([h for _, h in by_x], [short.height, tall.height], atol=0.04)
    near = Block(0.5, 1.8, 0.5, 1.95, 0.3)  # 1.8 m away, the camera tilted down 10 degrees: the image
    tilted = DepthClusterDetector(DepthParams(camera_height_m=CAMERA_HEIGHT, tilt_deg=10.0))
    rgb, depth, K = scene(with_head(near), 10.0)
    for _ in range(2):
        boxes, _ = tilted.detect(rgb, depth, K)
    assert len(boxes) == 1 and boxes[0, 1] <= 1.0  # ends at 1.68 m on them
    assert tilted.heights[0] < near.height - 0.2 and np.isnan(tilted.statures[0])


def test_a_wall_end_seen_edge_on_is_flat_and_not_a_person() -> None:
    # a 2 m tall, 5 cm thick partition running away from the camera: person-tall and narrower
    # than max_width_m, but all its points lie on one vertical plane
    wall = Block(-1.0, 3.5, 0.05, 2.0, 1.0)
    rgb, depth, K = scene([wall, *with_head(PEOPLE[1])], 0.0)
    found = {}
    for thickness in (0.0, DepthParams().min_thickness_m):  # its top is a 1 m slab too: the head rule off
        det = DepthClusterDetector(DepthParams(camera_height_m=CAMERA_HEIGHT, min_thickness_m=thickness,
                                               head_max_width_m=0.0))
        for _ in range(2):
            boxes, _ = det.detect(rgb, depth, K)
        found[thickness] = iou_matrix(boxes, np.array([expected_box(b, K, 0.0) for b in (wall, PEOPLE[1])]))
    assert found[0.0].shape[0] == 2 and found[0.0][:, 0].max() > 0.5  # without the rule: the wall is a person
    (person,) = found[DepthParams().min_thickness_m]  # with it: only the person
    assert person[1] > 0.7 and person[0] < 0.1


def test_a_person_close_enough_to_be_cut_by_the_lower_edge_is_still_a_person_a_wall_is_not() -> None:
    # 0.95-1.25 m away the image's lower edge is 0.63-0.77 m over the floor: Basso/Munaro's rule (a
    # cluster must come down to max_bottom_m, 0.6 m) alone would drop this person
    person, wall = Block(0.3, 1.1, 0.4, 1.75, 0.3), Block(-0.6, 1.6, 0.05, 2.0, 1.2)
    rgb, depth, K = scene([*with_head(person), wall], 0.0)
    det = DepthClusterDetector(DepthParams(camera_height_m=CAMERA_HEIGHT))
    for _ in range(2):
        boxes, _ = det.detect(rgb, depth, K)
    assert len(boxes) == 1  # the partition, cut by the same edge, is flat
    box = boxes[0]
    expected = np.clip(expected_box(person, K, 0.0), 0, [W, H, W, H])
    assert box[3] >= H - 2 and iou_matrix(boxes, expected[None]).max() > 0.7
    seen_bottom = CAMERA_HEIGHT - 1.25 * (H / 2) / K[1, 1]  # the lower edge's height at the back face
    assert seen_bottom > DepthParams().max_bottom_m


def test_a_person_behind_a_sofa_is_seen_from_the_waist_up() -> None:
    # the sofa's back (0.9 m) hides the person below it: Basso/Munaro's rule (down to max_bottom_m)
    # drops them; the occlusion rule keeps them, and only because the sofa is in front
    person, sofa = Block(0.8, 3.6, 0.45, 1.75, 0.3), Block(0.8, 3.0, 1.2, 0.9, 0.5)  # off-axis: its side shows
    rgb, depth, K = scene([*with_head(person), sofa], 0.0)
    found = {}
    for occluded in (0.0, OCCLUDED):
        det = DepthClusterDetector(DepthParams(camera_height_m=CAMERA_HEIGHT, occluded_max_bottom_m=occluded))
        for _ in range(2):
            boxes, _ = det.detect(rgb, depth, K)
        found[occluded] = boxes
    assert len(found[0.0]) == 0
    (box,) = found[OCCLUDED]
    assert iou_matrix(box[None], expected_box(person, K, 0.0)[None])[0, 0] > 0.6  # down to the feet, behind the sofa
    # the same upper body with nothing in front (floating: a picture, a lamp) is not a person
    rgb, depth, K = scene([Block(0.8, 3.6, 0.45, 1.75, 0.3, bottom=0.9)], 0.0)
    det = DepthClusterDetector(DepthParams(camera_height_m=CAMERA_HEIGHT, occluded_max_bottom_m=OCCLUDED))
    assert len(det.detect(rgb, depth, K)[0]) == 0


def test_a_person_behind_a_sofa_they_touch_is_split_out_of_it() -> None:
    # the person leans on the sofa's back: one cluster 2 m wide, split by the parts above 1.05 m;
    # the part's lowest points are hidden by the sofa, so it need not reach the floor
    person, sofa = Block(1.0, 3.55, 0.45, 1.75, 0.3), Block(0.6, 3.2, 2.0, 0.9, 0.4)
    rgb, depth, K = scene([*with_head(person), sofa], 0.0)
    assert len(DepthClusterDetector(DepthParams(camera_height_m=CAMERA_HEIGHT)).detect(rgb, depth, K)[0]) == 0  # off
    det = DepthClusterDetector(DepthParams(camera_height_m=CAMERA_HEIGHT, occluded_max_bottom_m=OCCLUDED))
    for _ in range(2):
        boxes, _ = det.detect(rgb, depth, K)
    assert len(boxes) == 1
    assert iou_matrix(boxes, expected_box(person, K, 0.0)[None]).max() > 0.5


def test_the_floor_from_the_transforms_replaces_a_lost_estimate() -> None:
    # a detector configured for a level camera while the head pitches 20 deg down, beyond what
    # it re-acquires: its own estimate fails, the floor given by the robot's transforms works
    rgb, depth, K = scene([*with_heads(PEOPLE), TABLE], 20.0)
    truth = initial_plane(CAMERA_HEIGHT, 20.0)
    det = DepthClusterDetector(DepthParams(camera_height_m=CAMERA_HEIGHT, tilt_deg=0.0,
                                           ground=GroundParams(acquire_max_deg=10.0)))
    assert len(det.detect(rgb, depth, K)[0]) == 0  # beyond re-acquisition
    off = initial_plane(CAMERA_HEIGHT + 0.05, 21.5)  # the transforms' floor, 5 cm and 1.5 deg off
    boxes, _ = det.detect(rgb, depth, K, floor=off)
    assert len(boxes) == 2
    assert det.plane.angle_to(truth) < np.deg2rad(0.3) and abs(det.plane.offset - CAMERA_HEIGHT) < 0.02  # refined
    wrong = initial_plane(CAMERA_HEIGHT + 0.4, 20.0)  # a floor refinement may not stray this far from
    det.detect(rgb, depth, K, floor=wrong)
    assert det.plane is wrong and det.plane_inliers == 0


def test_plane_converges_from_a_wrong_initial_guess() -> None:
    rgb, depth, K = scene([*with_heads(PEOPLE), TABLE], 20.0)
    det = DepthClusterDetector(DepthParams(camera_height_m=1.3, tilt_deg=14.0))
    for _ in range(4):
        boxes, _ = det.detect(rgb, depth, K)
    assert det.plane.angle_to(initial_plane(CAMERA_HEIGHT, 20.0)) < np.deg2rad(0.5)
    assert abs(det.plane.offset - CAMERA_HEIGHT) < 0.02
    assert len(boxes) == 2


def test_floor_is_reacquired_when_the_head_tilts_beyond_tracking() -> None:
    """A pan-tilt head pitched 20 deg more than configured: one-frame refinement cannot
    reach the floor, re-acquisition around the configured plane does."""
    rgb, depth, K = scene([*with_heads(PEOPLE), TABLE], 20.0)
    det = DepthClusterDetector(DepthParams(camera_height_m=CAMERA_HEIGHT, tilt_deg=0.0))
    boxes, _ = det.detect(rgb, depth, K)
    assert det.plane.angle_to(initial_plane(CAMERA_HEIGHT, 20.0)) < np.deg2rad(0.5)
    assert len(boxes) == 2


def test_a_person_beside_furniture_is_split_out_of_the_merged_cluster() -> None:
    """A person touching a chair-high block and a table makes one cluster over 1.5 m wide."""
    person = Block(0.0, 3.5, 0.5, 1.75, 0.3)
    bench = Block(0.85, 3.5, 1.2, 0.9, 0.5)  # touches the person's side
    rgb, depth, K = scene([*with_head(person), bench], 0.0)
    det = DepthClusterDetector(DepthParams(camera_height_m=CAMERA_HEIGHT, tilt_deg=0.0))
    boxes, _ = det.detect(rgb, depth, K)
    assert len(boxes) == 1
    assert iou_matrix(boxes, expected_box(person, K, 0.0)[None]).max() > 0.6


def _person(x: float, z: float, height: float) -> list[Block]:
    """A body (0.45 m wide, up to the shoulders) and a head (0.2 m wide) on top of it."""
    shoulders = height - 0.28
    return [Block(x, z, 0.45, shoulders, 0.3), Block(x, z, 0.2, height, 0.2, bottom=shoulders)]


def test_two_people_side_by_side_in_one_cluster_are_split_by_their_heads() -> None:
    """Shoulder to shoulder, two people make one cluster narrower than max_width_m (0.9 m):
    without the head rule it is one person between them; with it, one per head."""
    left, right = _person(-0.225, 3.5, 1.80), _person(0.225, 3.5, 1.70)
    rgb, depth, K = scene([*left, *right], 0.0)
    found = {}
    for separation in (0.0, DepthParams().head_separation_m):
        det = DepthClusterDetector(DepthParams(camera_height_m=CAMERA_HEIGHT, head_separation_m=separation))
        for _ in range(2):
            boxes, _ = det.detect(rgb, depth, K)
        found[separation] = (boxes, np.sort(det.heights))
    assert len(found[0.0][0]) == 1  # without the rule
    boxes, heights = found[DepthParams().head_separation_m]
    assert len(boxes) == 2
    np.testing.assert_allclose(heights, [1.70, 1.80], atol=0.08)
    truth = np.array([expected_box(b, K, 0.0) for b in (left[0], right[0])])  # the bodies' boxes
    assert iou_matrix(boxes, truth).max(axis=0).min() > 0.5, iou_matrix(boxes, truth)


def test_a_flat_topped_box_of_a_persons_size_is_not_a_person() -> None:
    """A cupboard 0.5 m wide and 1.8 m tall, seen off-axis (its side shows: not flat), passes every
    other rule; its top is a slab wider than a head. The same box with a head on top is a person.
    With its top cut by the image's upper edge nothing shows a slab, and it stays."""
    cupboard = Block(1.0, 3.0, 0.5, 1.8, 0.4)
    rgb, depth, K = scene([cupboard], 0.0)
    found = {}
    for width in (0.0, DepthParams().head_max_width_m):
        det = DepthClusterDetector(DepthParams(camera_height_m=CAMERA_HEIGHT, head_max_width_m=width))
        for _ in range(2):
            boxes, _ = det.detect(rgb, depth, K)
        found[width] = len(boxes)
    assert found == {0.0: 1, DepthParams().head_max_width_m: 0}
    rgb, depth, K = scene(with_head(cupboard), 0.0)
    assert len(DepthClusterDetector(DepthParams(camera_height_m=CAMERA_HEIGHT)).detect(rgb, depth, K)[0]) == 1
    rgb, depth, K = scene([Block(0.5, 1.8, 0.5, 1.95, 0.3)], 10.0)  # the image ends at 1.68 m on it
    tilted = DepthClusterDetector(DepthParams(camera_height_m=CAMERA_HEIGHT, tilt_deg=10.0))
    for _ in range(2):
        boxes, _ = tilted.detect(rgb, depth, K)
    assert len(boxes) == 1


def test_a_flat_topped_wall_end_is_not_split_into_heads() -> None:
    """A partition's top has points far apart at the same height but no dip between them:
    one cluster, no heads, and (being flat) no person; a person beside it is still found."""
    wall = Block(-1.0, 3.5, 0.6, 1.9, 0.05)  # 0.6 m wide, thin, facing the camera
    person = _person(0.9, 4.5, 1.75)
    rgb, depth, K = scene([wall, *person], 0.0)
    det = DepthClusterDetector(DepthParams(camera_height_m=CAMERA_HEIGHT))
    seen: list[int] = []
    real = det._heads

    def counting(*args: np.ndarray) -> np.ndarray:
        heads = real(*args)
        seen.append(len(heads))
        return heads

    det._heads = counting  # type: ignore[method-assign]
    boxes, _ = det.detect(rgb, depth, K)
    assert sorted(seen) == [1, 1]  # the wall's top and the person's head: one peak each
    assert len(boxes) == 1
    assert iou_matrix(boxes, expected_box(person[0], K, 0.0)[None]).max() > 0.5


def test_sitting_people_need_a_lower_height_range() -> None:
    rgb, depth, K = scene(with_heads([PEOPLE[0], SITTING]), 10.0)
    standing_only = DepthParams(camera_height_m=CAMERA_HEIGHT, tilt_deg=10.0, seated=SeatedParams(enabled=False))
    assert len(DepthClusterDetector(standing_only).detect(rgb, depth, K)[0]) == 1  # Basso/Munaro's height rule
    relaxed = DepthClusterDetector(replace(standing_only, min_height_m=1.0))
    assert len(relaxed.detect(rgb, depth, K)[0]) == 2
    default = DepthClusterDetector(DepthParams(camera_height_m=CAMERA_HEIGHT, tilt_deg=10.0))
    assert len(default.detect(rgb, depth, K)[0]) == 2 and sorted(default.postures) == ["sitting", "standing"]


def test_hog_confirmation_rejects_shapes_that_are_not_people() -> None:
    rgb, depth, K = scene(with_heads(PEOPLE), 0.0)  # flat grey boxes: person-sized, but HOG sees no person
    det = DepthClusterDetector(DepthParams(camera_height_m=CAMERA_HEIGHT, hog_confirm=True, hog_min_score=0.5))
    assert len(det.detect(rgb, depth, K)[0]) == 0
    lenient = DepthClusterDetector(DepthParams(camera_height_m=CAMERA_HEIGHT, hog_confirm=True, hog_min_score=0.0))
    boxes, scores = lenient.detect(rgb, depth, K)
    assert len(boxes) == 2 and np.all(scores < 0.5)


def test_invalid_depth_and_empty_scene() -> None:
    rgb, depth, K = scene(with_heads(PEOPLE), 0.0)
    det = DepthClusterDetector(DepthParams(camera_height_m=CAMERA_HEIGHT))
    nan = np.full_like(depth, np.nan)
    boxes, scores = det.detect(rgb, nan, K)
    assert boxes.shape == (0, 4) and scores.shape == (0,)
    noisy = depth.copy()
    noisy[::7, ::5] = np.nan  # holes do not break the clusters
    assert len(det.detect(rgb, noisy, K)[0]) == 2


def test_depth_backend_needs_depth_and_intrinsics() -> None:
    rgb, depth, K = scene(with_heads(PEOPLE), 0.0)
    det = DepthClusterDetector()
    with pytest.raises(DetectorError, match="depth image"):
        det.detect(rgb, None, K)
    with pytest.raises(DetectorError, match="intrinsics"):
        det.detect(rgb, depth, None)
    with pytest.raises(DetectorError, match="differs"):
        det.detect(rgb, depth[:100], K)


def test_voxel_grid_averages_per_cell() -> None:
    pts = np.array([[0.01, 0.01, 0.01], [0.05, 0.05, 0.05], [0.2, 0.0, 0.0]])
    out = voxel_grid(pts, 0.06)
    assert len(out) == 2
    np.testing.assert_allclose(sorted(out[:, 0]), [0.03, 0.2])


def test_clusters_split_by_gap() -> None:
    a = np.column_stack([np.linspace(0, 1, 20), np.zeros(20), np.zeros(20)])
    b = a + [0.0, 0.0, 0.5]
    count, labels = cluster_points(np.vstack([a, b]), 0.1)
    assert count == 2 and len(set(labels[:20])) == 1 and labels[0] != labels[20]


def test_refine_plane_keeps_previous_without_floor() -> None:
    rng = np.random.default_rng(0)
    prior = initial_plane(1.2, 0.0)
    wall = np.column_stack([rng.uniform(-1, 1, 500), rng.uniform(-1, 0.5, 500), np.full(500, 3.0)])
    plane, inliers = refine_plane(wall, prior, GroundParams(), rng)
    assert inliers == 0 and plane is prior
