"""The attention core: the point feature's joint Jacobian (Ban et al., Eq 12-18), the control
law (Eq 19) with its limits and dead zone, and the choice of the person of interest."""

from __future__ import annotations

import numpy as np
import pytest

from common.geometry.poses import OPTICAL_FROM_BODY, make_pose, pose_inverse, rot_y, rot_z
from services.attention.core import Chooser, HeadGeometry, Person, ServoParams, head_angles, rest_rates, servo
from services.attention.core.servo import joint_jacobian, project

K = np.array([[262.5, 0.0, 159.5], [0.0, 262.5, 119.5], [0.0, 0.0, 1.0]])  # 320x240
CENTRE = (159.5, 119.5)
HEAD = np.array([0.05, 0.0, 1.15])
CAM = np.array([0.06, 0.0, 0.08])


def base_camera(pan: float, tilt: float) -> np.ndarray:
    """(4, 4) T_base_camera of the simulator's head: Rz(pan) Ry(tilt) at HEAD, camera at CAM."""
    return make_pose(rot_z(pan) @ rot_y(tilt), HEAD) @ make_pose(OPTICAL_FROM_BODY, CAM)


def geometry(pan: float, tilt: float) -> HeadGeometry:
    cam_base = pose_inverse(base_camera(pan, tilt))
    cam_head = cam_base @ make_pose(rot_z(pan) @ rot_y(tilt), HEAD)
    return HeadGeometry(cam_base[:3, 2], cam_head[:3, 3], cam_head[:3, 1], cam_head[:3, 3])


def in_camera(point_base: np.ndarray, pan: float, tilt: float) -> np.ndarray:
    c = pose_inverse(base_camera(pan, tilt))
    return c[:3, :3] @ point_base + c[:3, 3]


@pytest.mark.parametrize("pan,tilt,point", [(0.0, 0.1, (2.5, 0.4, 0.9)), (0.7, -0.2, (1.0, 2.0, 1.6)),
                                            (-1.2, 0.4, (0.8, -2.5, 0.3))])
def test_joint_jacobian_matches_finite_differences(pan: float, tilt: float, point: tuple[float, float, float]) -> None:
    p = np.array(point)
    J = joint_jacobian(K, in_camera(p, pan, tilt), geometry(pan, tilt))
    h = 1e-6
    numeric = np.stack([
        (project(K, in_camera(p, pan + h, tilt)) - project(K, in_camera(p, pan - h, tilt))) / (2 * h),
        (project(K, in_camera(p, pan, tilt + h)) - project(K, in_camera(p, pan, tilt - h))) / (2 * h),
    ], axis=1)
    np.testing.assert_allclose(J, numeric, rtol=1e-4, atol=1e-3)


def test_head_angles_read_back() -> None:
    assert head_angles(rot_z(0.4) @ rot_y(-0.25)) == pytest.approx((0.4, -0.25))


def _run(target: callable, pan: float, tilt: float, params: ServoParams, seconds: float = 6.0,
         dt: float = 0.05) -> tuple[list[float], float, float]:
    """Integrate the closed loop on the ideal head; the pixel error after every step."""
    errors = []
    for k in range(int(seconds / dt)):
        t = k * dt
        p, v = target(t)
        c = pose_inverse(base_camera(pan, tilt))
        X, X_dot = c[:3, :3] @ p + c[:3, 3], c[:3, :3] @ v
        res = servo(K, CENTRE, X, X_dot, geometry(pan, tilt), (pan, tilt), params)
        assert abs(res.pan_rate) <= params.max_pan_rate + 1e-9 and abs(res.tilt_rate) <= params.max_tilt_rate + 1e-9
        pan, tilt = pan + res.pan_rate * dt, tilt + res.tilt_rate * dt
        errors.append(float(np.hypot(*(project(K, in_camera(target(t + dt)[0], pan, tilt)) - CENTRE))))
    return errors, pan, tilt


def test_a_still_person_is_centred_within_the_dead_zone() -> None:
    params = ServoParams()
    still = lambda t: (np.array([2.0, 1.2, 1.0]), np.zeros(3))  # noqa: E731
    errors, pan, tilt = _run(still, 0.0, 0.1, params)
    assert errors[0] > 80
    assert max(errors[-20:]) <= params.dead_zone_px + 0.5
    assert pan == pytest.approx(np.arctan2(1.2, 2.0 - HEAD[0]), abs=0.05)


def test_feedforward_follows_a_walking_person() -> None:
    walker = lambda t: (np.array([2.5, -1.5 + 0.8 * t, 1.0]), np.array([0.0, 0.8, 0.0]))  # noqa: E731
    with_ff, _, _ = _run(walker, -0.5, 0.1, ServoParams(), seconds=4.0)
    without, _, _ = _run(walker, -0.5, 0.1, ServoParams(feedforward=0.0), seconds=4.0)
    assert max(with_ff[40:]) <= ServoParams().dead_zone_px + 0.5  # the lag is gone
    assert np.median(without[40:]) > 2 * np.median(with_ff[40:])


def test_velocity_limits_keep_the_direction() -> None:
    params = ServoParams(gain=50.0, max_pan_rate=0.3, max_tilt_rate=0.2, feedforward=0.0)
    X = in_camera(np.array([2.0, 1.5, 0.3]), 0.0, 0.0)
    fast = servo(K, CENTRE, X, np.zeros(3), geometry(0.0, 0.0), (0.0, 0.0), ServoParams(gain=50.0, feedforward=0.0))
    slow = servo(K, CENTRE, X, np.zeros(3), geometry(0.0, 0.0), (0.0, 0.0), params)
    assert slow.saturated and abs(slow.pan_rate) <= 0.3 + 1e-12 and abs(slow.tilt_rate) <= 0.2 + 1e-12
    assert fast.pan_rate * slow.tilt_rate - fast.tilt_rate * slow.pan_rate == pytest.approx(0.0, abs=1e-9)
    assert fast.pan_rate > 0 and fast.tilt_rate > 0  # left and below: pan left, tilt down


def test_dead_zone_and_joint_limits() -> None:
    params = ServoParams(feedforward=0.0, dead_zone_px=10.0)
    X = np.array([0.01, 0.0, 2.0])  # 1.3 px right of the centre
    res = servo(K, CENTRE, X, np.zeros(3), geometry(0.0, 0.0), (0.0, 0.0), params)
    assert (res.pan_rate, res.tilt_rate) == (0.0, 0.0)
    left = in_camera(np.array([1.0, 2.0, 1.2]), 0.0, 0.0)
    res = servo(K, CENTRE, left, np.zeros(3), geometry(0.0, 0.0), (params.pan_limits[1], 0.0), params)
    assert res.at_limit and res.pan_rate == 0.0


def test_a_person_behind_the_camera_turns_the_pan_towards_them() -> None:
    params = ServoParams()
    behind_left = in_camera(np.array([-1.0, 0.8, 1.0]), 0.0, 0.1)
    res = servo(K, CENTRE, behind_left, np.zeros(3), geometry(0.0, 0.1), (0.0, 0.1), params)
    assert res.fallback and res.pan_rate == pytest.approx(params.max_pan_rate) and res.tilt_rate == 0.0
    behind_right = in_camera(np.array([-1.0, -0.8, 1.0]), 0.0, 0.1)
    assert servo(K, CENTRE, behind_right, np.zeros(3), geometry(0.0, 0.1), (0.0, 0.1), params).pan_rate < 0


def test_rest_rates_return_to_the_rest_pose() -> None:
    params = ServoParams()
    pan, tilt = 1.0, -0.3
    for _ in range(200):
        dp, dt_, at_rest = rest_rates((pan, tilt), params)
        pan, tilt = pan + 0.05 * dp, tilt + 0.05 * dt_
    assert at_rest and (pan, tilt) == pytest.approx((params.rest_pan, params.rest_tilt), abs=params.rest_tolerance)


def _person(i: int, x: float, y: float = 0.0, confirmed: bool = True) -> Person:
    return Person(i, np.array([x, y, 1.0]), np.zeros(3), confirmed)


def test_chooser_id_hold_then_rest_and_the_id_coming_back() -> None:
    c = Chooser(hold_s=2.0)
    origin = np.zeros(3)
    assert c.decide([_person(1, 2.0)], origin, 0.0).phase == "rest"  # 'none' at start
    c.request("id", 4)
    d = c.decide([_person(4, 3.0), _person(1, 2.0)], origin, 0.1)
    assert d.phase == "track" and d.target is not None and d.target.id == 4
    assert c.decide([_person(1, 2.0)], origin, 0.2).phase == "hold"
    assert c.decide([_person(1, 2.0)], origin, 2.1).phase == "hold"
    assert c.decide([_person(1, 2.0)], origin, 2.3).phase == "rest"  # not the nearest: the ID is asked for
    assert c.decide([_person(4, 3.0)], origin, 9.0).phase == "track"  # the tracker gave the ID back
    c.request("none")
    assert c.decide([_person(4, 3.0)], origin, 9.1).phase == "rest"


def test_chooser_lock_takes_the_nearest_then_waits_for_that_id() -> None:
    c = Chooser(hold_s=1.0)
    c.request("lock")
    origin = np.zeros(3)
    assert c.decide([], origin, 0.0).phase == "rest"  # no one yet: wait at rest, still locking
    assert c.mode == "lock"
    assert c.decide([_person(5, 3.0, confirmed=False)], origin, 0.1).phase == "rest"  # tentative: not chosen
    d = c.decide([_person(5, 3.0), _person(2, 2.0)], origin, 0.2)
    assert d.phase == "track" and d.target_id == 2 and (c.mode, c.requested_id) == ("id", 2)
    assert c.decide([_person(5, 3.0), _person(2, 0.5)], origin, 0.3).target_id == 2
    assert c.decide([_person(5, 1.0)], origin, 0.4).phase == "hold"  # 2 lost
    # unlike 'nearest', a nearer person does not take over once the hold is over
    assert c.decide([_person(5, 1.0), _person(7, 2.0)], origin, 2.0).phase == "rest"
    d = c.decide([_person(5, 1.0), _person(2, 4.0)], origin, 5.0)  # the tracker gave the ID back
    assert d.phase == "track" and d.target_id == 2


def test_chooser_nearest_keeps_its_person_until_another_is_clearly_nearer() -> None:
    c = Chooser(hold_s=1.0, switch_margin_m=1.0)
    c.request("nearest")
    origin = np.zeros(3)
    assert c.decide([_person(1, 3.0, confirmed=False)], origin, 0.0).phase == "rest"  # tentative: not chosen
    assert c.decide([_person(1, 3.0), _person(2, 4.0)], origin, 0.1).target_id == 1
    assert c.decide([_person(1, 3.0), _person(2, 2.5)], origin, 0.2).target_id == 1  # within the margin
    assert c.decide([_person(1, 3.0), _person(2, 1.5)], origin, 0.3).target_id == 2
    assert c.decide([_person(1, 3.0)], origin, 0.4).phase == "hold"  # 2 lost: hold first
    d = c.decide([_person(1, 3.0)], origin, 1.5)
    assert d.phase == "track" and d.target_id == 1  # after the hold, the nearest again
