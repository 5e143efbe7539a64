"""The robot: base trajectory in the map, odometry with drift, and the pan/tilt head.

Frames: ``map`` -> ``odom`` (the drift) -> ``base_link`` (on the floor, x forward) ->
``head_link`` (pan about z, then tilt about y; positive tilt looks down) -> ``camera``
(optical: z forward, x right, y down).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Callable

import numpy as np

from tools.simulator.core.apartment import Apartment
from tools.simulator.core.head_servo import CommandedHead
from common.poses import OPTICAL_FROM_BODY, make_pose, planar_pose, pose_inverse, rot_y, rot_z

__all__ = [
    "HeadMotion",
    "Odometry",
    "ROBOT_RADIUS",
    "Robot",
    "follow_trajectory",
    "loop_trajectory",
    "static_trajectory",
]

ROBOT_RADIUS = 0.35
HEAD_OFFSET = np.array([0.05, 0.0, 1.15])  # base_link -> head_link (pan/tilt joint)
CAMERA_OFFSET = np.array([0.06, 0.0, 0.08])  # head_link -> camera
BaseTrajectory = Callable[[float], tuple[float, float, float]]  # t -> (x, y, yaw) in the map


@dataclass(frozen=True)
class HeadMotion:
    """Pan and tilt (rad) as sinusoids: ``pan0 + pan_amp sin(2 pi t / pan_period)``, same for tilt.

    With ``look_at`` (x, y in the map) the pan instead keeps the camera turned towards that
    point, within ``pan_limit`` of straight ahead.
    """

    pan0: float = 0.0
    tilt0: float = 0.12
    pan_amp: float = 0.0
    pan_period: float = 14.0
    tilt_amp: float = 0.0
    tilt_period: float = 9.0
    look_at: tuple[float, float] | None = None
    pan_limit: float = 1.4

    @property
    def moves(self) -> bool:
        return self.pan_amp != 0.0 or self.tilt_amp != 0.0 or self.look_at is not None

    def angles(self, t: float) -> tuple[float, float]:
        pan = self.pan0 + self.pan_amp * np.sin(2 * np.pi * t / self.pan_period)
        tilt = self.tilt0 + self.tilt_amp * np.sin(2 * np.pi * t / self.tilt_period)
        return float(pan), float(tilt)


def static_trajectory(x: float, y: float, yaw: float) -> BaseTrajectory:
    return lambda t: (x, y, yaw)


def loop_trajectory(
    apartment: Apartment, waypoints: list[tuple[float, float]], speed: float = 0.35, turn_rate: float = 0.6
) -> BaseTrajectory:
    """Drive a closed loop through ``waypoints`` (planned around furniture), turning in place at corners."""
    pts = [np.asarray(waypoints[0], float)]
    for a, b in zip(waypoints, waypoints[1:] + waypoints[:1]):
        pts += list(apartment.plan(np.asarray(a, float), np.asarray(b, float), ROBOT_RADIUS)[1:])
    path = np.stack(pts)
    yaw = float(np.arctan2(*(path[1] - path[0])[::-1]))
    t = 0.0
    knots = [(0.0, path[0][0], path[0][1], yaw)]  # (t, x, y, yaw)
    for a, b in zip(path[:-1], path[1:]):
        heading = float(np.arctan2(b[1] - a[1], b[0] - a[0]))
        turn = float(np.angle(np.exp(1j * (heading - yaw))))
        t += abs(turn) / turn_rate
        yaw += turn
        knots.append((t, a[0], a[1], yaw))
        t += float(np.linalg.norm(b - a)) / speed
        knots.append((t, b[0], b[1], yaw))
    k = np.array(knots)
    period = float(k[-1, 0])

    def pose(t: float) -> tuple[float, float, float]:
        tt = t % period if period > 0 else 0.0
        laps = np.floor(t / period) if period > 0 else 0.0
        x = float(np.interp(tt, k[:, 0], k[:, 1]))
        y = float(np.interp(tt, k[:, 0], k[:, 2]))
        yaw_t = float(np.interp(tt, k[:, 0], k[:, 3])) + laps * (k[-1, 3] - k[0, 3])
        return x, y, float(np.angle(np.exp(1j * yaw_t)))

    return pose


def follow_trajectory(
    target: Callable[[float], np.ndarray],
    start: tuple[float, float, float],
    gap: float = 2.2,
    max_speed: float = 1.0,
    dt: float = 0.05,
) -> BaseTrajectory:
    """Follow the trail of ``target(t) -> (2,)`` (which starts with the segment from ``start`` to the
    target), ``gap`` metres behind along the trail and never closer than ``gap`` in a straight line,
    at most ``max_speed``, facing the target when near it and the trail ahead otherwise.
    The trail is collision-free because the target walked it."""
    trail = [np.asarray(start[:2], float), np.asarray(target(0.0), float)]
    cum = [0.0, float(np.linalg.norm(trail[1] - trail[0]))]
    s_robot = [0.0]  # arclength reached at t = k * dt

    def at(s: float) -> np.ndarray:
        c, tr = np.asarray(cum), np.asarray(trail)
        return np.array([np.interp(s, c, tr[:, 0]), np.interp(s, c, tr[:, 1])])

    def grow(t: float) -> None:
        while (len(s_robot) - 1) * dt < t + dt:
            k = len(s_robot)
            p = np.asarray(target(k * dt), float)
            cum.append(cum[-1] + float(np.linalg.norm(p - trail[-1])))
            trail.append(p)
            s_next = max(s_robot[-1], min(cum[-1] - gap, s_robot[-1] + max_speed * dt))
            if np.linalg.norm(at(s_next) - p) < gap:  # the target turned back: wait for it to move away
                s_next = s_robot[-1]
            s_robot.append(s_next)

    def pose(t: float) -> tuple[float, float, float]:
        grow(t)
        s = float(np.interp(t, np.arange(len(s_robot)) * dt, s_robot))
        p = at(s)
        # face the trail 1 m ahead (through doors, not through walls) unless the target is close
        target_now = np.asarray(target(t), float)
        ahead = target_now if np.linalg.norm(target_now - p) < gap + 0.3 else at(min(s + 1.0, cum[-1]))
        goal = ahead - p
        yaw = float(np.arctan2(goal[1], goal[0])) if np.linalg.norm(goal) > 0.1 else start[2]
        return float(p[0]), float(p[1]), yaw

    return pose


@dataclass
class Odometry:
    """Wheel odometry integrated from the true motion with a scale error and a yaw drift.

    ``odom`` coincides with the robot's start pose; the increments are integrated on a
    fixed 20 ms grid, so the drift does not depend on the frame rate.
    """

    trajectory: BaseTrajectory
    scale_error: float = 0.03
    yaw_scale_error: float = 0.04
    yaw_drift_per_m: float = 0.03
    dt: float = 0.02
    _poses: list[np.ndarray] = field(default_factory=list, repr=False)
    _true: list[np.ndarray] = field(default_factory=list, repr=False)

    def _step(self, odom: np.ndarray, a: np.ndarray, b: np.ndarray) -> np.ndarray:
        inc = pose_inverse(a) @ b
        dx, dy = inc[0, 3], inc[1, 3]
        dyaw = float(np.arctan2(inc[1, 0], inc[0, 0]))
        dist = float(np.hypot(dx, dy))
        k = 1.0 + self.scale_error
        noisy = planar_pose(dx * k, dy * k, dyaw * (1.0 + self.yaw_scale_error) + self.yaw_drift_per_m * dist)
        return odom @ noisy

    def true_pose(self, t: float) -> np.ndarray:
        x, y, yaw = self.trajectory(t)
        return planar_pose(x, y, yaw)

    def pose(self, t: float) -> np.ndarray:
        """(4, 4) T_odom_base at time ``t``."""
        if not self._poses:
            self._poses.append(np.eye(4))
            self._true.append(self.true_pose(0.0))
        while (len(self._poses) - 1) * self.dt + self.dt <= t:
            nxt = self.true_pose(len(self._poses) * self.dt)
            self._poses.append(self._step(self._poses[-1], self._true[-1], nxt))
            self._true.append(nxt)
        k = min(int(t / self.dt), len(self._poses) - 1)
        return self._step(self._poses[k], self._true[k], self.true_pose(t))


@dataclass
class Robot:
    """The robot's true base motion, its odometry and its head; with ``servo`` the head obeys
    velocity commands instead of ``head``'s motion."""

    trajectory: BaseTrajectory
    head: HeadMotion
    odometry: Odometry
    servo: CommandedHead | None = None

    def base_pose(self, t: float) -> np.ndarray:
        """(4, 4) true T_map_base."""
        return self.odometry.true_pose(t)

    def head_joint(self, t: float) -> np.ndarray:
        """(4, 4) T_base_head: the pan/tilt joint."""
        if self.servo is not None:
            return make_pose(rot_z(self.servo.angles(t)[0]) @ rot_y(self.servo.tilt), HEAD_OFFSET)
        pan, tilt = self.head.angles(t)
        if self.head.look_at is not None:
            x, y, yaw = self.trajectory(t)
            bearing = np.arctan2(self.head.look_at[1] - y, self.head.look_at[0] - x) - yaw
            pan = float(np.clip(np.angle(np.exp(1j * bearing)), -self.head.pan_limit, self.head.pan_limit))
        return make_pose(rot_z(pan) @ rot_y(tilt), HEAD_OFFSET)

    @staticmethod
    def camera_mount() -> np.ndarray:
        """(4, 4) T_head_camera (static)."""
        return make_pose(OPTICAL_FROM_BODY, CAMERA_OFFSET)

    def camera_pose(self, t: float) -> np.ndarray:
        """(4, 4) true T_map_camera."""
        return self.base_pose(t) @ self.head_joint(t) @ self.camera_mount()

    def map_to_odom(self, t: float) -> np.ndarray:
        """(4, 4) T_map_odom = T_map_base @ inv(T_odom_base): the localisation's correction of the drift."""
        return self.base_pose(t) @ pose_inverse(self.odometry.pose(t))
