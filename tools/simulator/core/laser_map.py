"""The apartment's static map as a robot would have built it: what a 2-D laser scanner sees.

A robot maps its home once (SLAM with its laser, then Nav2's map saver) and navigates in that
map. The laser's plane, ``height`` above the floor, cuts the walls and the furniture that reach
down to it: a sofa, a bed, a counter, a shelf, chair and table legs (a table top or a chair's
seat lies above it). SLAM marks the outline the beams hit as occupied; a solid's inside stays
unknown (no beam reaches it), and the room's open floor is free. Pure numpy.
"""

from __future__ import annotations

import math

import numpy as np

from tools.simulator.core.apartment import Apartment

__all__ = ["LASER_HEIGHT_M", "MAP_RESOLUTION_M", "laser_map"]

#: A service robot's base laser, above the floor (m).
LASER_HEIGHT_M = 0.2
#: The map's cell (m), Nav2's and slam_toolbox's usual.
MAP_RESOLUTION_M = 0.05


def laser_map(apartment: Apartment, resolution: float = MAP_RESOLUTION_M,
              height: float = LASER_HEIGHT_M) -> tuple[np.ndarray, np.ndarray, tuple[float, float, float]]:
    """(occupied, unknown, origin): (H, W) bool grids of ``resolution`` m cells, row 0 at the lowest
    y, one cell beyond the outer walls on every side, and the map-frame (x, y, yaw) of cell (0, 0)'s
    corner. The outer walls and the outline of every solid the laser plane cuts are occupied,
    cells inside a solid unknown, the rest free."""
    lo, hi = np.asarray(apartment.bounds_lo[:2], float), np.asarray(apartment.bounds_hi[:2], float)
    origin = (float(lo[0] - resolution), float(lo[1] - resolution), 0.0)
    w = int(math.ceil((hi[0] - lo[0]) / resolution)) + 2
    h = int(math.ceil((hi[1] - lo[1]) / resolution)) + 2
    occupied, unknown = np.zeros((h, w), bool), np.zeros((h, w), bool)
    occupied[[0, -1], :] = True  # the outer walls
    occupied[:, [0, -1]] = True

    def span(a: float, b: float, axis_origin: float, n: int) -> slice:
        """The cells a solid from ``a`` to ``b`` overlaps along one axis."""
        first = int(math.floor((a - axis_origin) / resolution + 1e-9))
        last = int(math.ceil((b - axis_origin) / resolution - 1e-9))
        return slice(max(first, 0), min(max(last, first + 1), n))

    for box in apartment.boxes:
        if not box.lo[2] <= height <= box.hi[2]:
            continue
        rows, cols = span(box.lo[1], box.hi[1], origin[1], h), span(box.lo[0], box.hi[0], origin[0], w)
        inside = np.zeros((h, w), bool)
        inside[rows, cols] = True
        unknown[rows, cols] = True
        ring = inside.copy()
        ring[rows.start + 1:rows.stop - 1, cols.start + 1:cols.stop - 1] = False  # the outline the beams hit
        occupied |= ring
    return occupied, unknown & ~occupied, origin
