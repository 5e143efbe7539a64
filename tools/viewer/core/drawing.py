"""The viewer's pure pieces: colours as the page writes them, headings and trails.

Everything takes and returns numpy arrays, floats and dataclasses; the node turns
messages into these and the results into the page's JSON. The colour of an ID and which
image box a track is are shared with the other views (:mod:`tools.drawing.tracks`).
"""

from __future__ import annotations

import math
from collections import deque
from dataclasses import dataclass, field
import numpy as np

from tools.drawing.tracks import colour_rgb

__all__ = ["Trails", "colour_hex", "occupied_runs", "yaw_of"]


def colour_hex(track_id: int) -> str:
    """``colour_rgb`` as ``#rrggbb``."""
    return "#{:02x}{:02x}{:02x}".format(*colour_rgb(track_id))


def yaw_of(rotation: np.ndarray) -> float:
    """Heading (rad, about z) of a (3, 3) rotation matrix: where its x axis points in the plane."""
    return math.atan2(float(rotation[1, 0]), float(rotation[0, 0]))


@dataclass
class Trails:
    """The last ``span_s`` seconds of each track's ground-plane position.

    ``add(id, t, x, y)`` appends (at most one point per ``min_step_s``); ``prune(now)``
    forgets old points and tracks not seen for ``span_s``.
    """

    span_s: float = 5.0
    min_step_s: float = 0.1
    max_points: int = 100
    _points: dict[int, deque[tuple[float, float, float]]] = field(default_factory=dict)

    def add(self, track_id: int, t: float, x: float, y: float) -> None:
        trail = self._points.setdefault(track_id, deque(maxlen=self.max_points))
        if trail and t - trail[-1][0] < self.min_step_s:
            trail[-1] = (trail[-1][0], x, y)  # keep the newest position, not a denser trail
            return
        trail.append((t, x, y))

    def prune(self, now: float) -> None:
        for track_id in list(self._points):
            trail = self._points[track_id]
            while trail and now - trail[0][0] > self.span_s:
                trail.popleft()
            if not trail:
                del self._points[track_id]

    def get(self, track_id: int) -> list[tuple[float, float]]:
        """The trail of ``track_id``, oldest first, as (x, y) pairs."""
        return [(x, y) for _, x, y in self._points.get(track_id, ())]


def occupied_runs(occupied: np.ndarray) -> list[list[int]]:
    """The occupied cells of an (H, W) grid as runs ``[row, first column, end column)``, row by
    row: a map's walls in a few hundred rectangles for the page to draw, not one per cell."""
    occupied = np.asarray(occupied, bool)
    padded = np.zeros((occupied.shape[0], occupied.shape[1] + 2), np.int8)
    padded[:, 1:-1] = occupied
    rows, cols = np.nonzero(np.diff(padded, axis=1))  # +1 where a run starts, -1 where it ends
    starts, ends = cols[0::2], cols[1::2]
    return [[int(r), int(a), int(b)] for r, a, b in zip(rows[0::2], starts, ends)]
