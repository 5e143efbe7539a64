"""Bad inputs to the tracker service, through the in-memory transport: each is counted,
logged at most once a second, and survived (the node goes on tracking afterwards).

Unusable covariances, descriptors of another model or dimension, clock jumps (a replay
that loops, stamps that leap ahead) and an unknown profile name.
"""

from __future__ import annotations

import logging
import typing
from pathlib import Path

import numpy as np
import pytest
from pydantic import ValidationError

from common.runtime.join import Joiner
from common.messages.schemas import Embeddings, Header, LocalizedDetection, LocalizedDetections, ModelCard, Tracks
from services.tracker.config import PROFILES, TrackerConfig
from services.tracker.reorder import ClockJumps, ReorderBuffer
from tests.helpers.tracker_rig import DIM, KEYS, PERIOD_NS, S, T0, Person, Rig, config, ids_by_x

LOGGER = "services.tracker.service"


def warnings(caplog: pytest.LogCaptureFixture, text: str) -> list[str]:
    return [r.getMessage() for r in caplog.records if r.name == LOGGER and text in r.getMessage()]


A: Person = (0, (2.0, 0.0, 1.0))
B: Person = (1, (5.0, 0.0, 1.0))


# ------------------------------------------------------------------- covariances
@pytest.mark.parametrize("profile", PROFILES)
def test_unusable_covariances_are_counted_logged_once_a_second_and_replaced(
        tmp_path: Path, profile: str, caplog: pytest.LogCaptureFixture) -> None:
    caplog.set_level(logging.WARNING, logger=LOGGER)
    # the thesis profile only uses covariances when told to; then an unusable one would be its R
    rig = Rig(config(tmp_path, profile, use_detection_covariance=True))
    negative = -np.eye(3) * 0.01
    asymmetric = np.array([[0.01, 0.005, 0.0], [0.0, 0.01, 0.0], [0.0, 0.0, 0.01]])
    out: list[Tracks] = []
    for k in range(10):
        out += rig.step(T0 + k * PERIOD_NS, k, [A], cov=negative if k % 2 else asymmetric)
    assert rig.extra["bad_covariances"] == 10
    assert "update_errors" not in rig.extra
    assert len(warnings(caplog, "not symmetric positive definite")) == 1  # 10 in 1 s: one line
    assert [ids_by_x(m) for m in out[-3:]] == [{2: 1}] * 3
    np.testing.assert_allclose(out[-1].tracks[0].position[:2], [2.0, 0.0], atol=0.05)
    assert np.all(np.linalg.eigvalsh(out[-1].tracks[0].covariance[:3, :3]) > 0)  # as R they would make it negative
    rig.clock.now += 1.0
    out = rig.walk(T0 + 10 * PERIOD_NS, 3, [A], seq0=10)  # good covariances again
    assert rig.extra["bad_covariances"] == 10 and ids_by_x(out[-1]) == {2: 1}
    rig.step(T0 + 13 * PERIOD_NS, 13, [A], cov=negative)
    [again] = warnings(caplog, "not symmetric positive definite")[1:]
    assert "(9 more since the last report)" in again


def test_a_non_finite_covariance_is_refused_at_decode_and_tracking_goes_on(tmp_path: Path) -> None:
    rig = Rig(config(tmp_path))
    rig.walk(T0, 5, [A])
    header = Header(stamp_ns=T0 + 5 * PERIOD_NS, frame_id="map", seq=5, source="head")
    nan = np.full((3, 3), np.nan)
    det = LocalizedDetection.model_construct(index=0, bbox_xyxy=(0, 0, 10, 10), score=0.9, position=np.array(A[1]),
                                             cov=nan, depth_m=2.0, valid_pixels=0)
    rig.loc_pub.put(LocalizedDetections.model_construct(header=header, camera_frame="", detections=[det], rejected={}))
    rig.clock.now += 0.1
    assert rig.service.poll(rig.clock()) == []
    assert rig.service.loc_sub.stats.invalid == 1  # counted and logged by the subscription, once a second
    out = rig.walk(T0 + 6 * PERIOD_NS, 5, [A], seq0=6)
    assert ids_by_x(out[-1]) == {2: 1} and out[-1].appearance_available


# ------------------------------------------------------------------- descriptors
def test_descriptors_of_another_model_are_dropped_and_logged_naming_both(
        tmp_path: Path, caplog: pytest.LogCaptureFixture) -> None:
    caplog.set_level(logging.WARNING, logger=LOGGER)
    rig = Rig(config(tmp_path, embedding_model="colour"))
    trinet = ModelCard(name="trinet", dim=DIM)
    out: list[Tracks] = []
    for k in range(5):
        out += rig.step(T0 + k * PERIOD_NS, k, [A], card=trinet)
    assert len(out) == 5 and not any(m.appearance_available for m in out)  # at once, position-only
    assert rig.extra["dropped_wrong_model"] == 5
    [line] = warnings(caplog, "embedding model 'trinet'")
    assert "'colour'" in line
    out = rig.walk(T0 + 5 * PERIOD_NS, 3, [A], seq0=5)
    assert out[-1].appearance_available and [t.id for t in out[-1].tracks] == [1]


@pytest.mark.parametrize("profile", PROFILES)
def test_descriptors_of_another_dimension_run_the_frame_position_only(
        tmp_path: Path, profile: str, caplog: pytest.LogCaptureFixture) -> None:
    caplog.set_level(logging.WARNING, logger=LOGGER)
    rig = Rig(config(tmp_path, profile))
    rig.walk(T0, 5, [A])
    wide = ModelCard(name="colour", dim=2 * DIM, normalized=True)
    out = rig.step(T0 + 5 * PERIOD_NS, 5, [A], card=wide)
    out += rig.step(T0 + 6 * PERIOD_NS, 6, [A], card=wide)
    assert len(out) == 2 and not any(m.appearance_available for m in out)  # not waiting for the join
    assert rig.extra["dropped_wrong_dimension"] == 2 and "dropped_wrong_model" not in rig.extra
    [line] = warnings(caplog, "dimension")
    assert "'colour'" in line and f"dimension {2 * DIM}" in line and f"dimension {DIM}" in line
    out = rig.walk(T0 + 7 * PERIOD_NS, 3, [A], seq0=7)
    assert out[-1].appearance_available and [t.id for t in out[-1].tracks] == [1]
    assert "update_errors" not in rig.extra


@pytest.mark.parametrize("profile", PROFILES)
def test_descriptors_of_another_dimension_than_the_id_memory_are_refused(
        tmp_path: Path, profile: str, caplog: pytest.LogCaptureFixture) -> None:
    caplog.set_level(logging.WARNING, logger=LOGGER)
    first = Rig(config(tmp_path, profile))
    first.walk(T0, 8, [A])
    first.service.close()  # writes the live track's 16-D gallery to the memory file
    rig = Rig(config(tmp_path, profile))  # restarted, with an embedder that now gives 32-D descriptors
    wide = ModelCard(name="colour", dim=2 * DIM, normalized=True)
    out: list[Tracks] = []
    for k in range(8):
        out += rig.step(T0 + (100 + k) * PERIOD_NS, 100 + k, [A], card=wide)
    assert len(out) == 8 and not any(m.appearance_available for m in out)
    assert rig.extra["dropped_wrong_dimension"] == 8 and "update_errors" not in rig.extra
    [line] = warnings(caplog, "dimension")
    assert str(tmp_path / "memory.npz") in line and f"dimension {2 * DIM}" in line and f"dimension {DIM}" in line
    assert [t.id for t in out[-1].tracks] == [2]  # position-only: a new ID, the memory neither read nor broken
    out = rig.walk(T0 + 200 * PERIOD_NS, 4, [A], seq0=200)  # 16-D descriptors again
    assert out[-1].appearance_available and len(out[-1].tracks) == 1


def test_vectors_that_contradict_their_model_card_are_refused_at_decode(tmp_path: Path) -> None:
    rig = Rig(config(tmp_path))
    rig.walk(T0, 5, [A])
    header = Header(stamp_ns=T0 + 5 * PERIOD_NS, frame_id="map", seq=5, source="head")
    rig.send(T0 + 5 * PERIOD_NS, 5, [A], embeddings=False)
    card = ModelCard(name="colour", dim=DIM, normalized=True)
    rig.emb_pub.put(Embeddings.model_construct(header=header, model=card, indices=np.zeros(1, np.int32),
                                               vectors=np.zeros((1, DIM // 2), np.float32)))
    assert rig.service.poll(rig.clock()) == []  # the frame waits for embeddings that will not come
    assert rig.service.emb_sub.stats.invalid == 1
    rig.clock.now += 0.2
    [msg] = rig.service.poll(rig.clock())
    assert not msg.appearance_available and rig.extra["position_only_timeout"] == 1
    out = rig.walk(T0 + 6 * PERIOD_NS, 3, [A], seq0=6)
    assert out[-1].appearance_available and [t.id for t in out[-1].tracks] == [1]


# ------------------------------------------------------------------- clock jumps
@pytest.mark.parametrize("profile", PROFILES)
def test_a_looping_replay_restarts_the_clock_and_people_keep_their_ids(
        tmp_path: Path, profile: str, caplog: pytest.LogCaptureFixture) -> None:
    caplog.set_level(logging.WARNING, logger=LOGGER)
    rig = Rig(config(tmp_path, profile))
    frames = 60  # 6 s: longer than clock_jump_s; fewer keys than the joiner remembers
    out = rig.walk(T0, frames, [A, B])
    before = ids_by_x(out[-1])
    assert before == {2: 1, 5: 2}
    for loop in (1, 2):  # the same stamps, seqs and people again, twice
        out = rig.walk(T0, frames, [A, B])
        assert len(out) == frames  # every frame tracked: none too old, none a duplicate
        assert ids_by_x(out[-1]) == before
        assert rig.extra["clock_jumps"] == loop
    assert rig.extra["ids_recovered"] == 4
    for name in ("dropped_too_old", "dropped_duplicate", "dropped_late_embeddings", "update_errors"):
        assert name not in rig.extra, name
    assert rig.service.buffer.dropped_old == 0
    jumps = warnings(caplog, "went back")
    assert len(jumps) == 2 and "5.9 s" in jumps[0] and "[1, 2]" in jumps[0]
    state = rig.service.transport.query(KEYS.track_query() + "?id=1")[0][1]
    assert isinstance(state, Tracks) and state.tracks[0].status == "confirmed"


@pytest.mark.parametrize("profile", PROFILES)
def test_a_clock_jump_ends_tracks_in_the_query_table_and_keeps_ids_in_the_memory_file(
        tmp_path: Path, profile: str) -> None:
    rig = Rig(config(tmp_path, profile, memory_save_period_s=3600.0))
    rig.walk(T0, 20, [A])
    assert "memory_saves" not in rig.extra
    rig.step(T0 - 60 * S, 0, [])  # a sensor clock reset to a minute earlier, nobody in view
    assert rig.extra["clock_jumps"] == 1 and rig.extra["memory_saves"] == 1  # the ended track's gallery, at once
    state = rig.service.transport.query(KEYS.track_query() + "?id=1")[0][1]
    assert isinstance(state, Tracks) and state.tracks[0].status == "deleted"
    rig.service.close()
    rig2 = Rig(config(tmp_path, profile))  # a restarted tracker knows the person too
    out = rig2.walk(T0 + 1000 * S, 5, [A])
    assert [t.id for t in out[-1].tracks] == [1]


def test_stamps_a_little_back_are_still_too_old_not_a_clock_jump(tmp_path: Path) -> None:
    rig = Rig(config(tmp_path))
    rig.walk(T0, 30, [A])
    out = rig.step(T0 + 30 * PERIOD_NS - 2 * S, 999, [A])  # 2 s back: beyond the window, within clock_jump_s
    assert out == [] and rig.extra["dropped_too_old"] == 1 and "clock_jumps" not in rig.extra
    out = rig.walk(T0 + 30 * PERIOD_NS, 3, [A], seq0=30)
    assert [t.id for t in out[-1].tracks] == [1]


@pytest.mark.parametrize("profile", PROFILES)
@pytest.mark.parametrize("seen_at_the_leap", [False, True])
def test_stamps_that_leap_minutes_ahead_end_tracks_and_the_returning_person_gets_their_id(
        tmp_path: Path, profile: str, seen_at_the_leap: bool) -> None:
    rig = Rig(config(tmp_path, profile))
    rig.walk(T0, 20, [A, B])
    leap = T0 + 600 * S  # ten minutes later
    if not seen_at_the_leap:  # nobody in view for a while: every track ends, its gallery remembered
        [msg] = rig.step(leap, 20, [])
        assert msg.tracks == [] and rig.service.tracker.tracks == []
        assert len(rig.service.tracker.memory) == 2
    out = rig.walk(leap + PERIOD_NS, 10, [A], seq0=21)  # person A comes back alone
    assert ids_by_x(out[-1]) == {2: 1}
    assert "clock_jumps" not in rig.extra and "update_errors" not in rig.extra
    out = rig.walk(leap + 11 * PERIOD_NS, 10, [A, B], seq0=31)  # and then B
    assert ids_by_x(out[-1]) == {2: 1, 5: 2}


def test_clock_jumps_are_per_source_and_forward_leaps_are_none() -> None:
    jumps = ClockJumps(jump_ns=5 * S)
    assert jumps.check("left", 100 * S) == 0
    assert jumps.check("right", 10 * S) == 0  # another camera with another clock: not a jump
    assert jumps.check("left", 700 * S) == 0  # ten minutes ahead: taken as it comes
    assert jumps.check("left", 697 * S) == 0  # a little back: the reorder buffer's business
    assert jumps.check("left", 100 * S) == 600 * S
    assert jumps.newest == {"left": 100 * S}  # everything starts over
    assert jumps.check("right", 10 * S) == 0


def test_reorder_buffer_reset_forgets_inputs_but_keeps_counts() -> None:
    applied: list[int] = []
    buf: ReorderBuffer[int, list[int], int] = ReorderBuffer(
        apply=lambda x: applied.append(x) or x, snapshot=lambda: list(applied),
        restore=lambda s: applied.__setitem__(slice(None), s), window_ns=500)
    for t in (1000, 2000, 3000):
        buf.push((t, "head", t), t)
    assert buf.push((10, "head", 10), 10) == [] and buf.dropped_old == 1
    applied.clear()
    buf.reset()
    assert buf.newest_ns is None and buf.latest() is None
    assert buf.push((10, "head", 10), 10) == [10] and buf.push((5, "head", 5), 5) == [5, 10]  # a rewind to the reset
    assert applied == [5, 10] and buf.dropped_old == 1


def test_joiner_forget_released_lets_keys_come_again() -> None:
    join: Joiner[str] = Joiner(("a", "b"), wait_s=0.1, buffer=8, max_waiting=8, ordered=True)
    key = (T0, "head", 0)
    join.add("a", key, "x", 0.0)
    join.add("b", key, "y", 0.0)
    assert len(join.poll(0.0)[0]) == 1
    assert join.add("a", key, "x", 1.0)[0].reason == "duplicate"
    join.forget_released()
    assert join.add("a", key, "x", 2.0) == [] and join.newest_ns == T0


# ------------------------------------------------------------------- profiles
def test_unknown_profile_names_the_profiles() -> None:
    assert typing.get_args(TrackerConfig.model_fields["profile"].annotation) == PROFILES
    with pytest.raises(ValidationError, match="'robust' or 'thesis'"):
        TrackerConfig(profile="fast")  # type: ignore[arg-type]


def test_clock_jump_must_exceed_the_reorder_window() -> None:
    with pytest.raises(ValidationError, match=r"clock_jump_s \(0.4\) must exceed reorder_window_s \(0.5\)"):
        TrackerConfig(clock_jump_s=0.4)
    assert TrackerConfig(reorder_window_s=0.2, clock_jump_s=0.4).clock_jump_s == 0.4


def test_tracker_command_refuses_an_unknown_profile(tmp_path: Path, capsys: pytest.CaptureFixture[str],
                                                    monkeypatch: pytest.MonkeyPatch) -> None:
    from perception.cli import main

    bad = tmp_path / "tracker.yaml"
    bad.write_text("tracker:\n  profile: fast\n")
    assert main(["tracker", "--service-config", str(bad), "--connect", "tcp/127.0.0.1:1"]) == 2
    err = capsys.readouterr().err
    assert "profile" in err and "'robust' or 'thesis'" in err and "'fast'" in err and str(bad) in err
    monkeypatch.setenv("PERCEPTION_TRACKER__PROFILE", "fast")
    assert main(["tracker", "--connect", "tcp/127.0.0.1:1"]) == 2
    assert "'robust' or 'thesis'" in capsys.readouterr().err


def test_track_command_refuses_an_unknown_profile(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    from perception.cli import main

    dets = tmp_path / "dets.csv"
    dets.write_text("frame,stamp,x,y,z,score\n0,0.0,1.0,0.0,1.0,0.9\n")
    with pytest.raises(SystemExit) as exit_info:
        main(["track", "--detections", str(dets), "--output", str(tmp_path / "t.csv"), "--profile", "bogus"])
    assert exit_info.value.code == 2
    assert "'bogus'" in (err := capsys.readouterr().err) and "'robust'" in err and "'thesis'" in err
    bad = tmp_path / "tracker.yaml"
    bad.write_text("profile: fast\n")
    assert main(["track", "--detections", str(dets), "--output", str(tmp_path / "t.csv"), "--service-config", str(bad)]) == 2
    assert "'robust' or 'thesis'" in capsys.readouterr().err and not (tmp_path / "t.csv").exists()
