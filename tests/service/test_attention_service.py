"""The attention node over the in-memory transport: commands from tracks, the attention
query (unknown IDs refused), hold then rest, and bad inputs counted and survived."""

from __future__ import annotations

import numpy as np
import pytest

from common.messages.keys import RELIABLE, Keys
from common.transport.memory import MemoryBus
from common.geometry.poses import OPTICAL_FROM_BODY, make_pose, rot_y, rot_z
from common.messages.samples import rgbd_frame
from common.messages.schemas import AttentionReply, HeadCommand, Header, TrackState, Tracks, TransformBatch
from services.attention.config import AttentionConfig
from services.attention.service import AttentionService
from tools.simulator.messages import transform

STAMP = 10**18


def _tf(keys: Keys, bus: MemoryBus, stamp: int, pan: float = 0.0) -> None:
    t = bus.transport()
    base = make_pose(np.eye(3), (0.0, 0.0, 0.0))
    t.publisher(keys.tf_static(), TransformBatch, RELIABLE).put(TransformBatch(
        header=Header(stamp_ns=stamp), transforms=[transform("head_link", "camera", make_pose(OPTICAL_FROM_BODY, (0.06, 0, 0.08)),
                                                             stamp, static=True)]))
    t.publisher(keys.tf(), TransformBatch, RELIABLE).put(TransformBatch(header=Header(stamp_ns=stamp), transforms=[
        transform("map", "base_link", base, stamp),
        transform("base_link", "head_link", make_pose(rot_z(pan) @ rot_y(0.1), (0.05, 0.0, 1.15)), stamp)]))


def _tracks(stamp: int, *people: tuple[int, tuple[float, float, float]]) -> Tracks:
    return Tracks(header=Header(stamp_ns=stamp, frame_id="map", source="head"), tracks=[
        TrackState(id=i, status="confirmed", position=np.array(p, float), velocity=np.zeros(3), covariance=np.eye(6),
                   last_update_ns=stamp, hits=5, age_s=1.0) for i, p in people])


@pytest.fixture
def rig() -> tuple[MemoryBus, Keys, AttentionService, object, object]:
    bus, keys = MemoryBus(), Keys(robot="att")
    node = AttentionService(bus.transport(), keys, AttentionConfig(target="nearest", hold_s=1.0))
    client = bus.transport()
    frames = client.publisher(keys.frames("head"), type(rgbd_frame(320, 240)), RELIABLE)
    frames.put(rgbd_frame(320, 240, stamp_ns=STAMP))
    tracks = client.publisher(keys.tracks(), Tracks, RELIABLE)
    commands = client.subscribe(keys.head_command(), HeadCommand, RELIABLE)
    _tf(keys, bus, STAMP)
    return bus, keys, node, tracks, commands


def _last(commands) -> HeadCommand:  # type: ignore[no-untyped-def]
    got = None
    while (m := commands.try_recv()) is not None:
        got = m.msg
    assert got is not None
    return got


def test_a_person_on_the_left_turns_the_head_left(rig) -> None:  # type: ignore[no-untyped-def]
    _bus, _keys, node, tracks, commands = rig
    tracks.put(_tracks(STAMP, (1, (2.5, 1.0, 1.0)), (2, (5.0, -2.0, 1.0))))
    node.poll(0.0)
    cmd = _last(commands)
    assert cmd.mode == "track" and cmd.target_id == 1 and cmd.input_stamp_ns == STAMP
    assert cmd.pan_rate > 0 and cmd.error_px[0] < -50  # left of the centre: pan left
    assert cmd.header.source == "attention" and cmd.header.frame_id == "base_link"


def test_the_query_chooses_the_person_and_refuses_unknown_ids(rig) -> None:  # type: ignore[no-untyped-def]
    bus, keys, node, tracks, commands = rig
    tracks.put(_tracks(STAMP, (1, (2.5, 1.0, 1.0)), (2, (3.0, -1.5, 1.0))))
    node.poll(0.0)
    asker = bus.transport()
    (_, reply), = asker.query(keys.attention_query() + "?target=7")
    assert isinstance(reply, AttentionReply) and "unknown track ID 7" in reply.error and reply.known_ids == [1, 2]
    (_, bad), = asker.query(keys.attention_query() + "?target=someone")
    assert "malformed" in bad.error
    (_, ok), = asker.query(keys.attention_query() + "?target=2")
    assert not ok.error and ok.mode == "id" and ok.requested_id == 2
    tracks.put(_tracks(STAMP + 10**8, (1, (2.5, 1.0, 1.0)), (2, (3.0, -1.5, 1.0))))
    node.poll(0.1)
    cmd = _last(commands)
    assert cmd.target_id == 2 and cmd.pan_rate < 0  # person 2 is on the right
    extra = node.counters.extra
    assert extra["unknown_target_ids"] == 1 and extra["bad_requests"] == 1
    (_, none), = asker.query(keys.attention_query() + "?target=none")
    assert none.mode == "none"


def test_lock_over_the_query_follows_the_nearest_then_keeps_that_id(rig) -> None:  # type: ignore[no-untyped-def]
    bus, keys, node, tracks, commands = rig
    (_, reply), = bus.transport().query(keys.attention_query() + "?target=lock")
    assert not reply.error and reply.mode == "lock"
    tracks.put(_tracks(STAMP, (1, (2.5, 1.0, 1.0)), (2, (4.0, -1.5, 1.0))))
    node.poll(0.0)
    assert _last(commands).target_id == 1
    tracks.put(_tracks(STAMP + 10**8, (1, (4.0, 1.0, 1.0)), (2, (2.0, -1.5, 1.0))))  # 2 is now much nearer
    node.poll(0.1)
    assert _last(commands).target_id == 1  # locked: 'nearest' would have switched
    (_, state), = bus.transport().query(keys.attention_query())
    assert (state.mode, state.requested_id, state.following_id) == ("id", 1, 1)


def test_a_lost_target_holds_then_the_head_returns_to_rest(rig) -> None:  # type: ignore[no-untyped-def]
    bus, keys, node, tracks, commands = rig
    tracks.put(_tracks(STAMP, (1, (2.5, 1.0, 1.0))))
    node.poll(0.0)
    assert _last(commands).mode == "track"
    tracks.put(_tracks(STAMP + 10**8))
    node.poll(0.1)
    assert _last(commands).mode == "hold"
    _tf(keys, bus, STAMP + 2 * 10**8, pan=0.5)
    node.poll(0.5)  # no tracks: a timed command (keep-alive)
    assert _last(commands).mode == "hold"
    node.poll(1.3)
    rest = _last(commands)
    assert rest.mode == "rest" and rest.pan_rate < 0 and rest.target_id == -1  # back towards pan 0


def test_bad_inputs_are_counted_and_survived() -> None:
    bus, keys = MemoryBus(), Keys(robot="att")
    node = AttentionService(bus.transport(), keys, AttentionConfig(target="nearest"))
    client = bus.transport()
    tracks = client.publisher(keys.tracks(), Tracks, RELIABLE)
    commands = client.subscribe(keys.head_command(), HeadCommand, RELIABLE)
    _tf(keys, bus, STAMP)
    bad = _tracks(STAMP, (1, (2.5, 1.0, 1.0)), (2, (3.0, 0.0, 1.0)))
    bad.tracks[1].position[:] = np.nan
    tracks.put(bad)
    node.poll(0.0)  # no camera info yet
    assert _last(commands).mode == "blind"
    client.publisher(keys.frames("head"), type(rgbd_frame(64, 48)), RELIABLE).put(rgbd_frame(320, 240, stamp_ns=STAMP))
    tracks.put(bad)
    node.poll(2.0)
    cmd = _last(commands)
    assert cmd.mode == "track" and cmd.target_id == 1
    extra = node.counters.extra
    assert extra["nan_tracks"] == 2 and extra["no_camera_info"] == 1
