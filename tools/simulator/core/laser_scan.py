"""A 2-D laser scanner in the simulated apartment: rays cut at the scanner's height through the
walls and furniture (axis-aligned boxes) and through each person's two legs (circles that swing
as they walk), with a real scanner's range noise and dropouts. Pure numpy.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from tools.simulator.core.apartment import Apartment

__all__ = ["LaserSpec", "cast", "cast_hits", "legs_of", "rectangles_at", "sense"]

#: A leg's radius at shin height (m) and half the distance between the feet across the body.
LEG_RADIUS_M = 0.06
HIP_HALF_M = 0.1


@dataclass(frozen=True)
class LaserSpec:
    """A scanner: ``fov_deg`` centred on its x axis in ``step_deg`` steps, ``rate_hz``, the
    range limits, the range noise's sigma (m) and the share of beams that return nothing;
    Hokuyo UST-10LX-like defaults."""

    fov_deg: float = 270.0
    step_deg: float = 0.25
    rate_hz: float = 15.0
    range_min: float = 0.06
    range_max: float = 10.0
    sigma_m: float = 0.01
    dropout: float = 0.01

    @property
    def beams(self) -> int:
        return int(round(self.fov_deg / self.step_deg)) + 1

    def angles(self) -> np.ndarray:
        half = np.radians(self.fov_deg) / 2
        return -half + np.radians(self.step_deg) * np.arange(self.beams)


def rectangles_at(apartment: Apartment, height: float) -> np.ndarray:
    """(M, 4) x0, y0, x1, y1 of every solid the scanner's plane at ``height`` cuts."""
    rows = [(b.lo[0], b.lo[1], b.hi[0], b.hi[1]) for b in apartment.boxes if b.lo[2] <= height <= b.hi[2]]
    return np.asarray(rows, np.float64).reshape(-1, 4)


def legs_of(xy: np.ndarray, heading: np.ndarray, speed: np.ndarray, t: float, seated: np.ndarray | None = None,
            stride_m: float = 0.6) -> np.ndarray:
    """(2P, 3) the legs (x, y, radius) of P people at ``xy`` (P, 2) facing ``heading`` (P,) rad
    walking at ``speed`` (P,) m/s at time ``t``: side by side across the hips, swinging fore and
    aft in opposite phase at a cadence that grows with speed (about 1.8 steps/s at 1.2 m/s).
    A seated person's legs reach forward of the seat."""
    xy = np.asarray(xy, np.float64).reshape(-1, 2)
    heading, speed = np.asarray(heading, np.float64), np.asarray(speed, np.float64)
    fwd = np.column_stack([np.cos(heading), np.sin(heading)])
    side = np.column_stack([-fwd[:, 1], fwd[:, 0]])
    walking = speed > 0.05
    swing = np.where(walking, 0.5 * stride_m * np.minimum(speed / 1.2, 1.0), 0.0)
    phase = 2 * np.pi * 0.75 * np.maximum(speed, 0.0) / 0.6 * t
    ahead = swing * np.sin(phase)  # the left foot's; the right one's is opposite
    other = -ahead
    if seated is not None:
        ahead, other = np.where(seated, 0.35, ahead), np.where(seated, 0.35, other)
    left = xy + side * HIP_HALF_M + fwd * ahead[:, None]
    right = xy - side * HIP_HALF_M + fwd * other[:, None]
    out = np.empty((2 * len(xy), 3))
    out[0::2, :2], out[1::2, :2] = left, right
    out[:, 2] = LEG_RADIUS_M
    return out


def cast(origin: np.ndarray, yaw: float, angles: np.ndarray, rectangles: np.ndarray, circles: np.ndarray,
         max_range: float) -> np.ndarray:
    """The exact range of every beam (``angles`` about the scanner's x axis, the scanner at
    ``origin`` (2,) facing ``yaw``) to the nearest rectangle side or circle; inf where nothing is
    within ``max_range``."""
    return cast_hits(origin, yaw, angles, rectangles, circles, max_range)[0]


def cast_hits(origin: np.ndarray, yaw: float, angles: np.ndarray, rectangles: np.ndarray, circles: np.ndarray,
              max_range: float) -> tuple[np.ndarray, np.ndarray]:
    """:func:`cast`'s ranges, and per beam the index of the circle it hit (-1: a rectangle or
    nothing): which leg, hence whose, each beam saw."""
    theta = yaw + np.asarray(angles, np.float64)
    dx, dy = np.cos(theta)[:, None], np.sin(theta)[:, None]
    ox, oy = float(origin[0]), float(origin[1])
    best = np.full(len(theta), np.inf)
    if len(rectangles):
        x0, y0, x1, y1 = (rectangles[:, k][None, :] for k in range(4))
        with np.errstate(divide="ignore", invalid="ignore"):
            tx0, tx1 = (x0 - ox) / dx, (x1 - ox) / dx
            ty0, ty1 = (y0 - oy) / dy, (y1 - oy) / dy
        t_near = np.maximum(np.minimum(tx0, tx1), np.minimum(ty0, ty1))
        t_far = np.minimum(np.maximum(tx0, tx1), np.maximum(ty0, ty1))
        t_near = np.nan_to_num(t_near, nan=-np.inf)
        t_far = np.nan_to_num(t_far, nan=-np.inf)
        # from outside: the entry; from inside a box (the outer walls are boxes round the rooms): none
        hit = (t_far >= t_near) & (t_near > 0)
        best = np.minimum(best, np.where(hit, t_near, np.inf).min(axis=1))
    if len(circles):
        cx, cy, r = circles[:, 0][None, :] - ox, circles[:, 1][None, :] - oy, circles[:, 2][None, :]
        b = cx * dx + cy * dy
        disc = b * b - (cx * cx + cy * cy - r * r)
        t = b - np.sqrt(np.maximum(disc, 0.0))
        t = np.where((disc >= 0) & (t > 0), t, np.inf)
        nearest = t.argmin(axis=1)
        t_circle = t[np.arange(len(t)), nearest]
        owner = np.where(t_circle < best, nearest, -1)
        best = np.minimum(best, t_circle)
    else:
        owner = np.full(len(theta), -1)
    owner = np.where(best <= max_range, owner, -1)
    return np.where(best <= max_range, best, np.inf), owner


def sense(exact: np.ndarray, spec: LaserSpec, rng: np.random.Generator) -> np.ndarray:
    """What the scanner reports for the ``exact`` ranges: Gaussian range noise, a share of beams
    dropped (0: no return, as a Hokuyo reports it), and 0 beyond the range (float32)."""
    r = exact + rng.normal(0.0, spec.sigma_m, exact.shape)
    r = np.where(np.isfinite(exact) & (r > spec.range_min) & (r < spec.range_max), r, 0.0)
    r[rng.random(exact.shape) < spec.dropout] = 0.0
    return r.astype(np.float32)
