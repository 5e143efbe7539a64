"""The tracker with a 2-D laser beside the camera: the laser's view (ScanView), IsPerson per
detector (legs alone never confirm a person), and a person kept with their ID while only the laser
sees them (issue: people all around the robot)."""

from __future__ import annotations

import numpy as np
import pytest

from services.tracker.config import TrackerConfig
from services.tracker.core.robust import RobustParams, RobustTracker, ScoreModel
from services.tracker.core.types import FrameInput, TrackStatus
from services.tracker.core.view import FieldOfView, ScanView, Views
from tests.helpers.views import camera_looking_along_x

#: the shipped score model of the laser's people
LASER = TrackerConfig().score_models()["laser-legs"]


def head_camera() -> FieldOfView:
    """The robot's head camera, 1 m above the floor, looking along +x."""
    fov = camera_looking_along_x()
    pose = fov.camera_to_frame.copy()
    pose[2, 3] = 1.0
    return FieldOfView(pose, fov.K, fov.width, fov.height, fov.max_range_m)


def sweep(ranges: np.ndarray | None = None, x: float = 0.0, y: float = 0.0, yaw: float = 0.0,
          fov_deg: float = 360.0, max_range_m: float = 8.0) -> ScanView:
    n = 720 if ranges is None else len(ranges)
    pose = np.eye(4)
    pose[:2, :2] = [[np.cos(yaw), -np.sin(yaw)], [np.sin(yaw), np.cos(yaw)]]
    pose[:2, 3] = x, y
    inc = np.radians(fov_deg) / n
    r = np.full(n, np.inf) if ranges is None else ranges
    return ScanView(pose, -np.radians(fov_deg) / 2, inc, r, max_range_m)


def test_the_laser_sees_what_no_nearer_return_hides_within_its_range_and_sweep() -> None:
    r = np.full(720, np.inf)
    r[340:381] = 2.0  # something 2 m ahead, 0.7 m wide (beams 340-380 of 720 over 360 degrees)
    view = sweep(r)
    pts = np.array([[1.5, 0.0, 0.9], [2.1, 0.0, 0.9], [4.0, 0.0, 0.9], [0.0, 4.0, 0.9], [-3.0, -1.0, 0.9],
                    [9.0, 0.0, 0.9]])
    # in front of the return, at it (the legs it measured), hidden behind it, free, behind the robot, too far
    assert view.contains(pts).tolist() == [True, True, False, True, True, False]
    # a 270-degree scanner turned to face -x: what is behind it (along +x) is outside its sweep
    back = sweep(np.full(540, np.inf), yaw=np.pi, fov_deg=270.0)
    assert back.contains(np.array([[-3.0, 0.0, 0.9], [3.0, 0.0, 0.9], [0.0, 3.0, 0.9]])).tolist() == [True, False, True]
    with pytest.raises(ValueError):
        ScanView(np.eye(4), 0.0, 0.0, np.ones(4), 8.0)
    # it sees that nobody is there only where every beam across a body went on past: not at the return
    assert view.sees_absence(pts).tolist() == [True, False, False, True, True, False]
    assert view.absence_differs and not Views((head_camera(),)).absence_differs


def test_a_person_by_a_wall_the_laser_cannot_tell_apart_is_kept_while_one_in_free_space_is_missed() -> None:
    """A confirmed track stops being detected: where the laser's beams end at it (a wall or a chair
    where they stood) the miss says nothing and the track is kept on the limits out of view (the
    several-cameras preset's wider ones here); where the beams go on through (nobody there) it is a
    miss: its prediction spreads past max_position_var and it ends."""
    r = np.full(720, np.inf)
    r[350:371] = 3.1  # a wall just behind the place of the person at (3, 0)
    by_wall, free = sweep(r), sweep()
    kept = {}
    for name, view in (("by the wall", by_wall), ("free", free)):
        trk = RobustTracker(RobustParams(max_coast_unseen_s=10.0, max_position_var_unseen=25.0))
        for k in range(10):
            trk.step(*camera_frame(k * 0.1, [(3.0, 0.0)]))
        for k in range(10, 25):  # 1.5 s of laser scans that find nobody
            trk.step(*laser_frame(k * 0.1, [], view=view))
        kept[name] = [v.id for v in trk.tracks]
    assert kept == {"by the wall": [1], "free": []}


def laser_frame(t: float, people: list[tuple[float, float]], score: float = 0.95, view: ScanView | None = None
                ) -> tuple[float, FrameInput]:
    pos = np.array([[x, y, 0.9] for x, y in people]).reshape(-1, 3)
    return t, FrameInput.of(pos, None, None, np.full(len(pos), score), view=view if view is not None else sweep(),
                            score_model=LASER, camera="base_laser")._replace(detector="laser-legs")


def camera_frame(t: float, people: list[tuple[float, float]]) -> tuple[float, FrameInput]:
    pos = np.array([[x, y, 1.0] for x, y in people]).reshape(-1, 3)
    return t, FrameInput.of(pos, None, None, np.full(len(pos), 0.9), view=head_camera(),
                            camera="head")._replace(detector="depth")


def confirmed(trk: RobustTracker, result) -> list[int]:  # type: ignore[no-untyped-def]
    return [v.id for v in trk.reported(result) if v.status is not TrackStatus.TENTATIVE]


def test_legs_alone_never_confirm_a_person_however_long_and_sure() -> None:
    trk = RobustTracker(RobustParams())
    for k in range(200):  # 20 s of a chair's legs at 10 Hz, every scan sure it is a leg
        r = trk.step(*laser_frame(k * 0.1, [(2.0, 1.0)], score=0.99))
        assert confirmed(trk, r) == []
    [row] = trk.tracks
    assert row.status is TrackStatus.TENTATIVE and row.beliefs == {"laser-legs": pytest.approx(0.7)}
    assert row.is_person == pytest.approx(0.7) and row.is_person < RobustParams().confirm_is_person


def test_a_person_the_laser_followed_is_confirmed_at_the_cameras_first_sight() -> None:
    trk = RobustTracker(RobustParams())
    for k in range(10):
        trk.step(*laser_frame(k * 0.1, [(3.0, 0.0)]))
    r = trk.step(*camera_frame(1.0, [(3.0, 0.0)]))
    assert confirmed(trk, r) == [1]  # the laser's belief (0.7) and the camera's first (0.7): 0.84
    [row] = trk.tracks
    assert set(row.beliefs) == {"laser-legs", "depth"} and row.is_person > 0.8
    # a camera alone needs its three confident hits
    alone = RobustTracker(RobustParams())
    assert confirmed(alone, alone.step(*camera_frame(1.0, [(3.0, 0.0)]))) == []


def test_each_detectors_belief_drifts_with_its_own_time_constant() -> None:
    slow = ScoreModel(0.5, 0.2, max_is_person=0.7, is_person_tau_s=100.0)
    trk = RobustTracker(RobustParams(is_person_tau_s=0.5))
    t, f = laser_frame(0.0, [(3.0, 0.0)])
    trk.step(t, f._replace(score_model=slow))
    trk.step(*camera_frame(0.05, [(3.0, 0.0)]))
    before = trk.tracks[0].beliefs
    trk.step(0.2, FrameInput.of(np.zeros((0, 3))))
    after = trk.tracks[0].beliefs
    assert after["laser-legs"] == pytest.approx(0.5 + (before["laser-legs"] - 0.5) * np.exp(-0.15 / 100.0))
    assert after["depth"] == pytest.approx(0.5 + (before["depth"] - 0.5) * np.exp(-0.15 / 0.5))


def _round_the_robot(with_laser: bool) -> tuple[set[int], int, float]:
    """A person seen by the head camera (looking along +x) walks round the robot on a 2.5 m circle
    at 0.5 m/s: 31 s a lap, most of it outside the camera's view; the laser (360 degrees) sees
    them all the way at 10 Hz. The IDs ever reported, the frames they were reported in, and the share
    of the camera's frames behind the robot after which they were reported as confirmed (the
    camera's frame, which cannot see them, does not make them coast between two scans)."""
    trk = RobustTracker(RobustParams())
    fov = head_camera()
    ids: set[int] = set()
    reported, behind, confirmed_behind = 0, 0, 0
    for k in range(int(40 / 0.1)):
        t = k * 0.1
        a = 0.2 * t  # rad: 0.5 m/s on 2.5 m
        p = [(2.5 * np.cos(a), 2.5 * np.sin(a))]
        inside = bool(fov.contains(np.array([[p[0][0], p[0][1], 1.0]]), 0.1)[0])
        frames = [camera_frame(t, p if inside else [])]
        if with_laser:
            frames.append(laser_frame(t + 0.03, p))
        for when, frame in frames:
            if with_laser:
                frame = frame._replace(view=Views((fov, sweep())))
            r = trk.step(when, frame)
            now = confirmed(trk, r)
            ids |= set(now)
            if frame.camera == "head" and p[0][0] < -1.0:
                behind += 1
                confirmed_behind += any(v.status is TrackStatus.CONFIRMED for v in trk.reported(r))
        reported += bool(now)
    return ids, reported, confirmed_behind / max(behind, 1)


def test_a_person_walking_round_the_robot_keeps_their_id_while_only_the_laser_sees_them() -> None:
    ids, reported, confirmed_behind = _round_the_robot(with_laser=True)
    assert ids == {1}
    assert reported >= 0.95 * 400  # reported all the way round, behind the robot too
    assert confirmed_behind == 1.0  # and confirmed there, after the camera's frames too
    ids_alone, reported_alone, _ = _round_the_robot(with_laser=False)
    assert len(ids_alone) >= 2 and reported_alone < 0.5 * 400  # the camera alone: lost behind, a new ID back
