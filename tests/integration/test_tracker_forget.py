"""Forgetting a person (privacy): one ID or everyone, during tracking and across a restart,
the memory file rewritten without them, retention, and what the track query answers;
`perception forget` over a real router."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from common.transport.memory import MemoryBus
from common.messages.schemas import ForgetReply, Tracks
from services.tracker.config import PROFILES
from services.tracker.memory_file import read_classifiers, read_last_seen, read_memory
from tests.helpers.tracker_rig import KEYS, PERIOD_NS, T0, Person, Rig, config, ids_by_x
from tests.helpers.wait import wait_until

S = 1_000_000_000
A: Person = (0, (2.0, 0.0, 1.0))
B: Person = (1, (5.0, 0.0, 1.0))


def forget(rig: Rig, selector: str) -> ForgetReply:
    [(_, reply)] = rig.bus.transport().query(KEYS.forget_query() + selector)
    assert isinstance(reply, ForgetReply)
    return reply


def query(rig: Rig, track_id: int) -> Tracks:
    [(_, msg)] = rig.bus.transport().query(KEYS.track_query() + f"?id={track_id}")
    assert isinstance(msg, Tracks)
    return msg


def remembered(path: Path) -> set[int]:
    """The IDs whose descriptors the memory file holds, read from the file's arrays."""
    with np.load(path) as f:
        return {int(i) for i in f["ids"]}


@pytest.mark.parametrize("profile", PROFILES)
def test_a_person_forgotten_while_tracked_gets_a_new_id_and_leaves_nothing_in_the_file(
        tmp_path: Path, profile: str) -> None:
    rig = Rig(config(tmp_path, profile))
    out = rig.walk(T0, 20, [A, B])
    a_id, b_id = ids_by_x(out[-1])[2], ids_by_x(out[-1])[5]
    reply = forget(rig, f"?id={a_id}")
    assert reply.error == "" and reply.forgotten_ids == [a_id] and reply.live_tracks_cleared == [a_id]
    assert reply.descriptors_removed > 0
    path = tmp_path / "memory.npz"
    assert a_id not in remembered(path) and b_id in remembered(path)  # rewritten at once
    assert a_id not in read_classifiers(path) and a_id not in read_last_seen(path)
    assert query(rig, a_id).tracks == [] and "not found" in query(rig, a_id).note
    # the live track keeps its ID while the person stays, learning no appearance
    out = rig.walk(T0 + 20 * PERIOD_NS, 10, [A, B], seq0=20)
    assert ids_by_x(out[-1]) == {2: a_id, 5: b_id}
    # A leaves long enough for the track to end, and comes back: a new ID, none of A's descriptors kept
    rig.walk(T0 + 30 * PERIOD_NS, 40, [B], seq0=30)
    assert a_id not in remembered(path)
    out = rig.walk(T0 + 70 * PERIOD_NS, 10, [A, B], seq0=70)
    assert ids_by_x(out[-1])[2] not in (a_id, b_id) and ids_by_x(out[-1])[5] == b_id
    assert rig.extra["ids_forgotten"] == 1


@pytest.mark.parametrize("profile", PROFILES)
def test_a_forgotten_person_does_not_come_back_after_a_restart(tmp_path: Path, profile: str) -> None:
    rig = Rig(config(tmp_path, profile))
    rig.walk(T0, 20, [A])
    rig.walk(T0 + 20 * PERIOD_NS, 40, [], seq0=20)  # A leaves: remembered
    path = tmp_path / "memory.npz"
    [a_id] = sorted(remembered(path))
    assert forget(rig, f"?id={a_id}").forgotten_ids == [a_id]
    rig.service.close()
    assert remembered(path) == set() and read_memory(path)[0].entries == {}
    rig2 = Rig(config(tmp_path, profile))
    out = rig2.walk(T0 + 100 * S, 10, [A])
    assert ids_by_x(out[-1])[2] != a_id


def test_forget_all_unknown_and_malformed_requests(tmp_path: Path) -> None:
    rig = Rig(config(tmp_path))
    out = rig.walk(T0, 20, [A, B])
    ids = sorted(ids_by_x(out[-1]).values())
    unknown = forget(rig, "?id=99")
    assert unknown.forgotten_ids == [] and "not found" in unknown.error
    bad = forget(rig, "?id=abc")
    assert bad.forgotten_ids == [] and "malformed" in bad.error
    assert "malformed" in forget(rig, "").error
    everyone = forget(rig, "?all=1")
    assert everyone.forgotten_ids == ids and sorted(everyone.live_tracks_cleared) == ids
    assert remembered(tmp_path / "memory.npz") == set()
    assert rig.service.forget(ids[0]).error.startswith("not found")  # already forgotten


def test_remembered_ids_not_seen_for_the_retention_time_are_forgotten(tmp_path: Path) -> None:
    wall = [1_000_000.0]
    bus = MemoryBus()
    rig = Rig(config(tmp_path, retention_s=3600.0), bus=bus)
    rig.service.wall_clock = lambda: wall[0]
    rig.walk(T0, 20, [A])
    rig.walk(T0 + 20 * PERIOD_NS, 40, [], seq0=20)
    path = tmp_path / "memory.npz"
    [a_id] = sorted(remembered(path))
    wall[0] += 1800.0
    rig.clock.now += 120.0
    rig.walk(T0 + 60 * PERIOD_NS, 2, [], seq0=60)
    assert a_id in rig.service.tracker.memory  # half the retention time: kept
    wall[0] += 3600.0
    rig.clock.now += 120.0
    rig.walk(T0 + 62 * PERIOD_NS, 2, [], seq0=62)
    assert a_id not in rig.service.tracker.memory and rig.extra["ids_expired"] == 1
    rig.service.close()
    assert remembered(path) == set()


def test_the_track_query_answers_for_confirmed_tracks_only(tmp_path: Path) -> None:
    rig = Rig(config(tmp_path, "thesis"))
    rig.step(T0, 0, [A])  # the thesis gives an ID at birth: tentative after one hit
    assert query(rig, 1).tracks == [] and "tentative" in query(rig, 1).note
    out = rig.walk(T0 + PERIOD_NS, 5, [A], seq0=1)
    assert out[-1].tracks and [t.status for t in query(rig, 1).tracks] == ["confirmed"]


def test_perception_forget_over_a_real_router(tmp_path: Path, router, zenoh_client) -> None:  # type: ignore[no-untyped-def]
    rig = Rig(config(tmp_path))  # frames through memory; the forget request over Zenoh
    rig.walk(T0, 20, [A])
    transport = zenoh_client()
    service = rig.service
    closers = [transport.serve(KEYS.forget_query(), service._answer_forget)]

    def run(*args: str) -> subprocess.CompletedProcess[str]:
        cmd = [sys.executable, "-m", "perception", "-q", "forget", *args, "--robot", KEYS.robot, "--mode", "client",
               "--connect", router.endpoint, "--no-multicast-scouting", "--timeout", "5"]
        return subprocess.run(cmd, capture_output=True, text=True, timeout=60, check=False)

    try:
        [a_id] = list(ids_by_x(rig.walk(T0 + 20 * PERIOD_NS, 1, [A], seq0=20)[-1]).values())
        done = run(str(a_id))
        assert done.returncode == 0, done.stderr
        assert f"forgot ID(s) [{a_id}]" in done.stdout and "keep their ID without appearance" in done.stdout
        again = run(str(a_id))
        assert again.returncode == 1 and "not found" in again.stdout
        assert run("0").returncode == 2
    finally:
        for close in closers:
            close()
    probe = zenoh_client()  # another session: asks the router, not the closed queryable's own session
    wait_until(lambda: not probe.query(KEYS.forget_query() + "?id=0", timeout=1.0), 30.0,
               what="the closed forget queryable to leave the router")
    nobody = run("5")
    assert nobody.returncode == 2 and "no tracker answered" in nobody.stderr
