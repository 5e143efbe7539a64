"""A 2-D laser's scan as the page draws it: the returns' points in the map, and which
positions have no image box (a laser's people).

Plain numpy in and out; the node reads the messages and looks up the transforms.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Generic, TypeVar

import numpy as np

__all__ = ["MAX_SCAN_POINTS", "Newest", "flat", "no_box", "scan_points"]

#: At most this many points of one scan go to the page (every k-th return beyond it): a
#: 1 000-beam scan at 10 Hz is then some 14 kB a state.
MAX_SCAN_POINTS = 720

T = TypeVar("T")


def scan_points(ranges: np.ndarray, angle_min: float, angle_increment: float, range_min: float, range_max: float,
                rotation: np.ndarray, translation: np.ndarray, max_points: int = MAX_SCAN_POINTS) -> np.ndarray:
    """The returns of one scan as (N, 2) points in the map.

    Beam ``i`` points at ``angle_min + i * angle_increment`` about the scanner's z and returned at
    ``ranges[i]`` m; a beam with no return (NaN, inf, at or outside ``range_min`` .. ``range_max``)
    has no point. ``rotation`` (3, 3) and ``translation`` (3,) place the scanner in the map. With
    more than ``max_points`` returns, every k-th is kept, evenly along the sweep.
    """
    r = np.asarray(ranges, np.float64).ravel()
    with np.errstate(invalid="ignore"):
        beams = np.flatnonzero(np.isfinite(r) & (r > range_min) & (r < range_max))
    if len(beams) > max_points > 0:
        beams = beams[np.linspace(0, len(beams) - 1, max_points).round().astype(int)]
    a = angle_min + beams * angle_increment
    local = np.stack([r[beams] * np.cos(a), r[beams] * np.sin(a), np.zeros(len(beams))], axis=1)
    return (local @ np.asarray(rotation, np.float64).T + np.asarray(translation, np.float64))[:, :2]


def flat(points: np.ndarray, decimals: int = 2) -> list[float]:
    """(N, 2) points as ``[x0, y0, x1, y1, ...]`` rounded to ``decimals`` (the page's compact form)."""
    return [float(v) for v in np.round(np.asarray(points, np.float64).reshape(-1), decimals)]


def no_box(bboxes: np.ndarray) -> np.ndarray:
    """(N,) bool: which of (N, 4) boxes are no box at all (zero area: a laser's person, a
    position-only detection), to be drawn on the map only, never on the image."""
    b = np.asarray(bboxes, np.float64).reshape(-1, 4)
    return ~((b[:, 2] > b[:, 0]) & (b[:, 3] > b[:, 1]))


@dataclass
class Newest(Generic[T]):
    """The newest item of each source (a laser), forgotten once none came for ``stale_s``."""

    stale_s: float = 1.0
    _items: dict[str, tuple[float, T]] = field(default_factory=dict)

    def put(self, source: str, now: float, item: T) -> None:
        self._items[source] = (now, item)

    def fresh(self, now: float) -> dict[str, tuple[float, T]]:
        """Source -> (when it arrived, its newest item), by source name; stale ones are dropped."""
        for source in [s for s, (at, _) in self._items.items() if now - at > self.stale_s]:
            del self._items[source]
        return dict(sorted(self._items.items()))
