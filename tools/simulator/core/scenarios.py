"""The seven scenarios of the dataset of Pinto's thesis (§IV-B), plus ``handover`` for a
second camera on the base and ``guided-tour`` (a person following the robot, out of the head
camera's view) from the TU Ilmenau framework; each deterministic per seed."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Callable

import numpy as np

from tools.simulator.core.apartment import Apartment, default_apartment
from tools.simulator.core.motion import WALK_RADIUS, Action, TrackWalker, Walker, follow_route
from tools.simulator.core.robot import (
    HeadMotion,
    Odometry,
    Robot,
    Route,
    follow_trajectory,
    loop_trajectory,
    static_trajectory,
)
from tools.simulator.core.wardrobe import draw_outfits, person_height

__all__ = ["SCENARIOS", "Scenario", "World", "build_world"]

LIVING = (0.4, 1.9, 5.8, 6.6)  # where people roam in front of the robot
BEDROOM = (6.5, 0.4, 8.7, 4.6)  # behind the partition: out of view
LIVING_WEST = (0.4, 1.9, 4.6, 6.6)  # the living room west of guided-tour's leg north to the door (x = 5.6)


@dataclass
class World:
    """Everything that moves: people (``ids[i]`` is ``walkers[i]``'s ground-truth id) and the robot."""

    apartment: Apartment
    walkers: list[Walker | TrackWalker]
    ids: list[int]
    robot: Robot
    head_moves: bool
    duration_s: float


@dataclass(frozen=True)
class Scenario:
    name: str
    description: str
    duration_s: float
    build: Callable[[np.random.Generator, Apartment, bool], World]


def _walkers(
    rng: np.random.Generator,
    apt: Apartment,
    plans: list[list[Action]],
    starts: list[tuple[float, float]],
    alike: bool,
    per_person: int = 1,
    avoid: list[tuple[float, float, float]] | None = None,
    regions: list[tuple[float, float, float, float]] | None = None,
) -> list[Walker]:
    wardrobes = draw_outfits(rng, len(plans), per_person, alike)
    walkers = []
    for i, (plan, start) in enumerate(zip(plans, starts)):
        child = np.random.default_rng(rng.integers(2**63))
        walkers.append(
            Walker(
                apt,
                start,
                float(child.uniform(-np.pi, np.pi)),
                person_height(child),
                wardrobes[i],
                plan,
                child,
                speed=float(child.uniform(0.8, 1.1)),
                roam_regions=regions or [LIVING, LIVING, BEDROOM],
                avoid=avoid or [],
            )
        )
    return walkers


def _robot(
    trajectory: Callable[[float], tuple[float, float, float]], head: HeadMotion, rng: np.random.Generator
) -> Robot:
    odo = Odometry(
        trajectory,
        scale_error=float(rng.normal(0.03, 0.01)),
        yaw_scale_error=float(rng.normal(0.04, 0.01)),
        yaw_drift_per_m=float(rng.normal(0.03, 0.01)),
    )
    return Robot(trajectory, head, odo)


_STILL_POSE = (3.0, 0.6, np.pi / 2)
_STARTS = [(0.6, 5.6), (4.2, 3.0), (7.2, 2.5)]


def _still(rng: np.random.Generator, apt: Apartment, alike: bool, head: HeadMotion | None = None) -> World:
    avoid = [(_STILL_POSE[0], _STILL_POSE[1], 0.5)]
    # people 1 and 2 first cross in front of the camera, 1 m apart in depth: person 1 stops and
    # person 2 passes behind them, hidden for a moment; then everybody roams
    plans = [
        [Action("goto", (3.7, 2.8)), Action("turn", -np.pi / 2), Action("wait", seconds=4.0), Action("roam")],
        [Action("wait", seconds=2.0), Action("goto", (2.3, 3.9)), Action("wait", seconds=1.0), Action("roam")],
        [Action("goto", "door"), Action("roam")],
    ]
    starts = [(2.3, 2.8), (5.3, 3.9), (7.2, 2.5)]
    walkers = _walkers(rng, apt, plans, starts, alike, avoid=avoid)
    head = head or HeadMotion()
    return World(apt, walkers, [1, 2, 3], _robot(static_trajectory(*_STILL_POSE), head, rng), head.moves, 39.5)


def _moving_head(rng: np.random.Generator, apt: Apartment, alike: bool) -> World:
    world = _still(
        rng, apt, alike, HeadMotion(pan_amp=0.6, pan_period=14.0, tilt0=0.12, tilt_amp=0.06, tilt_period=9.0)
    )
    world.duration_s = 42.1
    return world


def _moving_base(rng: np.random.Generator, apt: Apartment, alike: bool) -> World:
    loop = loop_trajectory(apt, [(1.2, 1.3), (5.3, 1.3), (5.4, 3.3), (3.6, 3.0)])
    plans = [[Action("roam")], [Action("goto", "tv"), Action("roam")], [Action("goto", "door"), Action("roam")]]
    walkers = _walkers(rng, apt, plans, _STARTS, alike, regions=[LIVING, LIVING, LIVING, BEDROOM])
    head = HeadMotion(tilt0=0.15, look_at=(3.0, 4.6))  # the head keeps looking into the living room
    return World(apt, walkers, [1, 2, 3], _robot(loop, head, rng), head.moves, 60.0)


def _chairs(rng: np.random.Generator, apt: Apartment, alike: bool) -> World:
    pose = (2.6, 1.0, float(np.arctan2(4.8 - 1.0, 3.4 - 2.6)))
    plans = [
        [Action("sit", "chair-w", 8.0), Action("goto", "hall"), Action("sit", "chair-e", 9.0), Action("roam")],
        [Action("sit", "chair-s", 6.0), Action("goto", "window"), Action("sit", "chair-n", 8.0), Action("roam")],
        [
            Action("goto", "centre"),
            Action("sit", "sofa-right", 6.0),
            Action("wait", seconds=3.0),
            Action("sit", "chair-w", 10.0),
            Action("roam"),
        ],
    ]
    starts = [(3.0, 6.2), (5.2, 3.2), (0.6, 2.6)]
    walkers = _walkers(rng, apt, plans, starts, alike, avoid=[(pose[0], pose[1], 0.5)], regions=[LIVING])
    return World(apt, walkers, [1, 2, 3], _robot(static_trajectory(*pose), HeadMotion(tilt0=0.15), rng), False, 52.2)


def _following(rng: np.random.Generator, apt: Apartment, alike: bool) -> World:
    tour = [
        Action("goto", p) for p in ("hall", "door", "bedroom", "kitchen", "door", "centre", "tv", "window", "shelf")
    ]
    plans = [[Action("wait", seconds=2.0), *tour, Action("roam")], [Action("roam")], [Action("roam")]]
    starts = [(3.0, 2.6), (0.6, 5.6), (2.8, 5.6)]
    walkers = _walkers(rng, apt, plans, starts, alike)
    target = walkers[0]
    target.speed = 0.65  # a person being followed walks calmly
    follow = follow_trajectory(lambda t: _xy(target, t), (3.0, 0.9, np.pi / 2), apt)
    return World(apt, walkers, [1, 2, 3], _robot(follow, HeadMotion(tilt0=0.1), rng), False, 39.0)


def _xy(walker: Walker, t: float) -> np.ndarray:
    pose = walker.state(t)[0]
    return np.array([pose.x, pose.y])


def _clothes_world(rng: np.random.Generator, apt: Apartment, alike: bool, plans: list[list[Action]],
                   duration_s: float) -> World:
    """Two people with a second outfit each, watched by a still robot in the living room."""
    walkers = _walkers(
        rng,
        apt,
        plans,
        [(0.6, 5.6), (2.7, 5.0)],
        alike,
        per_person=2,
        avoid=[(_STILL_POSE[0], _STILL_POSE[1], 0.5)],
        regions=[LIVING],
    )
    return World(apt, walkers, [1, 2], _robot(static_trajectory(*_STILL_POSE), HeadMotion(), rng), False, duration_s)


def _clothes_in_view(rng: np.random.Generator, apt: Apartment, alike: bool) -> World:
    plans = [
        [
            Action("goto", (2.8, 3.8)),
            Action("turn", -np.pi / 2),
            Action("wait", seconds=3.0),
            Action("dress", 1),
            Action("wait", seconds=3.0),
            Action("roam", seconds=20.0),
            Action("goto", (2.9, 4.4)),
            Action("wait", seconds=2.0),
            Action("dress", 0),
            Action("wait", seconds=2.0),
            Action("roam"),
        ],
        [Action("roam")],
    ]
    return _clothes_world(rng, apt, alike, plans, 68.0)


def _clothes_out_of_view(rng: np.random.Generator, apt: Apartment, alike: bool) -> World:
    plans = [
        [
            Action("roam", seconds=10.0),
            Action("goto", "bedroom"),
            Action("wait", seconds=4.0),
            Action("dress", 1),
            Action("goto", "centre"),
            Action("roam"),
        ],
        [
            Action("roam", seconds=25.0),
            Action("goto", "kitchen"),
            Action("wait", seconds=4.0),
            Action("dress", 1),
            Action("goto", "tv"),
            Action("roam"),
        ],
    ]
    return _clothes_world(rng, apt, alike, plans, 56.7)


_HANDOVER_POSE = (3.4, 3.5, np.pi / 2)  # mid-room facing north: room to walk in front of and behind the robot


def _round_trips(front: tuple[float, float], side: tuple[float, float], back: tuple[float, float], trips: int,
                 start_behind: bool, stand_s: float = 3.0) -> list[Action]:
    """From the spot where the walker starts (``back`` if ``start_behind``, else ``front``), walk
    ``trips`` times to the other spot and back, passing beside the robot at ``side`` (where neither
    the head camera nor the back camera sees them), standing ``stand_s`` at each end facing the robot."""
    ends = [(back, np.pi / 2), (front, -np.pi / 2)]  # facing the robot, which faces north
    if start_behind:
        ends.reverse()
    plan: list[Action] = []
    for _ in range(trips):
        for spot, yaw in ends:
            plan += [Action("goto", side), Action("goto", spot), Action("turn", yaw), Action("wait", seconds=stand_s)]
    return plan


def _handover(rng: np.random.Generator, apt: Apartment, alike: bool) -> World:
    x, y, _ = _HANDOVER_POSE
    # person 1 crosses on the robot's left, person 2 on its right, a few seconds apart
    plans = [
        [Action("turn", -np.pi / 2), Action("wait", seconds=1.5),
         *_round_trips((2.6, 5.9), (x - 0.9, y), (2.9, 0.6), 2, start_behind=False)],
        [Action("turn", np.pi / 2), Action("wait", seconds=4.5),
         *_round_trips((3.25, 5.95), (x + 0.9, y), (4.0, 0.6), 2, start_behind=True)],
    ]
    walkers = _walkers(rng, apt, plans, [(2.6, 5.9), (4.0, 0.6)], alike, avoid=[(x, y, 0.5)], regions=[LIVING])
    # the head is level: the walls 3.3 m ahead and behind then show higher than a person (above
    # 2.3 m) in both cameras, instead of as person-sized slices to the depth detector
    robot = _robot(static_trajectory(*_HANDOVER_POSE), HeadMotion(tilt0=0.0), rng)
    return World(apt, walkers, [1, 2], robot, False, 42.0)


# the tour: south between the west wall and the sofa, east across the living room, north to the
# door, through it and south into the kitchen; the long legs straight, their corners right angles
_TOUR = [(0.6, 3.1), (0.6, 2.6), (0.95, 2.0), (5.6, 2.0), (5.6, 4.2), (7.45, 4.2), (7.45, 1.2)]
_TOUR_GUEST = (0.6, 5.5)  # person 1 at the start, by the window: 2.4 m in front of the robot, which faces them
_TOUR_GAP = 2.4  # at the start and the end: 2.3 m from the camera, a 1.95 m tall person wholly in its view
_TOUR_GAPS = (2.25, 0.75)  # while driving the gap swings 2.25 +- 0.75 m along the path
_SIDE_START = (0.8, 0.8)  # where person 2 waits, by the bookshelf (in view as the robot turns round)
_SIDE_JOIN, _SIDE_LEAVE = 1.9, 5.3  # person 2 walks beside the robot while it drives east from x = 1.9 to 5.3
_SIDE_OFFSET = -1.0  # on its right (south), out of the head camera's view
_SIDE_AFTER = (2.6, 0.7)  # then back along the south wall, behind person 1, before roaming the room's west
_TOUR_S = 48.4  # the robot stands still for good after 44.2 s: 4.2 s more facing person 1


def _polyline(points: np.ndarray) -> Callable[[float], np.ndarray]:
    """s -> (2,): the point at distance s along ``points`` (K, 2), clipped to its ends."""
    cum = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(points, axis=0), axis=1))])
    return lambda s: np.array([np.interp(s, cum, points[:, 0]), np.interp(s, cum, points[:, 1])])


def _guided_tour(rng: np.random.Generator, apt: Apartment, alike: bool) -> World:
    route = Route(apt, _TOUR, speed=0.45, turn_rate=1.0, start_yaw=np.pi / 2, wait_s=3.0, end_yaw=np.pi / 2)
    duration = _TOUR_S
    wardrobes = draw_outfits(rng, 2, 1, alike)
    guest_rng, side_rng = (np.random.default_rng(rng.integers(2**63)) for _ in range(2))

    # person 1 walks the robot's own path behind it, the gap swinging smoothly between about 1.5
    # and 3 m (period and sense per seed), back to the start's for the end
    period, sense = float(guest_rng.uniform(13.0, 19.0)), float(guest_rng.choice([-1.0, 1.0]))
    go, stop = route.depart_s, route.arrival_s

    def gap(t: float) -> float:
        swing = _TOUR_GAPS[0] + _TOUR_GAPS[1] * sense * np.sin(2 * np.pi * max(t - go, 0.0) / period)
        # from the start's gap once the robot drives off, back to it 1.5 s before the robot stops
        fade = float(np.clip(min((t - go) / 3.0, (stop - 1.5 - t) / 5.0), 0.0, 1.0)) ** 2
        return _TOUR_GAP + (swing - _TOUR_GAP) * fade

    trail = np.vstack([_TOUR_GUEST, route.path])
    lead0 = float(np.linalg.norm(route.path[0] - np.asarray(_TOUR_GUEST)))
    guest_track = follow_route(_polyline(trail), lambda t: lead0 + route.driven(t),
                               lambda t: np.asarray(route(t)[:2]), gap, duration)
    guest = TrackWalker(guest_track, duration, person_height(guest_rng), wardrobes[0])

    # person 2 catches up with the robot on its long leg east and walks beside it, then turns
    # back along the south wall and roams the living room's west, away from the route
    east = 2  # the leg from route.path[2] to route.path[3]
    x0, y0 = route.path[east]
    t_join, t_leave = (route.reaches(route.cum[east] + x - x0) for x in (_SIDE_JOIN, _SIDE_LEAVE))
    join = np.array([_SIDE_JOIN, y0 + _SIDE_OFFSET])
    approach = apt.plan(np.asarray(_SIDE_START), join, WALK_RADIUS)
    walk = _polyline(approach)
    length = float(np.sum(np.linalg.norm(np.diff(approach, axis=0), axis=1)))
    t_set = t_join - length / float(side_rng.uniform(0.6, 0.75))  # 0.6-0.75 m/s, then the robot's 0.45

    def side_track(t: float) -> np.ndarray:
        if t < t_join:
            return walk(length * float(np.clip((t - t_set) / (t_join - t_set), 0.0, 1.0)))
        x, y, _ = route(min(t, t_leave))
        return np.array([x, y + _SIDE_OFFSET])

    side = TrackWalker(side_track, t_leave, person_height(side_rng), wardrobes[1])
    leave = side_track(side.until)
    plan = [Action("wait", seconds=side.until), Action("turn", np.pi), Action("goto", _SIDE_AFTER),
            Action("wait", seconds=2.0), Action("goto", "centre"), Action("roam")]
    side.then = Walker(apt, (float(leave[0]), float(leave[1])), 0.0, side.height, side.wardrobe, plan, side_rng,
                       speed=float(side_rng.uniform(0.8, 1.1)), roam_regions=[LIVING_WEST])
    robot = _robot(route, HeadMotion(tilt0=0.1), rng)
    return World(apt, [guest, side], [1, 2], robot, False, duration)


SCENARIOS: dict[str, Scenario] = {
    s.name: s
    for s in (
        Scenario("still", "static robot and head; three people walk, stop, cross and leave the room", 39.5, _still),
        Scenario("moving-head", "static base, the head pans and tilts; three people walk around", 42.1, _moving_head),
        Scenario(
            "moving-base",
            "the robot drives a loop, its head looking into the room; furniture occludes people",
            60.0,
            _moving_base,
        ),
        Scenario("chairs", "three people sit on chairs and the sofa and switch places", 52.2, _chairs),
        Scenario(
            "people-following",
            "the robot follows person 1 through the apartment; two others walk around",
            39.0,
            _following,
        ),
        Scenario(
            "changing-clothes-in-view",
            "two people; person 1 changes clothes in front of the camera",
            68.0,
            _clothes_in_view,
        ),
        Scenario(
            "changing-clothes-out-of-view",
            "two people; each changes clothes in the other room and comes back",
            56.7,
            _clothes_out_of_view,
        ),
        Scenario(
            "handover",
            "static robot mid-room; two people walk from the front of the robot to behind it and back, twice, "
            "passing beside it: from the head camera's view into the back camera's (--back-camera)",
            42.0,
            _handover,
        ),
        Scenario(
            "guided-tour",
            "the robot guides person 1, who follows 1.5-3 m behind it out of the head camera's view, through the "
            "apartment; person 2 walks beside it for a stretch; it faces person 1 at the start and the end",
            _TOUR_S,
            _guided_tour,
        ),
    )
}


def build_world(name: str, seed: int = 0, alike: bool = False, apartment: Apartment | None = None) -> World:
    """The world of scenario ``name`` for ``seed``; ``alike`` dresses the first two people the same."""
    if name not in SCENARIOS:
        raise KeyError(f"unknown scenario {name!r}; choose one of {', '.join(SCENARIOS)}")
    rng = np.random.default_rng(seed)
    return SCENARIOS[name].build(rng, apartment or default_apartment(), alike)
