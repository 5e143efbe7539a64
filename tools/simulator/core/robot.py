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
from common.geometry.poses import OPTICAL_FROM_BODY, make_pose, planar_pose, pose_inverse, rot_y, rot_z

__all__ = [
    "HeadMotion",
    "Odometry",
    "ROBOT_RADIUS",
    "Robot",
    "Route",
    "follow_trajectory",
    "loop_trajectory",
    "static_trajectory",
    "whole_in_sight",
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


def _drive_knots(path: np.ndarray, yaw: float, t: float, speed: float, turn_rate: float) -> list[tuple[float, ...]]:
    """(t, x, y, yaw) knots of a base driving ``path`` (K, 2) from time ``t`` and heading ``yaw``
    (unwrapped): at each corner it turns in place at ``turn_rate``, then drives straight at ``speed``."""
    knots: list[tuple[float, ...]] = []
    for a, b in zip(path[:-1], path[1:]):
        heading = float(np.arctan2(b[1] - a[1], b[0] - a[0]))
        turn = float(np.angle(np.exp(1j * (heading - yaw))))
        t += abs(turn) / turn_rate
        yaw += turn
        knots.append((t, a[0], a[1], yaw))
        t += float(np.linalg.norm(b - a)) / speed
        knots.append((t, b[0], b[1], yaw))
    return knots


def loop_trajectory(
    apartment: Apartment, waypoints: list[tuple[float, float]], speed: float = 0.35, turn_rate: float = 0.6
) -> BaseTrajectory:
    """Drive a closed loop through ``waypoints`` (planned around furniture), turning in place at corners."""
    pts = [np.asarray(waypoints[0], float)]
    for a, b in zip(waypoints, waypoints[1:] + waypoints[:1]):
        pts += list(apartment.plan(np.asarray(a, float), np.asarray(b, float), ROBOT_RADIUS)[1:])
    path = np.stack(pts)
    yaw = float(np.arctan2(*(path[1] - path[0])[::-1]))
    knots = [(0.0, path[0][0], path[0][1], yaw), *_drive_knots(path, yaw, 0.0, speed, turn_rate)]  # (t, x, y, yaw)
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


class Route:
    """A base that drives once along ``waypoints`` (planned around furniture, as
    :func:`loop_trajectory` does) and stays at the end: it first stands ``wait_s`` facing
    ``start_yaw``, turns in place towards the path, drives at ``speed`` turning in place at
    corners (``turn_rate``), and at the end turns in place to ``end_yaw``. Callable as a
    :data:`BaseTrajectory`; :attr:`path` (K, 2) is the planned path (:attr:`cum` the distance
    along it at each vertex), :meth:`driven` the distance driven by time t and :meth:`reaches`
    when it first gets somewhere, for people who walk the same path."""

    def __init__(self, apartment: Apartment, waypoints: list[tuple[float, float]], speed: float = 0.45,
                 turn_rate: float = 1.0, start_yaw: float | None = None, wait_s: float = 0.0,
                 end_yaw: float | None = None) -> None:
        pts = [np.asarray(waypoints[0], float)]
        for a, b in zip(waypoints[:-1], waypoints[1:]):
            pts += list(apartment.plan(np.asarray(a, float), np.asarray(b, float), ROBOT_RADIUS)[1:])
        self.path = np.stack(pts)
        self.cum = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(self.path, axis=0), axis=1))])
        first = self.path[1] - self.path[0]
        yaw = float(np.arctan2(first[1], first[0])) if start_yaw is None else float(start_yaw)
        knots = [(0.0, *self.path[0], yaw), (wait_s, *self.path[0], yaw), *_drive_knots(self.path, yaw, wait_s, speed,
                                                                                      turn_rate)]
        self.depart_s = float(knots[2][0]) if len(knots) > 2 else float(wait_s)  # when it starts driving
        self.arrival_s = float(knots[-1][0])  # when it stops at the end of the path
        if end_yaw is not None:
            last = knots[-1][3]
            turn = float(np.angle(np.exp(1j * (end_yaw - last))))
            knots.append((self.arrival_s + abs(turn) / turn_rate, *self.path[-1], last + turn))
        self.knots = np.array(knots, float)  # (t, x, y, unwrapped yaw)
        self.end_s = float(self.knots[-1, 0])  # when it stands still for good
        # the distance driven at each knot: nothing while standing and turning, each segment's end after it
        along = [0.0, 0.0, *(d for i in range(len(self.path) - 1) for d in (self.cum[i], self.cum[i + 1]))]
        self._driven = np.array(along + [self.cum[-1]] * (len(self.knots) - len(along)))

    def __call__(self, t: float) -> tuple[float, float, float]:
        k = self.knots
        yaw = float(np.interp(t, k[:, 0], k[:, 3]))
        return float(np.interp(t, k[:, 0], k[:, 1])), float(np.interp(t, k[:, 0], k[:, 2])), float(
            np.angle(np.exp(1j * yaw)))

    def driven(self, t: float) -> float:
        """The distance (m) driven along :attr:`path` by time ``t``."""
        return float(np.interp(t, self.knots[:, 0], self._driven))

    def reaches(self, s: float) -> float:
        """When the base first reaches distance ``s`` along :attr:`path` (inf: never)."""
        d, t = self._driven, self.knots[:, 0]
        i = int(np.searchsorted(d, s, side="left"))  # the first knot at or past s
        if i == 0:
            return float(t[0])
        if i >= len(d):
            return float("inf")
        return float(t[i - 1] + (s - d[i - 1]) / (d[i] - d[i - 1]) * (t[i] - t[i - 1]))


#: Half a person's width: a base stops only when it sees both shoulders, not the target's middle
#: past a door frame that hides the rest.
_HALF_WIDTH_M = 0.25


def whole_in_sight(p: np.ndarray, q: np.ndarray, apartment: Apartment) -> bool:
    """Whether a person at ``q`` (2,) is in sight from ``p`` across their whole width."""
    d = q - p
    n = float(np.linalg.norm(d))
    if n < 1e-6:
        return True
    side = np.array([-d[1], d[0]]) / n * _HALF_WIDTH_M
    return apartment.line_of_sight(p, q + side) and apartment.line_of_sight(p, q - side)


_LOOKAHEAD_S = np.arange(0.0, 2.01, 0.25)  # how far ahead a base making way looks at the target's path


def _make_way(p: np.ndarray, ahead: np.ndarray, step: float, apartment: Apartment, radius: float) -> np.ndarray:
    """The clear spot within ``step`` of ``p`` (or ``p`` itself) farthest from the target's
    next positions ``ahead``: a base stepping out of the way of someone walking at it."""
    angles = np.linspace(0.0, 2.0 * np.pi, 16, endpoint=False)
    spots = [p] + [p + step * np.array([np.cos(a), np.sin(a)]) for a in angles]
    best, score = p, -np.inf
    for spot in spots:
        margin = float(np.min(np.linalg.norm(ahead - spot, axis=1)))
        if margin > score + 1e-9 and (spot is p or apartment.segment_free(p, spot, radius)):
            best, score = spot, margin
    return best


def follow_trajectory(
    target: Callable[[float], np.ndarray],
    start: tuple[float, float, float],
    apartment: Apartment,
    gap: float = 2.2,
    min_gap: float = 1.0,
    max_speed: float = 1.0,
    max_turn_rate: float = 1.5,
    dt: float = 0.05,
) -> BaseTrajectory:
    """A base that follows ``target(t) -> (2,)`` the way a people-following robot does.

    It drives towards the farthest point of the target's trail (which starts with the segment
    from ``start`` to the target) that it can reach in a straight, clear line, so it cuts
    corners and skips the loops the target walked back out of, at most ``max_speed``. It
    stops once it sees the whole target (no wall above eye height between it and either of
    their shoulders: not a person half hidden by a door frame) within ``gap``; a
    target hidden round a corner is followed closer, down to ``min_gap``, and when the target's
    next two seconds come closer than that it steps out of the target's way (the scenario knows where
    the target walks next: a stand-in for a robot reading the person's motion). It turns at most
    ``max_turn_rate`` towards the target when it sees it, along its way otherwise. The
    straight lines it drives keep the walkers' clearance, so it stays clear of walls and
    furniture as the target's trail does.
    """
    radius = 0.3  # the trail's clearance (motion.WALK_RADIUS): a shortcut is as clear as the trail
    p0 = np.asarray(start[:2], float)
    trail = [p0, np.asarray(target(0.0), float)]
    states = [(float(p0[0]), float(p0[1]), float(start[2]))]  # (x, y, yaw) at t = k * dt
    carrot = [1]  # the farthest trail index reached in a straight line so far

    def step(k: int) -> None:
        q = np.asarray(target(k * dt), float)
        if np.linalg.norm(q - trail[-1]) > 0.02:
            trail.append(q)
        x, y, yaw = states[-1]
        p = np.array([x, y])
        seen = apartment.line_of_sight(p, q)
        dist = float(np.linalg.norm(q - p))
        whole = seen and whole_in_sight(p, q, apartment)
        # the farthest trail point drivable in a straight line (scanning back from the newest)
        for i in range(len(trail) - 1, carrot[0] - 1, -1):
            if apartment.segment_free(p, trail[i], radius):
                carrot[0] = i
                break
        goal = trail[carrot[0]] - p
        length = float(np.linalg.norm(goal))
        move = 0.0 if (whole and dist <= gap) else min(max_speed * dt, length)
        if move > 0.0:
            nxt = p + goal / length * move
            if not (np.linalg.norm(q - nxt) < min_gap and np.linalg.norm(q - nxt) < dist):
                p = nxt
        else:
            ahead = np.array([target(k * dt + h) for h in _LOOKAHEAD_S], float)
            if np.min(np.linalg.norm(ahead - p, axis=1)) < min_gap:  # it walks at the base: make way
                p = _make_way(p, ahead, max_speed * dt, apartment, radius)
        look = q - p if seen else (goal if length > 0.1 else q - p)
        want = float(np.arctan2(look[1], look[0])) if np.linalg.norm(look) > 0.1 else yaw
        turn = float(np.angle(np.exp(1j * (want - yaw))))
        yaw = float(np.angle(np.exp(1j * (yaw + np.clip(turn, -max_turn_rate * dt, max_turn_rate * dt)))))
        states.append((float(p[0]), float(p[1]), yaw))

    def pose(t: float) -> tuple[float, float, float]:
        while (len(states) - 1) * dt < t + dt:
            step(len(states))
        k = max(0.0, t / dt)
        i = min(int(k), len(states) - 2)
        a, b, f = states[i], states[i + 1], k - i
        yaw = a[2] + f * float(np.angle(np.exp(1j * (b[2] - a[2]))))
        return a[0] + f * (b[0] - a[0]), a[1] + f * (b[1] - a[1]), float(np.angle(np.exp(1j * yaw)))

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
