"""Posture and orientation per track (TU Ilmenau): the evidence, the filters over time, and
what the service publishes."""

from __future__ import annotations

import numpy as np
import pytest

from common.messages.schemas import TrackState
from services.tracker.convert import track_state
from services.tracker.core.cues import posture as pose
from services.tracker.core.robust import RobustParams, RobustTracker
from services.tracker.core.thesis import ThesisTracker, ThesisParams
from services.tracker.core.types import FrameInput, FrameResult


def test_each_posture_is_the_most_likely_for_its_own_height_and_box() -> None:
    for k, (height, aspect) in enumerate([(1.1, 2.7), (0.7, 1.6), (0.3, 0.6)]):
        assert int(np.argmax(pose.posture_evidence(height, aspect))) == k
    assert int(np.argmax(pose.posture_evidence(0.7, None))) == 1  # the height alone when the box is unknown


def test_walking_direction_gives_the_orientation_and_standing_still_gives_nothing() -> None:
    params = pose.PostureParams()
    lik = pose.orientation_evidence(np.array([0.0, 1.2]), params)
    assert lik is not None and int(np.argmax(lik)) == 2  # walking along +y: 90 degrees
    assert pose.orientation_evidence(np.array([0.1, 0.0]), params) is None
    p = pose.update(pose.uniform(8), lik)
    for _ in range(100):  # a long time unobserved: back to unknown
        p = pose.drift(p, 1.0, params.orientation_tau_s, circular=True)
    np.testing.assert_allclose(p, pose.uniform(8), atol=1e-6)


def _frames(trk: RobustTracker, t0: float, t1: float, start: tuple[float, float], velocity: tuple[float, float],
            height: float, aspect: float) -> FrameResult:
    """The person's frames from ``t0`` to ``t1``; the last frame's result."""
    for t in np.arange(t0, t1, 0.1):
        x, y = start[0] + velocity[0] * (t - t0), start[1] + velocity[1] * (t - t0)
        result = trk.step(float(t), FrameInput.of(np.array([[x, y, height]]), aspects=np.array([aspect])))
    return result


def test_a_person_walks_then_sits_down_facing_the_way_they_walked() -> None:
    trk = RobustTracker(RobustParams())
    _frames(trk, 0.0, 3.0, (0.0, 0.0), (0.0, 1.0), 1.1, 2.7)  # walks along +y, standing
    t = trk.tracks[0]
    assert t.posture[0] > 0.9 and int(np.argmax(t.orientation)) == 2 and t.orientation[2] > 0.5
    last = _frames(trk, 3.0, 6.0, (0.0, 3.0), (0.0, 0.0), 0.7, 1.6)  # stops and sits
    t = trk.tracks[0]
    assert t.posture[1] > 0.8
    assert int(np.argmax(t.orientation)) == 2  # still facing the way they came, less sure
    state = track_state(trk.reported(last)[0], True)
    assert np.argmax(state.posture) == 1 and np.isclose(sum(state.orientation), 1.0)


def test_without_boxes_or_with_the_thesis_the_posture_stays_unknown() -> None:
    trk = RobustTracker(RobustParams())
    for t in np.arange(0.0, 1.0, 0.1):
        trk.step(float(t), FrameInput.of(np.array([[0.0, 0.0, 1.1]])))
    np.testing.assert_allclose(trk.tracks[0].posture, pose.uniform(3))
    thesis = ThesisTracker(ThesisParams())
    r = thesis.step(0.0, FrameInput.of(np.array([[0.0, 0.0, 1.1]]), aspects=np.array([2.7])))
    assert r.tracks[0].posture is None
    state = track_state(r.tracks[0], False)
    assert state.posture == [1 / 3] * 3 and state.orientation == [1 / 8] * 8  # uniform: unknown
    assert TrackState.model_fields["posture"].default_factory is not None


def test_the_service_publishes_posture_from_the_boxes(tmp_path) -> None:  # type: ignore[no-untyped-def]
    from tests.helpers.tracker_rig import T0, Rig, config

    rig = Rig(config(tmp_path))
    out = rig.walk(T0, 10, [(0, (2.0, 0.0, 1.0))])
    posture = out[-1].tracks[0].posture
    assert np.isclose(sum(posture), 1.0) and not np.allclose(posture, 1 / 3)


def test_a_detectors_posture_report_decides_where_height_and_box_do_not() -> None:
    assert pose.codes([None, None]) is None
    codes = pose.codes(["sitting", None, "standing"])
    assert codes is not None and codes.tolist() == [1, -1, 0]
    lik = pose.reported_evidences(codes, pose.PostureParams().reported_likelihood)
    np.testing.assert_allclose(lik, [[0.05, 1.0, 0.2], [1, 1, 1], [1.0, 0.5, 0.2]])
    with pytest.raises(ValueError, match="reported_likelihood"):
        pose.PostureParams(reported_likelihood=((1.0, 0.0, 0.0),))
    # halfway between a standing and a seated torso, a square-ish box: the geometry hesitates
    ambiguous = (0.9, 2.1)
    alone, told = RobustTracker(RobustParams()), RobustTracker(RobustParams())
    for t in np.arange(0.0, 2.0, 0.1):
        alone.step(float(t), FrameInput.of(np.array([[0.0, 0.0, ambiguous[0]]]), aspects=np.array([ambiguous[1]])))
        told.step(float(t), FrameInput.of(np.array([[0.0, 0.0, ambiguous[0]]]), aspects=np.array([ambiguous[1]]),
                    postures=np.array([1])))
    assert alone.tracks[0].posture[1] < 0.8 < told.tracks[0].posture[1]
    assert int(np.argmax(told.tracks[0].posture)) == 1


def test_the_service_reads_the_detectors_posture() -> None:
    from common.messages.schemas import Header, LocalizedDetection, LocalizedDetections
    from services.tracker.intake import Arrival

    def det(index: int, posture: str | None) -> LocalizedDetection:
        return LocalizedDetection(index=index, bbox_xyxy=(0, 0, 10, 20), score=0.9, position=np.full(3, index),
                                  cov=np.eye(3), depth_m=2.0, posture=posture)

    msg = LocalizedDetections(header=Header(stamp_ns=1, frame_id="map", seq=0, source="head"),
                              detections=[det(0, "sitting"), det(1, None)])
    arrival = Arrival.of(msg)  # on arrival, the reports become the core's posture codes
    assert arrival.postures is not None and arrival.postures.tolist() == [1, -1]
    assert Arrival.of(msg.model_copy(update={"detections": [det(0, None)]})).postures is None


def test_the_drift_matrix_equals_the_drift() -> None:
    p = np.array([0.1, 0.5, 0.05, 0.05, 0.1, 0.1, 0.05, 0.05])
    np.testing.assert_allclose(p @ pose.transition(8, 0.3, 5.0, circular=True), pose.drift(p, 0.3, 5.0, circular=True))


def test_config_turns_posture_off_and_sets_its_time_constants() -> None:
    from services.tracker.config import TrackerConfig

    assert TrackerConfig().robust.params(None, 500).posture == pose.PostureParams()
    cfg = TrackerConfig.model_validate({"robust": {"posture": {"enabled": False}}})
    assert cfg.robust.params(None, 500).posture is None
    cfg = TrackerConfig.model_validate({"robust": {"posture": {"posture_tau_s": 2.0}}})
    assert cfg.robust.params(None, 500).posture.posture_tau_s == 2.0  # type: ignore[union-attr]
