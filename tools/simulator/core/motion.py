"""People's motion as timelines: walk along planned paths, stand, sit, change clothes.

A :class:`Walker` turns a plan (a list of :class:`Action`) into time-stamped segments once,
with its own random generator, so its state is a pure function of time: the same seed
gives the same motion whatever the frame rate. When the plan runs out the walker roams
(random goals in its roaming regions) and the timeline grows on demand.

A :class:`TrackWalker` instead walks a given track (t -> position), e.g. the path a robot
drove (:func:`follow_route`: a person following the robot at a varying gap), and may hand
over to a :class:`Walker` when the track ends.
"""

from __future__ import annotations

import bisect
from dataclasses import dataclass, field, replace
from typing import Callable

import numpy as np

from tools.simulator.core.apartment import Apartment
from tools.simulator.core.body import Clothing, PersonPose

__all__ = ["Action", "TrackWalker", "Walker", "WALK_RADIUS", "follow_route"]

#: Clearance (m) every walker keeps from walls and furniture.
WALK_RADIUS = 0.3
_STRIDE = 1.3  # metres per gait cycle


@dataclass(frozen=True)
class Action:
    """One step of a plan.

    kind: ``goto`` (target: a place name, a seat name or an (x, y) point), ``wait`` (seconds),
    ``sit`` (target: a seat name; seconds) -- the walker goes to the seat first --,
    ``turn`` (yaw in radians), ``dress`` (index into the walker's wardrobe), ``roam`` (seconds
    of random goals; 0 = forever).
    """

    kind: str
    target: object = None
    seconds: float = 0.0


@dataclass
class _Segment:
    t0: float
    t1: float
    path: np.ndarray  # (K, 2) waypoints; one row when standing or sitting
    cum: np.ndarray  # (K,) distance along the path
    yaw: float  # heading while not moving
    posture: str
    seat_height: float = 0.45
    dist0: float = 0.0  # gait distance walked before this segment


@dataclass
class Walker:
    """A person's body, wardrobe and motion. ``state(t)`` gives (pose, clothing index, velocity)."""

    apartment: Apartment
    start: tuple[float, float]
    start_yaw: float
    height: float
    wardrobe: list[Clothing]
    plan: list[Action]
    rng: np.random.Generator
    speed: float = 1.0
    roam_regions: list[tuple[float, float, float, float]] = field(default_factory=lambda: [(0.3, 0.3, 5.9, 6.7)])
    avoid: list[tuple[float, float, float]] = field(default_factory=list)  # (x, y, radius) circles
    _segments: list[_Segment] = field(default_factory=list, repr=False)
    _starts: list[float] = field(default_factory=list, repr=False)
    _dress: list[tuple[float, int]] = field(default_factory=list, repr=False)
    _queue: list[Action] = field(default_factory=list, repr=False)

    def __post_init__(self) -> None:
        self._pos = np.array(self.start, dtype=np.float64)
        self._yaw = float(self.start_yaw)
        self._t = 0.0
        self._dist = 0.0
        self._dress = [(0.0, 0)]
        self._queue = list(self.plan)
        self._roam_until: float | None = None

    # ------------------------------------------------------------- building
    def _push(self, seg: _Segment) -> None:
        self._segments.append(seg)
        self._starts.append(seg.t0)
        self._t = seg.t1

    def _stand(self, seconds: float, posture: str = "standing", seat_height: float = 0.45) -> None:
        self._push(
            _Segment(
                self._t,
                self._t + seconds,
                self._pos[None, :].copy(),
                np.zeros(1),
                self._yaw,
                posture,
                seat_height,
                self._dist,
            )
        )

    def _blocked(self, p: np.ndarray) -> bool:
        return any(np.hypot(p[0] - x, p[1] - y) < r + WALK_RADIUS for x, y, r in self.avoid)

    def _walk_to(self, goal: np.ndarray, path: np.ndarray | None = None) -> None:
        if np.linalg.norm(goal - self._pos) < 0.05:
            return
        if path is None:
            path = self.apartment.plan(self._pos, goal, WALK_RADIUS)
        cum = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(path, axis=0), axis=1))])
        speed = self.speed * float(self.rng.uniform(0.85, 1.15))
        seg = _Segment(self._t, self._t + cum[-1] / speed, path, cum, self._yaw, "walking", 0.45, self._dist)
        self._push(seg)
        last = path[-1] - path[-2]
        self._yaw = float(np.arctan2(last[1], last[0]))
        self._pos = path[-1].copy()
        self._dist += float(cum[-1])

    def _resolve(self, target: object) -> np.ndarray:
        if isinstance(target, str):
            if target in self.apartment.places:
                return np.array(self.apartment.places[target], dtype=np.float64)
            raise KeyError(f"unknown place {target!r}")
        return np.asarray(target, dtype=np.float64)

    def _random_goal(self) -> tuple[np.ndarray, np.ndarray | None]:
        """A reachable random goal in a roaming region and the path to it (None: stay)."""
        region = self.roam_regions[int(self.rng.integers(len(self.roam_regions)))]
        for _ in range(200):
            p = self.apartment.random_free_point(self.rng, region, WALK_RADIUS + 0.05)
            if self._blocked(p) or np.linalg.norm(p - self._pos) <= 1.0:
                continue
            try:
                return p, self.apartment.plan(self._pos, p, WALK_RADIUS)
            except ValueError:  # in a pocket the walker cannot reach
                continue
        return self._pos.copy(), None

    def _next(self) -> None:
        """Append the segments of the next action (or of one roaming leg)."""
        if not self._queue:
            self._queue.append(Action("roam", seconds=0.0))
        act = self._queue[0]
        if act.kind == "roam":
            if self._roam_until is None:
                self._roam_until = self._t + act.seconds if act.seconds > 0 else np.inf
            if self._t >= self._roam_until:
                self._queue.pop(0)
                self._roam_until = None
                return
            self._walk_to(*self._random_goal())
            self._stand(float(self.rng.uniform(0.5, 3.0)))
            return
        self._queue.pop(0)
        if act.kind == "goto":
            self._walk_to(self._resolve(act.target))
        elif act.kind == "wait":
            self._stand(act.seconds)
        elif act.kind == "turn":
            self._yaw = float(act.target)  # type: ignore[arg-type]
            self._stand(0.5)
        elif act.kind == "dress":
            self._dress.append((self._t, int(act.target)))  # type: ignore[call-overload]
        elif act.kind == "sit":
            seat = self.apartment.seats[str(act.target)]
            self._approach(seat.x, seat.y, seat.yaw)
            self._yaw = seat.yaw
            self._stand(0.6)
            stand_pos = self._pos.copy()
            self._pos = np.array([seat.x, seat.y])
            self._stand(act.seconds, "sitting", seat.height)
            self._pos = stand_pos
            self._stand(0.6)
        else:
            raise ValueError(f"unknown action {act.kind!r}")

    def _approach(self, x: float, y: float, yaw: float) -> None:
        """Walk to a free, reachable standing point next to a seat: in front, else beside, else behind it."""
        for turn in (0.0, np.pi / 2, -np.pi / 2, np.pi):
            p = np.array([x + 0.75 * np.cos(yaw + turn), y + 0.75 * np.sin(yaw + turn)])
            if not self.apartment.clearance_ok(p, WALK_RADIUS)[0]:
                continue
            try:
                path = self.apartment.plan(self._pos, p, WALK_RADIUS)
            except ValueError:
                continue
            self._walk_to(p, path)
            return
        raise ValueError(f"no reachable free point next to the seat at ({x:.2f}, {y:.2f})")

    def _extend(self, t: float) -> None:
        guard = 0
        while self._t <= t:
            before = self._t
            self._next()
            guard = guard + 1 if self._t == before else 0
            if guard > 50:  # a plan that makes no progress: stand still a while
                self._stand(1.0)
                guard = 0

    # ------------------------------------------------------------- queries
    def state(self, t: float) -> tuple[PersonPose, int, np.ndarray]:
        """Pose at time ``t`` (s), the wardrobe index worn, and the velocity (2,) in m/s."""
        self._extend(t)
        seg = self._segments[max(0, bisect.bisect_right(self._starts, t) - 1)]
        dress = self._dress[max(0, bisect.bisect_right([d[0] for d in self._dress], t) - 1)][1]
        if seg.posture != "walking":
            p = seg.path[0]
            return (
                PersonPose(
                    float(p[0]),
                    float(p[1]),
                    seg.yaw,
                    "sitting" if seg.posture == "sitting" else "standing",
                    phase=2 * np.pi * seg.dist0 / _STRIDE,
                    seat_height=seg.seat_height,
                ),
                dress,
                np.zeros(2),
            )
        dur = seg.t1 - seg.t0
        s = float(np.clip((t - seg.t0) / dur, 0.0, 1.0)) * seg.cum[-1]
        k = int(np.clip(np.searchsorted(seg.cum, s, side="right") - 1, 0, len(seg.cum) - 2))
        a, b = seg.path[k], seg.path[k + 1]
        frac = (s - seg.cum[k]) / max(seg.cum[k + 1] - seg.cum[k], 1e-9)
        p = a + frac * (b - a)
        direction = (b - a) / max(float(np.linalg.norm(b - a)), 1e-9)
        velocity = direction * seg.cum[-1] / dur
        # ease the gait in and out over the first and last 0.3 m
        gait = float(np.clip(min(s, seg.cum[-1] - s) / 0.3, 0.0, 1.0))
        pose = PersonPose(
            float(p[0]),
            float(p[1]),
            float(np.arctan2(direction[1], direction[0])),
            "standing",
            phase=2 * np.pi * (seg.dist0 + s) / _STRIDE,
            gait=max(gait, 0.4),
        )
        return pose, dress, velocity


@dataclass
class TrackWalker:
    """A person walking a given ``track`` (t -> (2,) floor position) over [0, ``until``] s,
    then, with ``then``, that :class:`Walker`'s motion (start it where the track ends, standing
    until ``until``), else standing where the track ends. The track is sampled every ``dt`` and
    walked piecewise linearly between samples, so ``state(t)`` is a pure function of time as a
    Walker's is: the velocity is the derivative of the position, the heading the walking
    direction (the next one before the first step, the last one when standing), the gait
    grows with speed and is 0 when still. Same interface as :class:`Walker` for the simulation."""

    track: Callable[[float], np.ndarray]
    until: float
    height: float
    wardrobe: list[Clothing]
    then: Walker | None = None
    dt: float = 0.05
    start_yaw: float = 0.0  # the heading if the track never moves

    def __post_init__(self) -> None:
        n = max(1, int(np.ceil(self.until / self.dt - 1e-9)))
        self.until = n * self.dt
        self._xy = np.array([np.asarray(self.track(k * self.dt), np.float64) for k in range(n + 1)])
        self._step = np.diff(self._xy, axis=0)  # (n, 2) the displacement in each dt
        length = np.linalg.norm(self._step, axis=1)
        self._dist = np.concatenate([[0.0], np.cumsum(length)])
        yaw = np.full(n, np.nan)
        moving = length > 1e-6
        yaw[moving] = np.arctan2(self._step[moving, 1], self._step[moving, 0])
        if moving.any():
            first = int(np.argmax(moving))
            yaw[:first] = yaw[first]
            for k in range(first + 1, n):  # standing keeps the last heading
                if not moving[k]:
                    yaw[k] = yaw[k - 1]
        else:
            yaw[:] = self.start_yaw
        self._yaw = yaw

    def state(self, t: float) -> tuple[PersonPose, int, np.ndarray]:
        """Pose at time ``t`` (s), the wardrobe index worn, and the velocity (2,) in m/s."""
        if t >= self.until:
            if self.then is not None:
                pose, outfit, velocity = self.then.state(t)  # its gait goes on from the track's
                return replace(pose, phase=pose.phase + 2 * np.pi * self._dist[-1] / _STRIDE), outfit, velocity
            end = self._xy[-1]
            return (PersonPose(float(end[0]), float(end[1]), float(self._yaw[-1]),
                               phase=2 * np.pi * self._dist[-1] / _STRIDE), 0, np.zeros(2))
        u = max(t, 0.0) / self.dt
        k = min(int(u), len(self._step) - 1)
        f = u - k
        p = self._xy[k] + f * self._step[k]
        velocity = self._step[k] / self.dt if t >= 0 else np.zeros(2)
        speed = float(np.linalg.norm(velocity))
        dist = self._dist[k] + f * (self._dist[k + 1] - self._dist[k])
        pose = PersonPose(float(p[0]), float(p[1]), float(self._yaw[k]), "standing",
                          phase=2 * np.pi * dist / _STRIDE, gait=min(1.0, speed / 0.5))
        return pose, 0, velocity


def follow_route(
    at: Callable[[float], np.ndarray],
    lead: Callable[[float], float],
    leader: Callable[[float], np.ndarray],
    gap: Callable[[float], float],
    until: float,
    dt: float = 0.05,
    max_speed: float = 1.1,
    max_accel: float = 0.8,
    gain: float = 0.8,
    keep_off: float = 1.35,
) -> Callable[[float], np.ndarray]:
    """The track (t -> (2,)) of a person who walks along a path behind whoever leads on it.

    ``at(s)`` is the point of the path at distance s along it, ``lead(t)`` the leader's distance
    along the same path and ``leader(t)`` their position (2,); the person starts at s = 0 and
    walks to keep ``gap(t)`` metres of path behind the leader: at the leader's speed plus
    ``gain`` times the error, never backwards, at most ``max_speed``, changing speed by at most
    ``max_accel``, and slowing to a stop before coming within ``keep_off`` of the leader in a
    straight line (where the path turns a corner). Walking only the path the leader took keeps
    them where the leader could go."""
    n = int(np.ceil(until / dt)) + 1
    s = np.zeros(n + 1)
    v = 0.0
    for k in range(n):
        t = k * dt
        lead_speed = (lead(t + dt) - lead(t)) / dt
        want = float(np.clip(lead_speed + gain * (lead(t) - gap(t) - s[k]), 0.0, max_speed))
        v = float(np.clip(want, v - max_accel * dt, v + max_accel * dt))
        room = float(np.linalg.norm(at(s[k]) - leader(t))) - keep_off
        v = max(0.0, min(v, 2.0 * room))
        s[k + 1] = s[k] + v * dt
    times = np.arange(n + 1) * dt

    def track(t: float) -> np.ndarray:
        return at(float(np.interp(t, times, s)))

    return track
