"""The stature cue (services/tracker/core/cues/stature.py): its log-odds, a track's estimate, and the
robust tracker keeping a taller newcomer off a look-alike's track."""

from __future__ import annotations

import numpy as np
import pytest

from common.messages.schemas import Header
from services.tracker.config import TrackerConfig
from services.tracker.convert import tracks_message
from services.tracker.core.robust import AppearanceModel, RobustParams, RobustTracker
from services.tracker.core.cues.stature import StatureParams, log_odds, observe
from services.tracker.core.types import FrameResult, TrackStatus
from services.tracker.core.types import FrameInput
from tests.helpers.views import camera_looking_along_x, turned_round

P = StatureParams()
COLOUR = AppearanceModel(0.35, 0.85, 0.40)


def test_log_odds_favour_the_same_stature_and_weigh_a_different_one_against_boundedly() -> None:
    est, n = np.array([1.62, 1.80]), np.array([20, 20])
    lo = log_odds(np.array([1.62, 1.80, 1.71, np.nan, 1.30]), est, n, P)
    assert lo is not None and lo.shape == (5, 2)
    assert lo[0, 0] > 1.0 and lo[1, 1] > 1.0  # the same stature: for
    assert lo[1, 0] < -1.5  # 18 cm taller than the track's person: someone else
    assert lo[0, 1] < -1.0  # 18 cm shorter: against too, less (a tall person may sit on a high seat)
    assert lo[0, 1] > lo[1, 0]
    assert abs(lo[4, 0] - lo[4, 1]) < 1e-9 and abs(lo[4, 0]) < 0.5  # far lower than either: a hidden head, says little
    assert lo.min() >= -P.clip  # bounded
    assert np.all(lo[3] == 0.0)  # not measured: no information
    far = log_odds(np.array([2.6]), est, n, P)
    assert far is not None and abs(far[0, 0] - far[0, 1]) < 1e-6  # both improbable: it says as little of either


def test_no_information_until_a_track_has_min_samples() -> None:
    assert log_odds(np.array([1.7]), np.array([1.7]), np.array([P.min_samples - 1]), P) is None
    assert log_odds(np.array([np.nan]), np.array([1.7]), np.array([10]), P) is None
    lo = log_odds(np.array([1.7]), np.array([1.7, 0.0]), np.array([10, 0]), P)
    assert lo is not None and lo[0, 1] == 0.0 and lo[0, 0] > 0


def test_weight_scales_and_zero_turns_it_off() -> None:
    est, n, h = np.array([1.62]), np.array([20]), np.array([1.80])
    one = log_odds(h, est, n, P)
    half = log_odds(h, est, n, StatureParams(weight=0.5))
    off = log_odds(h, est, n, StatureParams(weight=0.0))
    assert one is not None and half is not None and off is not None
    assert half[0, 0] == pytest.approx(0.5 * one[0, 0]) and off[0, 0] == 0.0


def test_observe_learns_a_running_mean_ignores_outliers_once_learnt_and_forgets_slowly() -> None:
    est, n = np.zeros(2), np.zeros(2, np.int64)
    for h in (1.70, 1.72, 1.74):
        est, n = observe(est, n, np.array([0]), np.array([h]), P)
    assert est[0] == pytest.approx(1.72) and n.tolist() == [3, 0]
    est2, n2 = observe(est, n, np.array([0, 1]), np.array([1.72 + 2 * P.gate_m, np.nan]), P)
    assert est2[0] == est[0] and n2.tolist() == [3, 0]  # a raised arm: ignored; NaN: nothing learnt
    assert est2 is not est  # new arrays: a snapshot keeps its own
    for _ in range(500):
        est, n = observe(est, n, np.array([0]), np.array([1.80]), P)
    assert n[0] == P.window and est[0] == pytest.approx(1.80, abs=0.01)  # followed within the gate, at most window


@pytest.mark.parametrize("bad", [dict(noise_m=0.0), dict(outlier_low=0.96), dict(outlier_high=0.0),
                                 dict(min_samples=0), dict(window=2), dict(clip=0.0), dict(weight=-1.0)])
def test_params_are_checked(bad: dict) -> None:
    with pytest.raises(ValueError):
        StatureParams(**bad)


def test_config_section_builds_the_params_and_checks_the_window() -> None:
    config = TrackerConfig.model_validate({"robust": {"stature": {"weight": 0.5}}})
    assert config.robust.params(None, 10).stature == StatureParams(weight=0.5)
    assert TrackerConfig.model_validate({"robust": {"stature": {"enabled": False}}}).robust.params(None, 10).stature is None
    with pytest.raises(ValueError, match="window"):
        TrackerConfig.model_validate({"robust": {"stature": {"window": 2, "min_samples": 3}}})


def _a_then_b(stature: StatureParams | None, mix: float, height: float, gone_s: float, x: float) -> list[int]:
    """Person A (1.62 m) stands at (2, 0) for 3 s and is gone for ``gone_s``; then someone ``height``
    tall, whose look is A's moved by ``mix``, stands at (``x``, 0): the IDs reported after 1 s."""
    rng = np.random.default_rng(0)
    a = rng.normal(size=8)
    a /= np.linalg.norm(a)
    b = a + mix * rng.normal(size=8)
    b /= np.linalg.norm(b)
    trk = RobustTracker(RobustParams(appearance=COLOUR, stature=stature))
    t = 0.0
    for _ in range(30):
        trk.step(t, FrameInput.of(np.array([[2.0, 0.0, 1.0]]), a[None].astype(np.float32), None, np.array([0.9]),
                   statures=np.array([1.62])))
        t += 0.1
    for _ in range(round(gone_s * 10)):
        trk.step(t, FrameInput.of(np.zeros((0, 3)), np.zeros((0, 8), np.float32), None, np.zeros(0), statures=np.zeros(0)))
        t += 0.1
    for _ in range(10):
        r = trk.step(t, FrameInput.of(np.array([[x, 0.0, 1.0]]), b[None].astype(np.float32), None, np.array([0.9]),
                       statures=np.array([height])))
        t += 0.1
    return [v.id for v in trk.reported(r)]


def test_a_taller_newcomer_in_a_look_alikes_place_gets_a_new_id() -> None:
    """B (1.86 m), dressed much like A (about 1.0 apart: as near as appearance alone lets pass),
    steps 0.2 m from where A stands."""
    assert _a_then_b(None, 0.4, 1.86, 0.0, 2.2) == [1]  # position and a look this near: B continues A's track
    assert _a_then_b(P, 0.4, 1.86, 0.0, 2.2) == [2]  # their statures tell them apart: a new ID


def test_the_id_memory_weighs_the_remembered_stature() -> None:
    """A returning person's stature is remembered with their departure: it gives back the ID of
    someone whose look changed a little (other clothes, other light) and keeps it from a taller
    stranger who looks as near."""
    assert _a_then_b(None, 0.25, 1.62, 3.0, 2.5) == [2]  # appearance alone: too far, a new ID
    assert _a_then_b(P, 0.25, 1.62, 3.0, 2.5) == [1]  # the same stature: their own ID back
    assert _a_then_b(None, 0.2, 1.86, 3.0, 2.5) == [1]  # appearance alone: near enough, A's ID
    assert _a_then_b(P, 0.2, 1.86, 3.0, 2.5) == [2]  # 24 cm taller: someone new


def test_a_tracks_stature_is_reported_and_published() -> None:
    """The running mean of a track's measured statures is in its view and its TrackState (None
    where none was measured, or with the cue off)."""
    def last(stature: StatureParams | None, heights: list[float]):  # type: ignore[no-untyped-def]
        trk = RobustTracker(RobustParams(stature=stature))
        for k, h in enumerate(heights):
            r = trk.step(0.1 * k, FrameInput.of(np.array([[2.0, 0.0, 1.0]]), statures=np.array([h])))
        return trk.reported(r)

    views = last(P, [1.70, 1.72, 1.74, 1.72])
    assert len(views) == 1 and views[0].stature == pytest.approx(1.72)
    msg = tracks_message(FrameResult(0.3, False), views, Header(stamp_ns=1, frame_id="map", seq=0, source="head"), "", 0)
    assert msg.tracks[0].stature_m == pytest.approx(1.72)
    assert last(P, [np.nan] * 4)[0].stature is None
    assert last(None, [1.70, 1.72, 1.74, 1.72])[0].stature is None


def test_a_hand_over_between_cameras_takes_the_old_tracks_stature_too() -> None:
    """A person seen by the head camera for 1 s (1.76 m), then out of its view for 3 s, confirmed
    by the back camera: the track that takes their ID takes their stature's measurements too."""
    fov = camera_looking_along_x()
    away = turned_round(fov)
    trk = RobustTracker(RobustParams(max_coast_unseen_s=6.0, max_position_var_unseen=100.0, handover_gate_sq=13.8))
    for k in range(10):
        trk.step(k * 0.1, FrameInput.of(np.array([[3.0, 0.0, 1.0]]), view=fov, camera="head", statures=np.array([1.76])))
    for k in range(10, 40):
        trk.step(k * 0.1, FrameInput.of(np.zeros((0, 3)), view=away, camera="head", statures=np.zeros(0)))
    for k in range(40, 45):
        r = trk.step(k * 0.1, FrameInput.of(np.array([[3.0, 0.3, 1.0]]), view=away, camera="back", statures=np.array([1.78])))
    [view] = [v for v in r.tracks if v.status is TrackStatus.CONFIRMED]
    assert view.id == 1  # handed over
    assert view.stature == pytest.approx((10 * 1.76 + 5 * 1.78) / 15)
    assert [t.stature_n for t in trk.tracks] == [15]


def test_statures_of_the_wrong_length_are_refused_with_a_clear_error() -> None:
    trk = RobustTracker(RobustParams())
    with pytest.raises(ValueError, match="one value per detection"):
        trk.step(0.0, FrameInput.of(np.array([[2.0, 0.0, 1.0], [3.0, 0.0, 1.0]]), statures=np.array([1.7])))
