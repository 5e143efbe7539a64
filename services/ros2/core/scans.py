"""ROS 2 laser scans: a ``sensor_msgs/msg/LaserScan`` checked field by field before it becomes
this project's ``LaserScan`` (``common.messages.schemas``, which the node builds from it).

A range that is NaN, inf or outside ``(range_min, range_max)`` is a beam without return, as in
ROS: kept as sent, never an error. What makes the scan unusable (no ranges, a zero or NaN
increment, ranges that do not fit the angles, limits the wrong way round) is a :class:`ScanError`
whose ``reason`` is a short counter name and whose text says what was wrong. A scan swept
clockwise (a negative increment, as some drivers of scanners mounted upside down publish it) is
turned into the same scan counter-clockwise, beams reversed, so that beam ``i`` still points at
``angle_min + i * angle_increment`` with a positive increment.
"""

from __future__ import annotations

import dataclasses
import math
from typing import Any

import numpy as np

__all__ = ["BEAM_SLACK", "ScanError", "checked_scan"]

#: Beams by which the ranges may miss the angles: ROS drivers disagree by one on whether
#: ``angle_max`` is the last beam's angle or one past it (the same slack as LaserScan's).
BEAM_SLACK = 1
_FIELDS = ("angle_min", "angle_max", "angle_increment", "time_increment", "scan_time", "range_min", "range_max")


class ScanError(ValueError):
    """A scan this node cannot read; ``reason`` is the counter it is counted under."""

    def __init__(self, reason: str, text: str) -> None:
        super().__init__(text)
        self.reason = reason


def checked_scan(msg: Any) -> Any:
    """``msg`` (a ``sensor_msgs/msg/LaserScan``) if it is usable, or its counter-clockwise copy
    when it was swept clockwise; :class:`ScanError` names what makes it unusable."""
    ranges = np.asarray(msg.ranges, np.float32)
    n = len(ranges)
    if n == 0:
        raise ScanError("scan_empty", "the scan has no ranges")
    values = {f: float(getattr(msg, f)) for f in _FIELDS}
    bad = [f"{f} {v}" for f, v in values.items() if not math.isfinite(v)]
    if bad:
        raise ScanError("scan_not_finite", f"{', '.join(bad)}: the scan's geometry must be finite numbers")
    inc = values["angle_increment"]
    if inc == 0.0:
        raise ScanError("scan_increment", f"angle_increment is 0 for {n} ranges: the beams' angles are unknown")
    lo, hi = values["range_min"], values["range_max"]
    if lo < 0.0 or lo >= hi:
        raise ScanError("scan_range_limits", f"range_min {lo:g} m, range_max {hi:g} m: they must satisfy "
                                             "0 <= range_min < range_max")
    span = (values["angle_max"] - values["angle_min"]) / inc
    if span < -0.5 or abs(span + 1 - n) > BEAM_SLACK + 1e-3 * n:
        raise ScanError("scan_length", f"{n} ranges do not fit angle_min {values['angle_min']:.4f} .. angle_max "
                                       f"{values['angle_max']:.4f} rad in steps of {inc:.6f} ({span + 1:.1f} beams)")
    intensities = np.asarray(msg.intensities, np.float32)
    if len(intensities) not in (0, n):
        raise ScanError("scan_intensities", f"{len(intensities)} intensities for {n} ranges (0 or one per range)")
    if inc > 0.0:
        return msg
    return _counter_clockwise(msg, ranges, intensities, values)


def _counter_clockwise(msg: Any, ranges: np.ndarray, intensities: np.ndarray, v: dict[str, float]) -> Any:
    """A clockwise scan as the same beams counter-clockwise: the last beam first. It was measured
    last, so the stamp moves to its time and the time increment turns negative."""
    n = len(ranges)
    first = v["angle_min"] + (n - 1) * v["angle_increment"]
    later_ns = round((n - 1) * v["time_increment"] * 1e9)
    stamp = msg.header.stamp
    total = int(stamp.sec) * 1_000_000_000 + int(stamp.nanosec) + later_ns
    header = dataclasses.replace(msg.header, stamp=dataclasses.replace(stamp, sec=total // 1_000_000_000,
                                                                       nanosec=total % 1_000_000_000))
    return dataclasses.replace(msg, header=header, angle_min=first, angle_max=v["angle_min"],
                               angle_increment=-v["angle_increment"], time_increment=-v["time_increment"],
                               ranges=ranges[::-1].copy(), intensities=intensities[::-1].copy())

