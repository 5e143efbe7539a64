"""The demo's posture and orientation scores against the simulator's ground truth."""

from __future__ import annotations

import numpy as np

from common.messages.schemas import Header, PeopleGroundTruth, PersonGroundTruth, Tracks, TrackState
from tools.demo.scoring import pose_line, pose_scores


def _track(tid: int, x: float, posture: list[float], orientation: list[float]) -> TrackState:
    return TrackState(id=tid, status="confirmed", position=np.array([x, 0.0, 1.0]), velocity=np.zeros(3),
                      covariance=np.eye(6), last_update_ns=0, hits=5, age_s=1.0, posture=posture,
                      orientation=orientation)


def test_posture_accuracy_and_orientation_error_over_matched_pairs() -> None:
    gt = {1: PeopleGroundTruth(header=Header(stamp_ns=1, seq=1), people=[
        PersonGroundTruth(id=1, position=np.array([0.0, 0.0, 1.0]), posture="standing", facing_rad=np.pi / 2),
        PersonGroundTruth(id=2, position=np.array([3.0, 0.0, 0.7]), posture="sitting", facing_rad=0.0),
        PersonGroundTruth(id=3, position=np.array([9.0, 0.0, 1.0]), posture="standing", facing_rad=0.0),
    ])}
    north = [0.0, 0.05, 0.8, 0.05, 0.0, 0.0, 0.05, 0.05]  # most likely bin 2: 90 degrees
    tracks = [Tracks(header=Header(stamp_ns=1, seq=1), tracks=[
        _track(1, 0.2, [0.9, 0.05, 0.05], north),  # right posture, right orientation
        _track(2, 3.1, [0.8, 0.1, 0.1], north),  # wrong posture, 90 degrees off
        _track(3, 9.0, [1 / 3] * 3, [1 / 8] * 8),  # unknown: left out
    ])]
    scores = pose_scores(gt, tracks)
    assert scores == {"posture_pairs": 2, "posture_accuracy": 0.5, "orientation_pairs": 2,
                      "orientation_error_deg_p50": 45.0}
    assert "50.0 % right" in pose_line(scores)
    assert pose_scores(gt, [])["posture_accuracy"] is None
