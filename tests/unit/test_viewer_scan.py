"""The page's laser pieces (tools/viewer/core/scans.py): a scan's returns as points in the map,
the positions that have no image box, and each laser's newest scan going stale."""

from __future__ import annotations

import math

import numpy as np
import pytest

from tools.viewer.core.scans import Newest, flat, no_box, scan_points


def _yaw(rad: float) -> np.ndarray:
    c, s = math.cos(rad), math.sin(rad)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


def test_each_return_lands_where_its_beam_points_through_the_scanners_pose() -> None:
    # beams at -90, 0 and +90 degrees, 2 m each; the scanner 1 m ahead of the map's origin, turned 90 degrees left
    pts = scan_points(np.array([2.0, 2.0, 2.0], np.float32), -math.pi / 2, math.pi / 2, 0.1, 10.0,
                      _yaw(math.pi / 2), np.array([1.0, 0.0, 0.3]))
    assert pts.shape == (3, 2)
    assert pts == pytest.approx(np.array([[3.0, 0.0], [1.0, 2.0], [-1.0, 0.0]]), abs=1e-6)


def test_beams_with_no_return_have_no_point() -> None:
    ranges = np.array([np.nan, np.inf, -np.inf, 0.125, 0.25, 3.0, 30.0, 40.0], np.float32)  # limits 0.25 .. 30 m
    pts = scan_points(ranges, 0.0, 0.01, 0.25, 30.0, np.eye(3), np.zeros(3))
    assert pts == pytest.approx(np.array([[3.0 * math.cos(0.05), 3.0 * math.sin(0.05)]]), abs=1e-6)
    assert scan_points(np.full(5, np.nan, np.float32), 0.0, 0.1, 0.1, 30.0, np.eye(3), np.zeros(3)).shape == (0, 2)


def test_a_dense_scan_is_thinned_evenly_along_the_sweep_keeping_both_ends() -> None:
    n = 1081
    angles = -3 * math.pi / 4 + np.arange(n) * (1.5 * math.pi / (n - 1))
    pts = scan_points(np.full(n, 5.0, np.float32), float(angles[0]), float(angles[1] - angles[0]), 0.1, 30.0,
                      np.eye(3), np.zeros(3), max_points=100)
    assert len(pts) == 100
    assert pts[0] == pytest.approx([5 * math.cos(angles[0]), 5 * math.sin(angles[0])], abs=1e-6)
    assert pts[-1] == pytest.approx([5 * math.cos(angles[-1]), 5 * math.sin(angles[-1])], abs=1e-6)
    steps = np.diff(np.unwrap(np.arctan2(pts[:, 1], pts[:, 0])))
    assert steps.max() - steps.min() < 2 * (angles[1] - angles[0])  # even within a beam or so


def test_points_go_to_the_page_flat_and_rounded_to_the_centimetre() -> None:
    assert flat(np.array([[1.23456, -2.0], [0.004, 7.899]])) == [1.23, -2.0, 0.0, 7.9]
    assert flat(np.zeros((0, 2))) == []


def test_a_zero_box_is_no_box() -> None:
    boxes = np.array([[0, 0, 0, 0], [10, 20, 30, 60], [5, 5, 5, 9], [1, 2, 3, 2]], float)
    assert no_box(boxes).tolist() == [True, False, True, True]
    assert no_box(np.zeros((0, 4))).tolist() == []


def test_each_lasers_newest_scan_until_it_goes_quiet() -> None:
    newest: Newest[str] = Newest(stale_s=1.0)
    newest.put("rear", 0.0, "rear 1")
    newest.put("front", 0.2, "front 1")
    newest.put("front", 0.5, "front 2")
    assert newest.fresh(0.9) == {"front": (0.5, "front 2"), "rear": (0.0, "rear 1")}
    assert list(newest.fresh(1.2)) == ["front"]  # the rear laser stopped
    assert newest.fresh(2.0) == {}
