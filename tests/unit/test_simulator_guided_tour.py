"""The simulator's ``guided-tour`` scenario (TU Ilmenau's guided tour): the robot drives ahead
through the apartment while person 1 follows it, out of the head camera's view but for the start
and the end, where the robot faces them; person 2 walks beside it for a stretch. Also the
:class:`TrackWalker` and :class:`Route` it is built from."""

from __future__ import annotations

import numpy as np
import pytest

from tools.simulator.core.apartment import default_apartment
from tools.simulator.core.motion import WALK_RADIUS, Action, TrackWalker, Walker, follow_route
from tools.simulator.core.render import default_camera
from tools.simulator.core.robot import ROBOT_RADIUS, Route
from tools.simulator.core.scenarios import SCENARIOS, World, build_world
from tools.simulator.core.simulation import Simulation
from tools.simulator.core.wardrobe import OUTFITS

NAME = "guided-tour"
DT = 0.1


def _times(world: World) -> np.ndarray:
    return np.arange(0.0, world.duration_s, DT)


def _people(world: World, ts: np.ndarray) -> np.ndarray:
    """(P, T, 2) everybody's floor position at ``ts``."""
    return np.array([[[w.state(float(t))[0].x, w.state(float(t))[0].y] for t in ts] for w in world.walkers])


def _base(world: World, ts: np.ndarray) -> np.ndarray:
    """(T, 3) the robot's true (x, y, yaw) at ``ts``."""
    return np.array([world.robot.trajectory(float(t)) for t in ts])


def _driving(world: World, ts: np.ndarray) -> np.ndarray:
    route = world.robot.trajectory
    assert isinstance(route, Route)
    return (ts >= route.depart_s) & (ts <= route.arrival_s)


def test_it_is_listed_and_lasts_40_to_50_s() -> None:
    scenario = SCENARIOS[NAME]
    world = build_world(NAME, seed=0)
    assert 40.0 <= scenario.duration_s <= 50.0 and world.duration_s == scenario.duration_s
    assert world.ids == [1, 2] and not world.head_moves
    assert world.robot.head.angles(10.0) == (0.0, pytest.approx(0.1))  # the head looks forward


def test_the_same_seed_gives_the_same_tour_another_seed_another_gap() -> None:
    ts = np.arange(0.0, SCENARIOS[NAME].duration_s, 0.5)
    a, b, c = (build_world(NAME, seed=s) for s in (4, 4, 5))
    for w, v in zip(a.walkers, b.walkers):
        for t in ts:
            pa, oa, va = w.state(float(t))
            pb, ob, vb = v.state(float(t))
            assert pa == pb and oa == ob and np.array_equal(va, vb)
    assert np.array_equal(_base(a, ts), _base(b, ts))
    assert np.array_equal(_base(a, ts), _base(c, ts))  # the route is the same for every seed ...
    assert not np.allclose(_people(a, ts)[0], _people(c, ts)[0])  # ... how person 1 follows it is not


@pytest.mark.parametrize("seed", [0, 1, 2, 3])
def test_person_1_follows_1_2_to_3_2_m_behind_the_driving_robot(seed: int) -> None:
    world = build_world(NAME, seed=seed)
    ts = _times(world)
    base, guest = _base(world, ts), _people(world, ts)[0]
    gap = np.linalg.norm(guest - base[:, :2], axis=1)
    drive = _driving(world, ts)
    assert gap.min() > 1.2 and gap[drive].max() < 3.2
    assert gap[drive].max() - gap[drive].min() > 0.8  # the gap varies, it is not a rigid tow
    heading = np.column_stack([np.cos(base[:, 2]), np.sin(base[:, 2])])
    ahead = np.einsum("ij,ij->i", guest - base[:, :2], heading)
    assert np.mean(ahead[drive] < 0) > 0.9  # behind the robot (on a corner: beside it)
    # they walk, never backwards, not faster than 1.1 m/s, and along the path the robot drove
    steps = np.linalg.norm(np.diff(guest, axis=0), axis=1)
    assert steps.max() <= 1.1 * DT + 1e-6 and steps.sum() > 12.0
    route = world.robot.trajectory
    assert isinstance(route, Route)
    trail = np.vstack([guest[0], route.path])  # from where they stood to where the robot started, then its path
    assert max(_to_polyline(p, trail) for p in guest) < 0.01


def _to_polyline(p: np.ndarray, path: np.ndarray) -> float:
    """Distance from ``p`` (2,) to the polyline ``path`` (K, 2)."""
    a, b = path[:-1], path[1:]
    ab = b - a
    f = np.clip(np.einsum("ij,ij->i", p - a, ab) / np.maximum(np.einsum("ij,ij->i", ab, ab), 1e-12), 0.0, 1.0)
    return float(np.linalg.norm(a + f[:, None] * ab - p, axis=1).min())


@pytest.mark.parametrize("seed", [0, 2])
def test_nobody_walks_through_walls_or_furniture_or_the_robot(seed: int) -> None:
    world = build_world(NAME, seed=seed)
    apt = world.apartment
    ts = np.arange(0.0, world.duration_s + 10.0, 0.05)  # and on after the end (person 2 roams)
    base, people = _base(world, ts), _people(world, ts)
    assert apt.clearance_ok(base[:, :2], ROBOT_RADIUS - 0.005).all()
    for person in people:
        # paths are checked every 5 cm: between checks a corner can come up to ~1 mm closer
        assert apt.clearance_ok(person, WALK_RADIUS - 0.005).all()
        assert np.linalg.norm(person - base[:, :2], axis=1).min() > 0.95
    assert np.linalg.norm(people[0] - people[1], axis=1).min() > 1.0


def test_person_2_walks_beside_the_robot_for_several_seconds() -> None:
    world = build_world(NAME, seed=1)
    ts = _times(world)
    base, side = _base(world, ts), _people(world, ts)[1]
    offset = side - base[:, :2]
    heading = np.column_stack([np.cos(base[:, 2]), np.sin(base[:, 2])])
    along = np.einsum("ij,ij->i", offset, heading)
    across = heading[:, 0] * offset[:, 1] - heading[:, 1] * offset[:, 0]
    moving = np.r_[np.linalg.norm(np.diff(base[:, :2], axis=0), axis=1) > 0.01, False]
    beside = moving & (np.abs(along) < 0.05) & (np.abs(np.abs(across) - 1.0) < 0.05)
    assert beside.sum() * DT > 5.0
    assert not beside[: int(3.0 / DT)].any() and not beside[-int(15.0 / DT):].any()  # joins, then walks off


def test_the_head_camera_sees_person_1_at_the_start_and_the_end_and_hardly_during_the_drive() -> None:
    world = build_world(NAME, seed=0)
    fps = 2.0
    sim = Simulation(world, default_camera(160, 120), fps=fps, seed=0, depth_noise=False)
    route = world.robot.trajectory
    assert isinstance(route, Route)
    last = int(world.duration_s * fps) - 1

    def counted(seq: int) -> list[bool]:
        return [p.counted for p in sim.frame(seq).people]

    start = [counted(k) for k in range(0, int(3.0 * fps))]  # the robot stands facing them
    end = [counted(k) for k in range(last - int(3.5 * fps), last + 1)]  # it has turned round to face them
    drive = [counted(k) for k in range(int((route.depart_s + 1.0) * fps), int(route.arrival_s * fps), 3)]
    assert all(c[0] for c in start) and all(c[0] for c in end)
    assert np.mean([c[0] for c in drive]) < 0.2
    near = [fd.people[0] for fd in (sim.frame(0), sim.frame(last))]
    assert all(p.in_view_fraction > 0.95 and p.posture == "standing" for p in near)  # wholly in view, standing


def test_person_1_stands_facing_the_robot_at_the_start_and_the_end() -> None:
    world = build_world(NAME, seed=3)
    route = world.robot.trajectory
    assert isinstance(route, Route)
    for t in (0.5, 2.5, route.end_s + 0.5, world.duration_s - 0.1):
        pose, _, velocity = world.walkers[0].state(t)
        x, y, yaw = route(t)
        to_robot = np.arctan2(y - pose.y, x - pose.x)
        to_person = np.arctan2(pose.y - y, pose.x - x)
        assert abs(np.angle(np.exp(1j * (pose.yaw - to_robot)))) < 0.15
        assert abs(np.angle(np.exp(1j * (yaw - to_person)))) < 0.15  # the robot faces them too
        assert np.array_equal(velocity, np.zeros(2)) and pose.gait == 0.0
        assert 2.0 < np.hypot(pose.x - x, pose.y - y) < 2.6


@pytest.mark.parametrize("who", [0, 1])
def test_the_track_walkers_velocity_heading_and_gait_agree_with_their_motion(who: int) -> None:
    walker = build_world(NAME, seed=2).walkers[who]
    assert isinstance(walker, TrackWalker)
    for t in np.arange(0.01, walker.until - 0.06, 0.37):
        pose, _, velocity = walker.state(float(t))
        nxt = walker.state(float(t) + 0.01)[0]
        if int(t / walker.dt) != int((t + 0.01) / walker.dt):
            continue  # the derivative of the piecewise-linear track: both ends in one sample step
        assert np.allclose(velocity, [(nxt.x - pose.x) / 0.01, (nxt.y - pose.y) / 0.01], atol=1e-6)
        speed = float(np.linalg.norm(velocity))
        if speed > 0.05:
            assert abs(np.angle(np.exp(1j * (pose.yaw - np.arctan2(velocity[1], velocity[0]))))) < 1e-6
            assert pose.gait > 0.0 and nxt.phase > pose.phase
        assert pose.gait == pytest.approx(min(1.0, speed / 0.5))


def test_a_track_walker_hands_over_to_a_walker_where_its_track_ends() -> None:
    apt = default_apartment()
    rng = np.random.default_rng(0)
    then = Walker(apt, (3.0, 2.0), 0.0, 1.7, [OUTFITS[0]], [Action("wait", seconds=4.0), Action("goto", "centre")],
                  rng)
    walker = TrackWalker(lambda t: np.array([1.0 + 0.5 * t, 2.0]), 4.0, 1.7, [OUTFITS[0]], then=then)
    before, _, v_before = walker.state(3.99)
    after, _, _ = walker.state(4.0)
    assert np.allclose(v_before, [0.5, 0.0]) and before.yaw == pytest.approx(0.0)
    assert np.hypot(after.x - before.x, after.y - before.y) < 0.01
    assert after.phase == pytest.approx(before.phase, abs=0.1)  # the gait goes on
    later, _, v_later = walker.state(8.0)
    assert np.linalg.norm(v_later) > 0.5 and (later.x, later.y) != (3.0, 2.0)  # the walker's plan
    still = TrackWalker(lambda t: np.array([1.0, 2.0]), 2.0, 1.7, [OUTFITS[0]], start_yaw=1.0)
    pose, _, v = still.state(1.0)
    assert pose.yaw == 1.0 and pose.gait == 0.0 and not v.any() and still.state(9.0)[0].x == 1.0


def test_a_route_stands_turns_drives_and_turns_round_at_the_end() -> None:
    apt = default_apartment()
    route = Route(apt, [(1.0, 1.3), (5.0, 1.3)], speed=0.5, turn_rate=1.0, start_yaw=np.pi, wait_s=2.0,
                  end_yaw=np.pi)
    assert route(1.0) == pytest.approx((1.0, 1.3, np.pi)) and route.driven(1.0) == 0.0
    assert route.depart_s == pytest.approx(2.0 + np.pi) and route.arrival_s == pytest.approx(2.0 + np.pi + 8.0)
    assert route(route.depart_s + 2.0)[:2] == pytest.approx((2.0, 1.3))
    assert route.driven(route.depart_s + 2.0) == pytest.approx(1.0) and route.reaches(1.0) == pytest.approx(
        route.depart_s + 2.0)
    assert abs(np.angle(np.exp(1j * (route(route.end_s + 1.0)[2] - np.pi)))) < 1e-9
    assert route(100.0)[:2] == pytest.approx((5.0, 1.3)) and route.reaches(4.1) == np.inf


def test_a_follower_keeps_its_gap_on_a_straight_path_and_its_distance_round_a_corner() -> None:
    path = np.array([[0.0, 0.0], [4.0, 0.0], [4.0, 4.0]])
    cum = np.array([0.0, 4.0, 8.0])

    def at(s: float) -> np.ndarray:
        return np.array([np.interp(s, cum, path[:, 0]), np.interp(s, cum, path[:, 1])])

    lead = lambda t: min(2.0 + 0.5 * t, 8.0)  # noqa: E731
    track = follow_route(at, lead, lambda t: at(lead(t)), lambda t: 2.0, 20.0)
    assert np.linalg.norm(track(0.0) - at(0.0)) == 0.0
    assert np.linalg.norm(track(3.0) - at(lead(3.0))) == pytest.approx(2.0, abs=0.1)  # on the straight
    dist = [np.linalg.norm(track(t) - at(lead(t))) for t in np.arange(0.0, 20.0, 0.05)]
    assert min(dist) > 1.3  # the corner cuts the straight-line distance, not below keep_off
    # stopped 2 m of path behind the end, give or take their braking (at most 0.8 m/s^2) when the leader stopped
    assert np.linalg.norm(track(20.0) - at(6.0)) < 0.2 and np.array_equal(track(19.0), track(20.0))
