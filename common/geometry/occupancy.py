"""A robot's static map as an occupancy grid, and how far each place is from its obstacles.

The grid is ROS's ``nav_msgs/OccupancyGrid`` (and ``map_server``'s): cell ``(row, col)`` covers
``[col, col + 1) x [row, row + 1)`` cells of ``resolution`` metres from ``origin`` (x, y, yaw: the
pose of cell (0, 0)'s outer corner in the map frame), row 0 at the lowest y. A cell is occupied
(a wall, furniture the robot's laser sees), free, or unknown; only occupied cells are obstacles.

:class:`ObstacleMap` answers, for points in the map frame, how far they are from the nearest
occupied cell (a Euclidean distance transform, once, when the map is made). Pure numpy and scipy;
reading and writing map files is :mod:`common.geometry.map_file`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy import ndimage

__all__ = ["ObstacleMap"]


@dataclass(frozen=True, eq=False)
class ObstacleMap:
    """Distances to a static map's obstacles.

    ``distance`` (H, W) float32: metres from each cell's centre to the nearest occupied cell's
    centre (0 on an occupied cell); ``resolution`` (m per cell); ``origin`` (x, y, yaw) as in a
    ROS map. Build one with :meth:`from_occupied`.
    """

    distance: np.ndarray
    resolution: float
    origin: tuple[float, float, float] = (0.0, 0.0, 0.0)

    def __post_init__(self) -> None:
        if self.distance.ndim != 2 or not self.distance.size:
            raise ValueError(f"an obstacle map needs a 2-D grid, got shape {self.distance.shape}")
        if not (math.isfinite(self.resolution) and self.resolution > 0):
            raise ValueError(f"map resolution must be a positive number of metres per cell, got {self.resolution}")
        if len(self.origin) != 3 or not all(math.isfinite(v) for v in self.origin):
            raise ValueError(f"map origin must be three finite numbers (x, y, yaw), got {self.origin}")

    @classmethod
    def from_occupied(cls, occupied: np.ndarray, resolution: float,
                      origin: tuple[float, float, float] = (0.0, 0.0, 0.0), min_extent_m: float = 0.0) -> ObstacleMap:
        """From an (H, W) bool grid of occupied cells, row 0 at the lowest y. Connected occupied
        areas (8-neighbours) whose bounding box is shorter than ``min_extent_m`` on both sides
        are left out: posts such as chair and table legs, where walls and furniture remain. A
        map without any (remaining) occupied cell has every distance infinite."""
        occupied = np.asarray(occupied, bool)
        if occupied.ndim != 2 or not occupied.size:
            raise ValueError(f"occupied must be a non-empty (H, W) grid, got shape {occupied.shape}")
        if min_extent_m > 0 and occupied.any():
            labels, _ = ndimage.label(occupied, structure=np.ones((3, 3), bool))
            cells = min_extent_m / resolution
            small = [k for k, (rows, cols) in enumerate(ndimage.find_objects(labels), 1)
                     if max(rows.stop - rows.start, cols.stop - cols.start) < cells]
            if small:
                occupied = occupied & ~np.isin(labels, small)
        if occupied.any():
            cells = ndimage.distance_transform_edt(~occupied)
            distance = (np.asarray(cells) * resolution).astype(np.float32)
        else:
            distance = np.full(occupied.shape, np.inf, np.float32)
        return cls(distance, float(resolution), tuple(float(v) for v in origin))  # type: ignore[arg-type]

    @property
    def shape(self) -> tuple[int, int]:
        return self.distance.shape  # type: ignore[return-value]

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

    def clearance(self, xy: np.ndarray) -> np.ndarray:
        """(N,) metres from map-frame points ``xy`` (N, 2) to the nearest obstacle, to a cell's
        precision: 0 inside an occupied cell, about the distance to the obstacle's edge
        elsewhere; ``inf`` off the map (no obstacle known there) and for NaN points."""
        row, col, on = self.cells(xy)
        d = self.distance[row, col].astype(np.float64)
        return np.where(on, np.maximum(d - 0.5 * self.resolution, 0.0), np.inf)

    def blocked(self, xy: np.ndarray, clearance_m: float) -> np.ndarray:
        """(N,) bool: which points lie on an obstacle or within ``clearance_m`` of one."""
        return self.clearance(xy) <= clearance_m
