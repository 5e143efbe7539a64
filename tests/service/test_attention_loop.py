"""The attention loop: the ground truth republished as tracks (a perfect tracker), the closed
loop on it centring person 1 better than a head left at rest, and the loop over the whole of
people-following, on the ground truth and on the tracker's tracks."""

from __future__ import annotations

import numpy as np

from common.messages.keys import RELIABLE, Keys
from common.transport.memory import MemoryBus
from common.messages.schemas import Header, PeopleGroundTruth, PersonGroundTruth, Tracks
from services.attention.config import AttentionConfig
from tools.demo.attention import TruthTracks
from tools.demo.inprocess import run_chain


def test_truth_tracks_republish_every_person_with_their_true_id_and_motion() -> None:
    bus, keys = MemoryBus(), Keys(robot="att")
    truth = TruthTracks(bus.transport(), keys)
    client = bus.transport()
    out = client.subscribe(truth.key, Tracks, RELIABLE)
    client.publisher(keys.groundtruth(), PeopleGroundTruth, RELIABLE).put(PeopleGroundTruth(
        header=Header(stamp_ns=5, seq=3, frame_id="map"), people=[
            PersonGroundTruth(id=1, position=np.array([1.0, 2.0, 1.1]), velocity=np.array([0.5, 0.0, 0.0])),
            PersonGroundTruth(id=4, position=np.array([3.0, 0.0, 1.1]), counted=False)]))
    truth.poll(0.0)
    got = out.try_recv()
    assert got is not None and out.try_recv() is None
    msg = got.msg
    assert (msg.header.stamp_ns, msg.header.seq, msg.header.frame_id) == (5, 3, "map")
    assert [(t.id, t.status) for t in msg.tracks] == [(1, "confirmed"), (4, "confirmed")]  # seen or not
    assert msg.tracks[0].position.tolist() == [1.0, 2.0, 1.1] and msg.tracks[0].velocity.tolist() == [0.5, 0.0, 0.0]
    truth.close()


def test_the_loop_on_perfect_tracks_centres_person_1_better_than_the_rest_pose() -> None:
    followed = run_chain("people-following", duration_s=6.0, attention=AttentionConfig(target="1"),
                         attention_truth=True).attention
    resting = run_chain("people-following", duration_s=6.0, attention=AttentionConfig(target="none"),
                        attention_truth=True).attention
    assert followed is not None and resting is not None
    assert followed["target_visible_fraction"] == 1.0
    assert followed["center_error_px_p50"] <= 20.0  # the rest pose leaves them about 30 px off
    assert followed["center_error_px_p50"] < resting["center_error_px_p50"] - 5.0


def test_the_loop_keeps_person_1_in_view_on_people_following() -> None:
    # the whole scenario, 39 s: on the ground truth the targets hold (0.959, 13.7 px when
    # written); on the tracker's tracks (target lock) the head follows the tracker's ID, which is
    # not always person 1, so this is a floor under the figure measured (0.915, 26.6 px), not the
    # issue's 95 % (not met reliably: README, the attention node)
    truth = run_chain("people-following", duration_s=39.0, attention=AttentionConfig(target="1"),
                      attention_truth=True).attention
    assert truth is not None and truth["frames"] == 390
    assert truth["target_visible_fraction"] >= 0.95 and truth["center_error_px_p50"] <= 20.0
    lock = run_chain("people-following", duration_s=39.0, attention=AttentionConfig(target="lock")).attention
    assert lock is not None
    assert lock["target_visible_fraction"] >= 0.8 and lock["center_error_px_p50"] <= 40.0
