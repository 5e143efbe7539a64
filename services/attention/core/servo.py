"""Visual servoing of a point feature with a pan/tilt head (Ban et al., Eq 11-19).

A static point ``X`` (camera frame, optical: z forward, x right, y down) projects to
``V = K X / X3`` (Eq 11). Its image Jacobian (Eq 12) is

    J_wi(X) = K[:2] @ [[1/X3, 0, -X1/X3^2], [0, 1/X3, -X2/X3^2]]          (2, 3)

and turning a joint at unit rate about a unit axis ``a`` through a pivot ``p`` (both in the
camera frame) moves the point, seen from the camera, by ``dX/dq = -a x (X - p)``: the
columns of ``J_mw`` (3, 2), Ban et al.'s Eq 14-16 for a pan axis and a tilt axis. The joint
Jacobian ``J = J_wi @ J_mw`` (2, 2, Eq 18) maps (pan rate, tilt rate) to the point's image
velocity, and the control law (Eq 19) asks for the joint rates that shrink the centring
error exponentially, less the image motion the target causes itself (feed-forward):

    q_dot = J^-1 (-gain * (V - c) - J_wi @ X_dot_target)

Everything here is numpy on plain arrays; rates in rad/s, pixels, metres.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

__all__ = ["HeadGeometry", "ServoParams", "ServoResult", "head_angles", "image_jacobian", "joint_jacobian",
           "motion_jacobian", "project", "rest_rates", "servo"]


@dataclass(frozen=True)
class HeadGeometry:
    """The head's two joint axes at one instant, in the camera frame.

    ``pan_axis`` (3,): unit vector of the pan axis (the base's z), ``pan_pivot`` (3,): a point
    on it; ``tilt_axis`` (3,) and ``tilt_pivot`` (3,) the same for the tilt axis (the head's y).
    Positive rates turn about the axes by the right-hand rule: pan left, tilt down.
    """

    pan_axis: np.ndarray
    pan_pivot: np.ndarray
    tilt_axis: np.ndarray
    tilt_pivot: np.ndarray


@dataclass(frozen=True)
class ServoParams:
    """Gains and limits of the controller (the attention config's defaults come from here)."""

    gain: float = 1.2  # 1/s: the centring error shrinks as exp(-gain t)
    feedforward: float = 1.0  # weight of the target's own image motion (0: pure feedback)
    max_pan_rate: float = 1.2  # rad/s
    max_tilt_rate: float = 0.6  # rad/s
    dead_zone_px: float = 6.0  # no feedback correction within this distance of the centre
    min_depth_m: float = 0.3  # closer (or behind): turn towards the bearing instead of the Jacobian
    max_condition: float = 1e4  # a worse-conditioned joint Jacobian is not inverted
    pan_limits: tuple[float, float] = (-2.4, 2.4)  # rad
    tilt_limits: tuple[float, float] = (-0.5, 0.8)  # rad, positive looks down
    rest_pan: float = 0.0  # rad
    rest_tilt: float = 0.1  # rad
    rest_gain: float = 1.5  # 1/s, towards the rest pose
    rest_tolerance: float = 0.01  # rad: at rest within this


@dataclass(frozen=True)
class ServoResult:
    """One command: joint rates (rad/s), the centring error (px) and how it was made."""

    pan_rate: float
    tilt_rate: float
    error_px: tuple[float, float]
    saturated: bool = False  # scaled down to the velocity limits
    at_limit: bool = False  # a joint limit stopped a rate
    fallback: bool = False  # target behind, too close or ill-conditioned: turned by bearing


def project(K: np.ndarray, X: np.ndarray) -> np.ndarray:
    """(2,) pixel of the camera-frame point ``X`` (3,) through the (3, 3) intrinsics ``K`` (Eq 11)."""
    return np.array([K[0, 0] * X[0] / X[2] + K[0, 1] * X[1] / X[2] + K[0, 2], K[1, 1] * X[1] / X[2] + K[1, 2]])


def image_jacobian(K: np.ndarray, X: np.ndarray) -> np.ndarray:
    """(2, 3) d(pixel)/dX of a camera-frame point (Eq 12)."""
    x1, x2, x3 = X
    d = np.array([[1.0 / x3, 0.0, -x1 / x3**2], [0.0, 1.0 / x3, -x2 / x3**2]])
    return K[:2, :2] @ d


def motion_jacobian(X: np.ndarray, geometry: HeadGeometry) -> np.ndarray:
    """(3, 2) dX/d(pan, tilt) of a static point ``X`` (3,) seen from the turning camera."""
    g = geometry
    return np.stack([-np.cross(g.pan_axis, X - g.pan_pivot), -np.cross(g.tilt_axis, X - g.tilt_pivot)], axis=1)


def joint_jacobian(K: np.ndarray, X: np.ndarray, geometry: HeadGeometry) -> np.ndarray:
    """(2, 2) d(pixel)/d(pan, tilt) (Eq 18)."""
    return image_jacobian(K, X) @ motion_jacobian(X, geometry)


def head_angles(base_to_tilt: np.ndarray) -> tuple[float, float]:
    """(pan, tilt) of a head whose tilt link has rotation ``base_to_tilt`` (3, 3) in the base:
    ``Rz(pan) @ Ry(tilt)`` (positive tilt looks down)."""
    r = base_to_tilt
    return float(math.atan2(r[1, 0], r[0, 0])), float(math.asin(float(np.clip(-r[2, 0], -1.0, 1.0))))


def _limit(pan_rate: float, tilt_rate: float, angles: tuple[float, float] | None,
           p: ServoParams) -> tuple[float, float, bool, bool]:
    """Scale to the velocity limits (keeping the direction), then stop a joint at its limit."""
    scale = 1.0
    if abs(pan_rate) > p.max_pan_rate:
        scale = min(scale, p.max_pan_rate / abs(pan_rate))
    if abs(tilt_rate) > p.max_tilt_rate:
        scale = min(scale, p.max_tilt_rate / abs(tilt_rate))
    pan_rate, tilt_rate = pan_rate * scale, tilt_rate * scale
    at_limit = False
    if angles is not None:
        pan, tilt = angles
        if (pan >= p.pan_limits[1] and pan_rate > 0) or (pan <= p.pan_limits[0] and pan_rate < 0):
            pan_rate, at_limit = 0.0, True
        if (tilt >= p.tilt_limits[1] and tilt_rate > 0) or (tilt <= p.tilt_limits[0] and tilt_rate < 0):
            tilt_rate, at_limit = 0.0, True
    return pan_rate, tilt_rate, scale < 1.0, at_limit


def _bearing_rates(X: np.ndarray, geometry: HeadGeometry, p: ServoParams) -> tuple[float, float]:
    """Turn the pan towards a point behind or beside the camera: the angle about the pan axis
    from the camera's forward direction to the point, times the gain (tilt held)."""
    a = geometry.pan_axis
    forward = np.array([0.0, 0.0, 1.0]) - a * a[2]
    left = np.cross(a, forward)
    d = X - geometry.pan_pivot
    phi = math.atan2(float(d @ left), float(d @ forward))
    return p.gain * phi, 0.0


def servo(K: np.ndarray, centre: tuple[float, float], X: np.ndarray, X_dot: np.ndarray, geometry: HeadGeometry,
          angles: tuple[float, float] | None, p: ServoParams) -> ServoResult:
    """The joint rates that bring the camera-frame point ``X`` (3,) to the image ``centre``.

    ``X_dot`` (3,): the target's own velocity in the camera frame (feed-forward); ``angles``:
    the current (pan, tilt) for the joint limits, None if unknown.
    """
    X = np.asarray(X, float)
    if X[2] < p.min_depth_m:
        pan_rate, tilt_rate = _bearing_rates(X, geometry, p)
        pan_rate, tilt_rate, sat, lim = _limit(pan_rate, tilt_rate, angles, p)
        return ServoResult(pan_rate, tilt_rate, (math.nan, math.nan), sat, lim, fallback=True)
    v = project(K, X)
    error = v - np.asarray(centre, float)
    J = joint_jacobian(K, X, geometry)
    if not np.all(np.isfinite(J)) or np.linalg.cond(J) > p.max_condition:
        pan_rate, tilt_rate = _bearing_rates(X, geometry, p)
        pan_rate, tilt_rate, sat, lim = _limit(pan_rate, tilt_rate, angles, p)
        return ServoResult(pan_rate, tilt_rate, (float(error[0]), float(error[1])), sat, lim, fallback=True)
    wanted = np.zeros(2) if float(np.hypot(*error)) <= p.dead_zone_px else -p.gain * error
    if p.feedforward:
        wanted = wanted - p.feedforward * (image_jacobian(K, X) @ np.asarray(X_dot, float))
    rates = np.linalg.solve(J, wanted)
    pan_rate, tilt_rate, sat, lim = _limit(float(rates[0]), float(rates[1]), angles, p)
    return ServoResult(pan_rate, tilt_rate, (float(error[0]), float(error[1])), sat, lim)


def rest_rates(angles: tuple[float, float], p: ServoParams) -> tuple[float, float, bool]:
    """Rates towards the rest pose from ``angles`` (pan, tilt); True when already at rest."""
    d_pan, d_tilt = p.rest_pan - angles[0], p.rest_tilt - angles[1]
    if abs(d_pan) <= p.rest_tolerance and abs(d_tilt) <= p.rest_tolerance:
        return 0.0, 0.0, True
    pan_rate, tilt_rate, _, _ = _limit(p.rest_gain * d_pan, p.rest_gain * d_tilt, None, p)
    return pan_rate, tilt_rate, False
