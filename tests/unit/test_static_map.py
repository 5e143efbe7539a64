"""The robot's static map: ROS map files, distances to obstacles, the apartment's laser map, and
the robust tracker's births (no track is born on a wall or a door jamb)."""

from __future__ import annotations

import math
from pathlib import Path

import cv2
import numpy as np
import pytest
from pydantic import ValidationError

from common.geometry.map_file import MapFileError, OccupancyGrid, read_map, write_map
from common.geometry.occupancy import ObstacleMap
from perception.cli import main
from services.tracker.config import TrackerConfig
from services.tracker.core.robust import RobustParams, RobustTracker, ScoreModel
from services.tracker.core.types import FrameInput
from tools.simulator.core.apartment import default_apartment
from tools.simulator.core.laser_map import laser_map

RES = 0.05


def wall_map(origin: tuple[float, float, float] = (0.0, 0.0, 0.0)) -> tuple[np.ndarray, ObstacleMap]:
    """A 4 x 3 m grid with a wall along x = 2.0-2.1 m (y 0-2 m) and one chair leg at (1.0, 2.5)."""
    occupied = np.zeros((60, 80), bool)
    occupied[0:40, 40:42] = True  # rows are y, columns x
    occupied[50, 20] = True
    return occupied, ObstacleMap.from_occupied(occupied, RES, origin, min_extent_m=0.3)


def test_clearance_is_the_distance_to_the_nearest_obstacle_to_a_cell() -> None:
    _, m = wall_map()
    d = m.clearance(np.array([[2.05, 1.0], [1.5, 1.0], [2.6, 1.0], [2.05, 2.5], [9.0, 1.0], [-0.1, 1.0],
                              [np.nan, 1.0]]))
    assert d[0] == 0.0  # on the wall
    assert d[1] == pytest.approx(0.5, abs=RES) and d[2] == pytest.approx(0.5, abs=RES)
    assert d[3] == pytest.approx(0.5, abs=RES)  # beyond the wall's end
    assert np.isinf(d[4:]).all()  # off the map and NaN: no obstacle known
    assert m.blocked(np.array([[2.05, 1.0], [1.92, 1.0], [1.5, 1.0]]), 0.1).tolist() == [True, True, False]


def test_posts_shorter_than_the_minimum_extent_are_no_obstacle() -> None:
    occupied, m = wall_map()
    near_leg = np.array([[1.02, 2.52]])
    assert math.isinf(m.clearance(near_leg)[0]) or m.clearance(near_leg)[0] > 0.5  # the leg is left out
    with_posts = ObstacleMap.from_occupied(occupied, RES)
    assert with_posts.clearance(near_leg)[0] == 0.0
    assert np.isinf(ObstacleMap.from_occupied(np.zeros((3, 3), bool), RES).clearance(np.array([[0.0, 0.0]])))[0]


def test_a_bounded_search_finds_what_the_whole_map_holds() -> None:
    rng = np.random.default_rng(3)
    occupied = rng.random((70, 90)) < 0.01
    occupied[30, :55] = True  # a wall reaching the map's left edge: windows cut by the border
    m = ObstacleMap.from_occupied(occupied, RES, (0.4, -1.2, 0.7))
    occupied[:] = False  # the map keeps its own cells
    points = np.vstack([rng.uniform(-3.0, 5.0, (1000, 2)), [[np.nan, 0.0]]])  # on the map, around it and off it
    whole = m.clearance(points)  # the k-d tree over every obstacle
    assert 100 < np.isfinite(whole).sum() < 1000 and (whole == 0.0).any()
    for bound in (0.0, 0.05, 0.1, 0.125, 0.3, 1.0):  # a window of cells around each point
        np.testing.assert_array_equal(m.clearance(points, up_to=bound), np.where(whole <= bound, whole, np.inf))
        np.testing.assert_array_equal(m.blocked(points, bound), whole <= bound)


def test_the_origin_and_its_yaw_place_the_grid_in_the_map_frame() -> None:
    _, shifted = wall_map((10.0, -5.0, 0.0))
    assert shifted.clearance(np.array([[12.05, -4.0]]))[0] == 0.0
    _, turned = wall_map((0.0, 0.0, math.pi / 2))  # the grid's x axis along the map's y
    assert turned.clearance(np.array([[-1.0, 2.05]]))[0] == 0.0  # grid (x 2.05, y 1.0) -> map (-1.0, 2.05)
    assert turned.clearance(np.array([[1.0, 2.05]]))[0] == math.inf


def test_bad_grids_are_refused() -> None:
    with pytest.raises(ValueError, match="non-empty"):
        ObstacleMap.from_occupied(np.zeros((0, 3), bool), RES)
    with pytest.raises(ValueError, match="resolution"):
        ObstacleMap.from_occupied(np.zeros((3, 3), bool), 0.0)


# ------------------------------------------------------------------ map files
def test_a_written_map_reads_back_cell_for_cell(tmp_path: Path) -> None:
    occupied, _ = wall_map()
    unknown = np.zeros_like(occupied)
    unknown[55:, 60:] = True
    image = write_map(tmp_path / "map.yaml", OccupancyGrid(occupied, unknown, RES, (1.5, -2.0, 0.25)))
    assert image == tmp_path / "map.pgm" and image.is_file()
    grid = read_map(tmp_path / "map.yaml")
    assert np.array_equal(grid.occupied, occupied) and np.array_equal(grid.unknown, unknown)
    assert grid.resolution == RES and grid.origin == (1.5, -2.0, 0.25)
    pixels = cv2.imread(str(image), cv2.IMREAD_UNCHANGED)
    assert pixels[-1, 40] == 0 and pixels[0, 0] == 254  # the image's bottom row is the lowest y


def test_a_map_saved_again_is_read_again_even_when_only_its_image_changed(tmp_path: Path) -> None:
    import os

    from common.geometry.map_file import load_obstacles

    occupied, _ = wall_map()
    path = tmp_path / "map.yaml"
    image = write_map(path, OccupancyGrid(occupied, np.zeros_like(occupied), RES, (0.0, 0.0, 0.0)))
    before = load_obstacles(path, 0.3)
    assert load_obstacles(path, 0.3) is before  # the distances are computed once per version
    yaml_stat = path.stat()
    moved = np.roll(occupied, 20, axis=1)  # the wall 1 m further in x, the image the same size
    assert cv2.imwrite(str(image), np.where(moved, 0, 254).astype(np.uint8)[::-1])  # the image alone saved again
    assert path.stat().st_mtime_ns == yaml_stat.st_mtime_ns
    stat = image.stat()
    os.utime(image, ns=(stat.st_atime_ns, stat.st_mtime_ns + 1_000_000_000))  # a later save, whatever the clock
    after = load_obstacles(path, 0.3)
    wall_then, wall_now = np.array([[2.05, 1.0]]), np.array([[3.05, 1.0]])
    assert before.blocked(wall_then, 0.0).tolist() == [True] and before.blocked(wall_now, 0.0).tolist() == [False]
    assert after.blocked(wall_then, 0.0).tolist() == [False] and after.blocked(wall_now, 0.0).tolist() == [True]


def test_map_saver_files_read_as_nav2_reads_them(tmp_path: Path) -> None:
    """A map as map_saver writes it (0 occupied, 254 free, 205 unknown, free_thresh 0.25, Nav2
    then reads 205 as free), negated and raw images, and a colour PNG."""
    pixels = np.array([[0, 205, 254], [100, 254, 0]], np.uint8)
    cv2.imwrite(str(tmp_path / "a.pgm"), pixels)
    (tmp_path / "a.yaml").write_text("image: a.pgm\nmode: trinary\nresolution: 0.1\norigin: [-1.0, 2.0, 0.0]\n"
                                     "negate: 0\noccupied_thresh: 0.65\nfree_thresh: 0.25\n")
    grid = read_map(tmp_path / "a.yaml")
    assert grid.occupied[::-1].tolist() == [[True, False, False], [False, False, True]]
    assert grid.unknown[::-1].tolist() == [[False, False, False], [True, False, False]]  # 205 is p 0.196 < 0.25
    (tmp_path / "n.yaml").write_text("image: a.pgm\nresolution: 0.1\norigin: [0, 0, 0]\nnegate: 1\n"
                                     "occupied_thresh: 0.65\nfree_thresh: 0.196\n")
    assert read_map(tmp_path / "n.yaml").occupied[::-1].tolist() == [[False, True, True], [False, True, False]]
    cv2.imwrite(str(tmp_path / "r.png"), np.array([[100, 0, 255], [64, 65, 50]], np.uint8))
    (tmp_path / "r.yaml").write_text("image: r.png\nmode: raw\nresolution: 0.1\norigin: [0, 0, 0]\n"
                                     "occupied_thresh: 0.65\nfree_thresh: 0.196\n")
    raw = read_map(tmp_path / "r.yaml")
    assert raw.occupied[::-1].tolist() == [[True, False, False], [False, True, False]]
    assert raw.unknown[::-1].tolist() == [[False, False, True], [False, False, False]]
    cv2.imwrite(str(tmp_path / "c.png"), np.stack([pixels] * 3, axis=2))
    (tmp_path / "c.yaml").write_text("image: c.png\nresolution: 0.1\norigin: [0, 0, 0]\n")
    assert np.array_equal(read_map(tmp_path / "c.yaml").occupied, grid.occupied)


@pytest.mark.parametrize("text, message", [
    (None, "no map file"),
    ("- just\n- a list\n", "YAML mapping"),
    ("image: a.pgm\nresolution: 0.05\n", "lacks origin"),
    ("image: a.pgm\nresolution: 0.05\norigin: [0, 0]\n", r"origin must be \[x, y, yaw\]"),
    ("image: a.pgm\nresolution: fine\norigin: [0, 0, 0]\n", "'resolution' must be a number"),
    ("image: a.pgm\nresolution: 0.05\norigin: [0, 0, 0]\nmode: fancy\n", "mode must be trinary"),
    ("image: missing.pgm\nresolution: 0.05\norigin: [0, 0, 0]\n", "cannot read its image"),
])
def test_unreadable_map_files_name_the_problem(tmp_path: Path, text: str | None, message: str) -> None:
    cv2.imwrite(str(tmp_path / "a.pgm"), np.zeros((2, 2), np.uint8))
    path = tmp_path / "map.yaml"
    if text is not None:
        path.write_text(text)
    with pytest.raises(MapFileError, match=message):
        read_map(path)


# ------------------------------------------------------------------ the apartment's laser map
def test_the_apartment_maps_as_its_laser_sees_it() -> None:
    occupied, unknown, origin = laser_map(default_apartment())
    m = ObstacleMap.from_occupied(occupied, RES, origin)
    on = m.clearance(np.array([[6.02, 1.0], [6.06, 4.2], [1.0, 4.0], [1.5, 4.0], [4.6, 3.0], [-0.02, 3.0],
                               [4.0 + 0.03, 4.9 + 0.03]]))
    assert on[0] == 0.0  # the partition wall's face (its inside is unknown, as a laser leaves it)
    assert on[1] > 0.5  # the door in it is open
    assert on[2] == 0.0 and on[3] > 0.3  # the sofa's outline; inside it is unknown, not an obstacle
    assert unknown[m.cells(np.array([[1.5, 4.0]]))[0][0], m.cells(np.array([[1.5, 4.0]]))[1][0]]
    assert on[4] > 1.0  # the open floor
    assert on[5] == 0.0  # the outer wall
    assert on[6] == 0.0  # a table leg (the table top is above the laser)


def test_simulate_writes_the_map_a_tracker_reads(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    path = tmp_path / "apartment.yaml"
    assert main(["simulate", "--write-map", str(path)]) == 0
    assert "apartment.pgm" in capsys.readouterr().out
    config = TrackerConfig.model_validate({"robust": {"static_map": {"path": str(path)}}})
    obstacles = config.robust.static_map.obstacles
    assert obstacles is not None and obstacles.clearance(np.array([[6.05, 1.0]]))[0] == 0.0
    assert config.build_tracker(None).params.obstacles is obstacles  # type: ignore[attr-defined]


# ------------------------------------------------------------------ the tracker
def test_no_track_is_born_on_the_maps_obstacles_but_a_track_walks_past_them() -> None:
    _, m = wall_map()
    tracker = RobustTracker(RobustParams(obstacles=m, birth_clearance_m=0.1, scores=ScoreModel(0.0, 1.0, 0.5)))
    blocked, confirmed = 0, set()
    for k in range(30):  # a jamb at the wall's face, and a person walking along the wall 0.4 m from it
        t = k / 10
        pos = np.array([[1.97, 1.0, 1.0], [1.6, 0.2 + 0.05 * k, 1.0]])
        result = tracker.step(t, FrameInput.of(pos, None, None, np.ones(2)))
        blocked += result.births_blocked
        confirmed |= {(v.id, round(float(v.mean[0]), 1)) for v in result.confirmed}
    assert blocked == 30  # every frame's detection on the wall, counted
    assert {x for _, x in confirmed} == {1.6}
    # a person already tracked keeps their track where a detection strays onto the wall's face
    for k in range(30, 40):
        result = tracker.step(k / 10, FrameInput.of(np.array([[1.6 + (0.35 if k == 35 else 0.0), 0.2 + 0.05 * k, 1.0]]),
                                None, None, np.ones(1)))
        assert [v.id for v in result.confirmed] == [1]
    assert result.births_blocked == 0


def test_a_missing_or_broken_map_stops_the_tracker_with_the_fix(tmp_path: Path) -> None:
    with pytest.raises(ValidationError, match="map_saver_cli"):
        TrackerConfig.model_validate({"robust": {"static_map": {"path": str(tmp_path / "nope.yaml")}}})
    (tmp_path / "bad.yaml").write_text("image: x.pgm\n")
    with pytest.raises(ValidationError, match="lacks resolution, origin"):
        TrackerConfig.model_validate({"robust": {"static_map": {"path": str(tmp_path / "bad.yaml")}}})
    assert main(["track", "--detections", str(tmp_path / "d.csv"), "--output", str(tmp_path / "t.csv"),
                 "--static-map", str(tmp_path / "nope.yaml")]) == 2


def test_the_page_draws_a_map_as_runs_of_occupied_cells() -> None:
    from tools.viewer.core.drawing import occupied_runs

    grid = np.zeros((3, 6), bool)
    grid[0, 1:4] = grid[0, 5] = grid[2, :] = True
    assert occupied_runs(grid) == [[0, 1, 4], [0, 5, 6], [2, 0, 6]]
    assert occupied_runs(np.zeros((2, 2), bool)) == []
