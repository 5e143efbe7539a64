"""A robot's static map as an occupancy grid, and how far each place is from its obstacles.

The grid is ROS's ``nav_msgs/OccupancyGrid`` (and ``map_server``'s): cell ``(row, col)`` covers
``[col, col + 1) x [row, row + 1)`` cells of ``resolution`` metres from ``origin`` (x, y, yaw: the
pose of cell (0, 0)'s outer corner in the map frame), row 0 at the lowest y. A cell is occupied
(a wall, furniture the robot's laser sees), free, or unknown; only occupied cells are obstacles.

:class:`ObstacleMap` answers, for points in the map frame, how far they are from the nearest
occupied cell. It keeps the occupied cells only and searches around each point it is asked
about (the nearest occupied cell within a window; for distances without a bound, a k-d tree of
the occupied cells, built at the first such question), so a map costs next to nothing to take:
slam_toolbox republishes a growing map every few seconds, and a tracker must not stop for it.
Pure numpy and scipy; reading and writing map files is :mod:`common.geometry.map_file`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from functools import lru_cache

import numpy as np
from scipy import ndimage
from scipy.spatial import cKDTree

__all__ = ["ObstacleMap"]


#: windows up to this many cells from their point (a birth check's 0.1 m is 3 at 5 cm); farther the k-d tree
_WINDOW_MAX = 16


@lru_cache(maxsize=8)
def _window(k: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The cells of a (2k + 1)^2 window: row and column offsets and their squared distances."""
    dr, dc = (a.reshape(-1) for a in np.mgrid[-k:k + 1, -k:k + 1])
    return dr, dc, (dr * dr + dc * dc).astype(np.float64)


@dataclass(frozen=True, eq=False)
class ObstacleMap:
    """Distances to a static map's obstacles.

    ``occupied`` (H, W) bool: the obstacles' cells, row 0 at the lowest y; ``resolution`` (m per
    cell); ``origin`` (x, y, yaw) as in a ROS map. Build one with :meth:`from_occupied`.
    """

    occupied: np.ndarray
    resolution: float
    origin: tuple[float, float, float] = (0.0, 0.0, 0.0)

    def __post_init__(self) -> None:
        if self.occupied.ndim != 2 or not self.occupied.size:
            raise ValueError(f"an obstacle map needs a 2-D grid, got shape {self.occupied.shape}")
        if not (math.isfinite(self.resolution) and self.resolution > 0):
            raise ValueError(f"map resolution must be a positive number of metres per cell, got {self.resolution}")
        if len(self.origin) != 3 or not all(math.isfinite(v) for v in self.origin):
            raise ValueError(f"map origin must be three finite numbers (x, y, yaw), got {self.origin}")

    @classmethod
    def from_occupied(cls, occupied: np.ndarray, resolution: float,
                      origin: tuple[float, float, float] = (0.0, 0.0, 0.0), min_extent_m: float = 0.0) -> ObstacleMap:
        """From an (H, W) bool grid of occupied cells, row 0 at the lowest y. Connected occupied
        areas (8-neighbours) whose bounding box is shorter than ``min_extent_m`` on both sides
        are left out: posts such as chair and table legs, where walls and furniture remain."""
        occupied = np.array(occupied, bool)  # a copy: the map keeps its own
        if occupied.ndim != 2 or not occupied.size:
            raise ValueError(f"occupied must be a non-empty (H, W) grid, got shape {occupied.shape}")
        if min_extent_m > 0 and occupied.any():
            labels, count = ndimage.label(occupied, structure=np.ones((3, 3), bool))
            cells = min_extent_m / resolution
            keep = np.ones(count + 1, bool)
            for k, (rows, cols) in enumerate(ndimage.find_objects(labels), 1):
                keep[k] = max(rows.stop - rows.start, cols.stop - cols.start) >= cells
            occupied &= keep[labels]
        return cls(occupied, float(resolution), tuple(float(v) for v in origin))  # type: ignore[arg-type]

    @property
    def shape(self) -> tuple[int, int]:
        return self.occupied.shape  # type: ignore[return-value]

    def cells(self, xy: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(row, col, on_map) of map-frame points ``xy`` (N, 2); row and col are clipped where off the map."""
        xy = np.asarray(xy, np.float64).reshape(-1, 2)
        x0, y0, yaw = self.origin
        dx, dy = xy[:, 0] - x0, xy[:, 1] - y0
        c, s = math.cos(yaw), math.sin(yaw)
        u, v = (c * dx + s * dy) / self.resolution, (-s * dx + c * dy) / self.resolution  # into the grid's axes
        h, w = self.shape
        col, row = np.floor(u), np.floor(v)
        on = (col >= 0) & (col < w) & (row >= 0) & (row < h)  # False for NaN
        row, col = np.where(on, row, 0.0), np.where(on, col, 0.0)
        return row.astype(np.intp), col.astype(np.intp), on

    def clearance(self, xy: np.ndarray, up_to: float = math.inf) -> np.ndarray:
        """(N,) metres from map-frame points ``xy`` (N, 2) to the nearest obstacle, to a cell's
        precision (the distance between the cells' centres less half a cell): 0 inside an occupied
        cell; ``inf`` off the map (no obstacle known there), for NaN points, and beyond ``up_to``
        (only the cells that near are searched)."""
        row, col, on = self.cells(xy)
        out = np.full(len(row), np.inf)
        if not on.any():
            return out
        res = self.resolution
        # the cells whose centre can be that near, a ring more for rounding: a window around each point
        k = max(0, int(math.floor(max(up_to, 0.0) / res + 0.5))) + 1 if math.isfinite(up_to) else _WINDOW_MAX + 1
        if k <= _WINDOW_MAX:
            dr, dc, d2 = _window(k)
            hit = self._padded(k)[row[on, None] + (dr + k), col[on, None] + (dc + k)]  # (M, window) around each
            out[on] = np.sqrt(np.where(hit, d2, np.inf).min(axis=1))
        else:
            tree = self._tree()
            if tree is None:
                return out
            cells = np.column_stack([row[on], col[on]]).astype(np.float64)
            out[on] = tree.query(cells)[0]
        d = (out * res).astype(np.float32).astype(np.float64)  # metres between the cells' centres
        clear = np.maximum(d - 0.5 * res, 0.0)
        return np.where(clear <= up_to, clear, np.inf)

    def _padded(self, k: int) -> np.ndarray:
        """The occupied cells with a free border of ``k`` cells, so every window lies inside (kept for the last ``k``)."""
        got = self.__dict__.get("_pad")
        if got is None or got[0] != k:
            got = (k, np.pad(self.occupied, k))
            object.__setattr__(self, "_pad", got)
        return got[1]  # type: ignore[no-any-return]

    def _tree(self) -> cKDTree | None:
        """The k-d tree of the occupied cells' (row, col), built once (None: no obstacle)."""
        if "_kd" not in self.__dict__:
            cells = np.argwhere(self.occupied)
            object.__setattr__(self, "_kd", cKDTree(cells.astype(np.float64)) if len(cells) else None)
        return self.__dict__["_kd"]  # type: ignore[no-any-return]

    def blocked(self, xy: np.ndarray, clearance_m: float) -> np.ndarray:
        """(N,) bool: which points lie on an obstacle or within ``clearance_m`` of one."""
        return self.clearance(xy, up_to=clearance_m) <= clearance_m
