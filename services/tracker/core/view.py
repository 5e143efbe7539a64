"""What the camera could see at a frame: tells a person out of view from one the detector missed.

A confirmed track missed inside the view is still there and is reported while it coasts; one who
walked out of the view, or whom the robot turned away from, cannot be seen by this camera, and
reporting their prediction as a person seen now would be a false positive for every consumer that
reads the output as "people in view": it is kept (their ID stays theirs) but not reported.
:class:`FieldOfView` is a pinhole camera's view, :class:`FloorView` a fixed camera's view of the
floor through its floor homography, :class:`ScanView` a 2-D laser's sweep (the scan itself says what it
could see: a person behind a nearer return is hidden), :class:`Views` several sensors' together (TU Ilmenau's two
cameras: a person behind the robot, seen by the back camera a moment ago, stays reported while the
head camera's frames come in). Pure numpy.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

__all__ = ["FieldOfView", "FloorView", "ScanView", "View", "Views"]


class _SeesAbsence:
    """A camera's view: where it could see a person, it would see that they are not there (a
    miss in view is a miss). A laser's is weaker (:class:`ScanView`)."""

    #: whether :meth:`sees_absence` can differ from ``contains`` (the tracker skips it when not)
    absence_differs = False

    def sees_absence(self, points: np.ndarray, margin: float = 0.0) -> np.ndarray:
        return self.contains(points, margin)  # type: ignore[attr-defined,no-any-return]


@dataclass(frozen=True)
class FieldOfView(_SeesAbsence):
    """A pinhole camera's view: ``camera_to_frame`` (4, 4) maps camera points (z forward)
    into the tracking frame; ``K`` (3, 3), ``width`` x ``height`` pixels; points farther
    than ``max_range_m`` along the optical axis are out of view."""

    camera_to_frame: np.ndarray
    K: np.ndarray
    width: int
    height: int
    max_range_m: float

    def __post_init__(self) -> None:
        m = np.asarray(self.camera_to_frame, np.float64).reshape(4, 4)
        k = np.asarray(self.K, np.float64).reshape(3, 3)
        if not (np.all(np.isfinite(m)) and np.all(np.isfinite(k)) and k[0, 0] > 0 and k[1, 1] > 0):
            raise ValueError("camera_to_frame and K must be finite, with positive focal lengths")
        if self.width <= 0 or self.height <= 0 or not self.max_range_m > 0:
            raise ValueError("width, height and max_range_m must be positive")
        object.__setattr__(self, "camera_to_frame", m)
        object.__setattr__(self, "K", k)

    def contains(self, points: np.ndarray, margin: float = 0.0) -> np.ndarray:
        """Whether each point (N, 3) of the tracking frame is in view: in front of the
        camera, within ``max_range_m`` and projecting inside the image less a border of
        ``margin`` times its width (and height): a person whose centre is near the edge
        is mostly outside the image."""
        p = np.asarray(points, np.float64).reshape(-1, 3)
        r, t = self.camera_to_frame[:3, :3], self.camera_to_frame[:3, 3]
        cam = (p - t) @ r  # R^T (p - t), row by row
        z = cam[:, 2]
        with np.errstate(divide="ignore", invalid="ignore"):
            u = self.K[0, 0] * cam[:, 0] / z + self.K[0, 2]
            v = self.K[1, 1] * cam[:, 1] / z + self.K[1, 2]
        mu, mv = margin * self.width, margin * self.height
        return ((z > 0.05) & (z <= self.max_range_m) & (u >= mu) & (u <= self.width - mu)
                & (v >= mv) & (v <= self.height - mv))


@dataclass(frozen=True)
class FloorView(_SeesAbsence):
    """A fixed camera's view of the floor: ``image_to_floor`` (3, 3) maps a foot pixel ``(u, v, 1)``
    to the floor ``(x, y, w)`` (the localizer's ``FloorHomography.H``), ``width`` x ``height``
    pixels; a point is in view when its foot (``x, y``) projects inside the image. The border is
    measured on the person, ``half_width_m`` at their place in the image: a wide view's people are a
    few per cent of its width, so a share of the image (the narrow :class:`FieldOfView`'s) would hide
    people still in full view."""

    image_to_floor: np.ndarray
    width: int
    height: int
    half_width_m: float = 0.25

    def __post_init__(self) -> None:
        h = np.asarray(self.image_to_floor, np.float64).reshape(3, 3)
        if not np.all(np.isfinite(h)) or not np.linalg.cond(h) < 1e12:
            raise ValueError("image_to_floor must be a finite, invertible 3x3 homography")
        if self.width <= 0 or self.height <= 0 or not self.half_width_m >= 0:
            raise ValueError("width and height must be positive, half_width_m not negative")
        object.__setattr__(self, "image_to_floor", h)
        object.__setattr__(self, "_to_image", np.linalg.inv(h))

    def contains(self, points: np.ndarray, margin: float = 0.0) -> np.ndarray:
        """Whether each point (N, 3) (or (N, 2)) stands inside the image; with ``margin`` > 0
        (the tracker's ``view_margin``: is there a border at all) at least half a body's width
        inside it on the left, right and top. The foot is the body's lowest point, so a person
        whose feet are near the image's lower edge is in full view above them."""
        p = np.asarray(points, np.float64)
        p = p.reshape(-1, p.shape[-1] if p.ndim > 1 else 3)[:, :2]
        G = self._to_image  # type: ignore[attr-defined]
        g = p @ G[:, :2].T + G[:, 2]
        w = g[:, 2]
        with np.errstate(divide="ignore", invalid="ignore"):
            u, v = g[:, 0] / w, g[:, 1] / w
            if margin > 0 and self.half_width_m > 0:
                # pixels per metre along the floor's least foreshortened direction: the larger
                # singular value of d(u, v)/d(x, y) = (G[:2, :2] - (u, v) G[2, :2]) / w
                a = (G[0, 0] - u * G[2, 0]) / w
                b = (G[0, 1] - u * G[2, 1]) / w
                c = (G[1, 0] - v * G[2, 0]) / w
                d = (G[1, 1] - v * G[2, 1]) / w
                s2 = a * a + b * b + c * c + d * d
                det = a * d - b * c
                sigma = np.sqrt(0.5 * (s2 + np.sqrt(np.maximum(s2 * s2 - 4.0 * det * det, 0.0))))
                border = self.half_width_m * sigma
            else:
                border = np.zeros(len(p))
        return (w > 0) & (u >= border) & (u <= self.width - border) & (v >= border) & (v <= self.height)


@dataclass(frozen=True)
class ScanView:
    """What a 2-D laser saw in one sweep: ``scanner_to_frame`` (4, 4) maps the scanner's frame into the
    tracking frame; beam ``i`` points at ``angle_min + i * angle_increment`` about the scanner's z and
    returned at ``ranges[i]`` m (no return: ``max_range_m`` or more, free as far as the detector looks).
    A point is in view when it is within ``max_range_m`` of the scanner, inside the sweep, and some
    beam across ``body_radius_m`` either side of it reaches it (within ``body_radius_m`` twice: the
    legs are in front of the body's centre): a person behind a nearer return is hidden, and missing
    them there is no miss. Where a person would stand among other returns (legs beside a wall or a
    chair, which the leg detector cannot always tell apart), the laser sees them but not their
    absence: a miss there says nothing (:meth:`sees_absence`)."""

    absence_differs = True

    scanner_to_frame: np.ndarray
    angle_min: float
    angle_increment: float
    ranges: np.ndarray
    max_range_m: float
    body_radius_m: float = 0.2

    def __post_init__(self) -> None:
        m = np.asarray(self.scanner_to_frame, np.float64).reshape(4, 4)
        r = np.asarray(self.ranges, np.float64).reshape(-1)
        if not (np.all(np.isfinite(m)) and np.isfinite(self.angle_min) and self.angle_increment > 0
                and self.max_range_m > 0 and len(r)):
            raise ValueError("scanner_to_frame and angle_min must be finite, angle_increment and max_range_m "
                             "positive, and there must be beams")
        object.__setattr__(self, "scanner_to_frame", m)
        object.__setattr__(self, "ranges", np.where(np.isfinite(r) & (r > 0), np.minimum(r, self.max_range_m),
                                                    self.max_range_m))

    def contains(self, points: np.ndarray, margin: float = 0.0) -> np.ndarray:
        """Whether each point (N, 3) of the tracking frame is in the laser's view (``margin``, a share
        of an image, means nothing to a scan)."""
        return self._reached(points, -2 * self.body_radius_m, np.max)

    def sees_absence(self, points: np.ndarray, margin: float = 0.0) -> np.ndarray:
        """Whether the laser saw that nobody stands at each point: every beam across the body's
        width went on past it, free space."""
        return self._reached(points, self.body_radius_m, np.min)

    def _reached(self, points: np.ndarray, beyond_m: float, which: object) -> np.ndarray:
        """Whether ``which`` (max: some, min: every) of the beams across a body's width at each point
        returned farther than the point's distance plus ``beyond_m``, within range and sweep."""
        p = np.asarray(points, np.float64).reshape(-1, 3)
        rot, t = self.scanner_to_frame[:3, :3], self.scanner_to_frame[:3, 3]
        local = (p - t) @ rot
        dist = np.hypot(local[:, 0], local[:, 1])
        n, inc = len(self.ranges), self.angle_increment
        beam = (np.arctan2(local[:, 1], local[:, 0]) - self.angle_min) / inc
        beam = np.mod(beam + 0.5, 2 * np.pi / inc) - 0.5  # bearings wrap: a 360-degree sweep's start
        inside = (dist <= self.max_range_m) & (beam >= -0.5) & (beam <= n - 0.5)
        out = np.zeros(len(p), bool)
        reach = self.ranges
        for k in np.flatnonzero(inside).tolist():
            half = int(np.ceil(np.arctan2(self.body_radius_m, max(dist[k], 1e-3)) / inc))
            c = int(round(beam[k]))
            lo, hi = max(0, c - half), min(n, c + half + 1)
            out[k] = bool(which(reach[lo:hi]) >= dist[k] + beyond_m)  # type: ignore[operator]
        return out


@dataclass(frozen=True)
class Views:
    """The union of several sensors' views: a point is in view when any of them contains it."""

    views: tuple[FieldOfView | FloorView | ScanView, ...]

    @property
    def absence_differs(self) -> bool:
        return any(v.absence_differs for v in self.views)

    def contains(self, points: np.ndarray, margin: float = 0.0) -> np.ndarray:
        return self._any("contains", points, margin)

    def sees_absence(self, points: np.ndarray, margin: float = 0.0) -> np.ndarray:
        return self._any("sees_absence", points, margin)

    def _any(self, test: str, points: np.ndarray, margin: float) -> np.ndarray:
        p = np.asarray(points, np.float64).reshape(-1, 3)
        seen = np.zeros(len(p), bool)
        for view in self.views:
            seen |= getattr(view, test)(p, margin)
        return seen


#: any view the tracker takes
View = FieldOfView | FloorView | ScanView | Views
