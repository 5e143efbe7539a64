"""A 2-D laser scan's beams as points in the scanner's frame, and what is wrong with them.

A beam counts when its range is finite and strictly inside (range_min, range_max), as ROS's
``sensor_msgs/LaserScan`` documents; a scanner writes 0, NaN, inf or range_max for no return.
Invalid beams are counted by reason (they are normal: a Hokuyo reads 0 through a doorway, the
robot's own body shadows part of the scan), never an error.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

__all__ = ["Beams", "ScanGeometry", "beams"]


@dataclass(frozen=True)
class ScanGeometry:
    """Where a scan's beams point: beam ``i`` at ``angle_min + i * angle_increment`` (rad,
    counter-clockwise from the scanner's x axis), ranges valid inside (range_min, range_max) m."""

    angle_min: float
    angle_increment: float
    range_min: float
    range_max: float

    def __post_init__(self) -> None:
        if not np.isfinite(self.angle_increment) or self.angle_increment <= 0.0:
            raise ValueError(f"angle_increment must be > 0 rad, got {self.angle_increment}")
        if not (np.isfinite(self.range_min) and np.isfinite(self.range_max)) or not 0 <= self.range_min < self.range_max:
            raise ValueError(f"need 0 <= range_min < range_max, got {self.range_min}, {self.range_max}")


@dataclass(frozen=True)
class Beams:
    """One scan's beams: ``ranges``, ``angle``, ``x``, ``y`` (n,) float64 and ``valid`` (n,) bool;
    ``invalid`` counts the beams left out by reason (``nonfinite``, ``too_near``, ``too_far``)."""

    ranges: np.ndarray
    angle: np.ndarray
    x: np.ndarray
    y: np.ndarray
    valid: np.ndarray
    geometry: ScanGeometry
    invalid: dict[str, int]

    def __len__(self) -> int:
        return len(self.ranges)


def beams(ranges: np.ndarray, g: ScanGeometry) -> Beams:
    """The beams of ``ranges`` (any float array) under geometry ``g``."""
    r = np.asarray(ranges, np.float64).ravel()
    angle = g.angle_min + g.angle_increment * np.arange(len(r))
    finite = np.isfinite(r)
    safe = np.where(finite, r, 0.0)
    near = finite & (safe <= g.range_min)
    far = finite & (safe >= g.range_max)
    valid = finite & ~near & ~far
    invalid = {"nonfinite": int(len(r) - finite.sum()), "too_near": int(near.sum()), "too_far": int(far.sum())}
    return Beams(safe, angle, safe * np.cos(angle), safe * np.sin(angle), valid, g, invalid)
