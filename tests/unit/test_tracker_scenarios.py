"""Scenario tests of the tracker core: life cycle, crossing, occlusion, re-identification,
position-only mode and time steps. Descriptors mimic an L2-normalised embedder: each person
has a fixed unit vector, each observation adds a little noise."""

from __future__ import annotations

import numpy as np
import pytest

from services.tracker.core import AppearanceGate, ThesisTracker, ThesisParams, TrackStatus
from services.tracker.core.types import FrameInput
from services.tracker.memory_file import read_memory, save_memory

FPS = 30.0
GATE = AppearanceGate(t_lower=0.25, t_upper=0.6, s_max=0.05)


def params(**kw: object) -> ThesisParams:
    base: dict[str, object] = {"gate": GATE, "t_recover": 0.35, "frame_period_s": 1 / FPS}
    base.update(kw)
    return ThesisParams(**base)  # type: ignore[arg-type]


class People:
    """Synthetic people with fixed appearances; ``observe`` gives positions and descriptors."""

    def __init__(self, n: int, dim: int = 32, seed: int = 0) -> None:
        self.rng = np.random.default_rng(seed)
        a = self.rng.normal(size=(n, dim))
        self.looks = a / np.linalg.norm(a, axis=1, keepdims=True)

    def observe(self, who: list[int], positions: list[tuple[float, float, float]], noise: float = 0.01) -> tuple[np.ndarray, np.ndarray]:
        pos = np.array(positions, dtype=np.float64).reshape(-1, 3) + self.rng.normal(scale=noise, size=(len(who), 3))
        desc = self.looks[who] + self.rng.normal(scale=0.01, size=(len(who), self.looks.shape[1]))
        desc /= np.linalg.norm(desc, axis=1, keepdims=True)
        return pos, desc.astype(np.float32).reshape(len(who), self.looks.shape[1])


def run_single(tracker: ThesisTracker, people: People, frames: list[bool], start: float = 0.0) -> list:
    """Person 0 standing at (2, 0, 1); ``frames[k]`` says whether it is detected in frame k."""
    results = []
    for k, seen in enumerate(frames):
        pos, desc = people.observe([0] if seen else [], [(2.0, 0.0, 1.0)] if seen else [])
        results.append(tracker.step(start + k / FPS, FrameInput.of(pos, desc)))
    return results


def test_life_cycle_tentative_confirmed_and_back() -> None:
    tr, people = ThesisTracker(params()), People(1)
    res = run_single(tr, people, [True, True, True, False, True, True, True])
    statuses = [r.tracks[0].status for r in res]
    assert statuses == [TrackStatus.TENTATIVE, TrackStatus.TENTATIVE, TrackStatus.CONFIRMED,
                        TrackStatus.TENTATIVE,  # a Confirmed track falls back on any miss
                        TrackStatus.TENTATIVE, TrackStatus.TENTATIVE, TrackStatus.CONFIRMED]
    assert [len(r.confirmed) for r in res] == [0, 0, 1, 0, 0, 0, 1]  # only Confirmed are output
    assert {r.tracks[0].id for r in res} == {1}


def test_tentative_is_deleted_after_five_misses_and_archived() -> None:
    tr, people = ThesisTracker(params()), People(1)
    res = run_single(tr, people, [True, True] + [False] * 5)
    assert [len(r.tracks) for r in res] == [1, 1, 1, 1, 1, 1, 0]
    assert [t.id for t in res[-1].deleted] == [1]
    assert res[-1].deleted[0].status is TrackStatus.DELETED
    assert 1 in tr.memory and len(tr.memory.entries[1]) == 2


def test_false_positive_never_confirmed() -> None:
    tr, people = ThesisTracker(params()), People(2)
    outputs = []
    for k in range(10):
        who, where = [0], [(2.0, 0.0, 1.0)]
        if k == 4:  # a single spurious detection of someone else
            who, where = [0, 1], [(2.0, 0.0, 1.0), (5.0, 3.0, 1.0)]
        pos, desc = people.observe(who, where)
        outputs.append({t.id for t in tr.step(k / FPS, FrameInput.of(pos, desc)).confirmed})
    assert all(ids <= {1} for ids in outputs)


def test_occlusion_of_four_frames_keeps_the_track() -> None:
    tr, people = ThesisTracker(params()), People(1)
    res = run_single(tr, people, [True] * 5 + [False] * 4 + [True] * 4)
    assert all(len(r.tracks) == 1 for r in res)
    assert not any(r.deleted for r in res) and not any(r.new_ids for r in res[1:])
    assert [t.id for t in res[-1].confirmed] == [1]


def test_occlusion_of_six_frames_deletes_then_recovers_id() -> None:
    tr, people = ThesisTracker(params()), People(1)
    res = run_single(tr, people, [True] * 5 + [False] * 6 + [True] * 4)
    assert [t.id for t in res[9].deleted] == [1]  # 5th missed frame
    back = res[11]
    assert back.new_ids == [1] and back.recovered_ids == [1]  # re-identified through the ID memory
    assert [t.id for t in res[-1].confirmed] == [1]
    assert tr.memory.next_id == 2


def test_same_person_returns_with_old_id_different_person_does_not() -> None:
    tr, people = ThesisTracker(params()), People(3)
    t = 0.0

    def show(who: int, n: int, where: tuple[float, float, float]) -> list:
        nonlocal t
        out = []
        for _ in range(n):
            pos, desc = people.observe([who], [where])
            out.append(tr.step(t, FrameInput.of(pos, desc)))
            t += 1 / FPS
        return out

    def absent(n: int) -> None:
        nonlocal t
        for _ in range(n):
            tr.step(t, FrameInput.of(np.zeros((0, 3)), np.zeros((0, 32), np.float32)))
            t += 1 / FPS

    a = show(0, 10, (1.0, 1.0, 1.0))
    absent(8)
    b = show(1, 10, (1.0, 1.0, 1.0))  # someone else, same place
    absent(8)
    c = show(0, 10, (4.0, -2.0, 1.0))  # the first person returns elsewhere
    assert a[-1].confirmed[0].id == 1
    assert b[0].new_ids == [2] and b[0].recovered_ids == []
    assert c[0].new_ids == [1] and c[0].recovered_ids == [1]
    assert c[-1].confirmed[0].id == 1


@pytest.mark.parametrize("time_step", ["time", "frame"])
def test_two_people_crossing_keep_their_ids(time_step: str) -> None:
    tr, people = ThesisTracker(params(time_step=time_step)), People(2, seed=5)
    n = 60
    ids_by_person: dict[int, set[int]] = {0: set(), 1: set()}
    for k in range(n):
        x = -1.5 + 3.0 * k / (n - 1)  # 1.5 m/s toward each other, meeting at x = 0
        pos, desc = people.observe([0, 1], [(x, 0.05, 1.0), (-x, -0.05, 1.0)])
        res = tr.step(k / FPS, FrameInput.of(pos, desc))
        for view in res.confirmed:
            person = 0 if np.sign(view.position[0]) == np.sign(x) or abs(x) < 0.1 else 1
            if abs(x) > 0.3:
                ids_by_person[person].add(view.id)
    assert ids_by_person == {0: {1}, 1: {2}}


def test_position_only_mode_tracks_and_leaves_memory_untouched() -> None:
    tr, people = ThesisTracker(params()), People(2)
    for k in range(5):
        pos, desc = people.observe([0], [(2.0 + 0.03 * k, 0.0, 1.0)])
        tr.step(k / FPS, FrameInput.of(pos, desc))
    entries_before = {i: g.descriptors.copy() for i, g in tr.memory.entries.items()}
    gallery_before = len(tr.tracks[0].gallery)  # type: ignore[arg-type]
    res = None
    for k in range(5, 12):
        pos, _ = people.observe([0], [(2.0 + 0.03 * k, 0.0, 1.0)])
        res = tr.step(k / FPS, FrameInput.of(pos, None))
        assert not res.appearance_available
    assert res is not None and [t.id for t in res.confirmed] == [1]
    assert len(tr.tracks[0].gallery) == gallery_before  # type: ignore[arg-type]
    # a far detection is outside the chi-square gate: a new track, with a fresh ID
    pos, _ = people.observe([0, 1], [(2.0 + 0.03 * 12, 0.0, 1.0), (8.0, 8.0, 1.0)])
    res = tr.step(12 / FPS, FrameInput.of(pos, None))
    assert res.new_ids == [2] and res.recovered_ids == []
    # person 0 vanishes in position-only frames: its gallery is archived only once appearance returns
    for k in range(13, 19):
        pos, _ = people.observe([1], [(8.0, 8.0, 1.0)])
        res = tr.step(k / FPS, FrameInput.of(pos, None))
    assert 1 not in tr.live_ids() and tr.memory.entries.keys() == entries_before.keys()
    pos, desc = people.observe([1], [(8.0, 8.0, 1.0)])
    tr.step(19 / FPS, FrameInput.of(pos, desc))
    assert 1 in tr.memory


def test_without_thresholds_every_frame_is_position_only() -> None:
    tr, people = ThesisTracker(params(gate=None)), People(1)
    pos, desc = people.observe([0], [(0.0, 0.0, 1.0)])
    assert not tr.step(0.0, FrameInput.of(pos, desc)).appearance_available


def test_time_mode_counts_dropped_frames_as_elapsed_misses() -> None:
    tr, people = ThesisTracker(params()), People(1)
    run_single(tr, people, [True] * 3)
    t0 = 2 / FPS
    res = tr.step(t0 + 3 / FPS, FrameInput.of(np.zeros((0, 3)), np.zeros((0, 32), np.float32)))  # frames dropped upstream
    assert res.tracks[0].misses == 3
    res = tr.step(t0 + 5 / FPS, FrameInput.of(np.zeros((0, 3)), np.zeros((0, 32), np.float32)))
    assert res.tracks == [] and [t.id for t in res.deleted] == [1]  # 5 frame periods without association


def test_frame_mode_ignores_gaps() -> None:
    tr, people = ThesisTracker(params(time_step="frame")), People(1)
    run_single(tr, people, [True] * 3)
    res = tr.step(10.0, FrameInput.of(np.zeros((0, 3)), np.zeros((0, 32), np.float32)))
    assert res.tracks[0].misses == 1


def test_time_mode_process_noise_grows_with_gap() -> None:
    a, b = ThesisTracker(params()), ThesisTracker(params())
    people = People(1)
    pos, desc = people.observe([0], [(0.0, 0.0, 1.0)])
    a.step(0.0, FrameInput.of(pos, desc))
    b.step(0.0, FrameInput.of(pos, desc))
    a.step(1 / FPS, FrameInput.of(np.zeros((0, 3)), np.zeros((0, 32), np.float32)))
    b.step(4 / FPS, FrameInput.of(np.zeros((0, 3)), np.zeros((0, 32), np.float32)))
    assert b.tracks[0].cov[2, 2] == pytest.approx(0.04 + 4 * 0.04)
    assert a.tracks[0].cov[2, 2] == pytest.approx(0.04 + 0.04)


def test_out_of_order_stamp_is_refused() -> None:
    tr = ThesisTracker(params())
    tr.step(1.0, FrameInput.of(np.zeros((0, 3))))
    with pytest.raises(ValueError, match="in order"):
        tr.step(0.5, FrameInput.of(np.zeros((0, 3))))


def test_snapshot_restore_replays_identically() -> None:
    people = People(2, seed=9)
    frames = [people.observe([0, 1], [(0.1 * k, 0.0, 1.0), (3.0, 0.1 * k, 1.0)]) for k in range(40)]
    tr = ThesisTracker(params(gallery_size=10))
    for k in range(20):
        tr.step(k / FPS, FrameInput.of(*frames[k]))
    snap = tr.snapshot()
    first = [tr.step(k / FPS, FrameInput.of(*frames[k])) for k in range(20, 40)]
    tr.restore(snap)
    second = [tr.step(k / FPS, FrameInput.of(*frames[k])) for k in range(20, 40)]
    for r1, r2 in zip(first, second):
        assert [t.id for t in r1.tracks] == [t.id for t in r2.tracks]
        for t1, t2 in zip(r1.tracks, r2.tracks):
            np.testing.assert_allclose(t1.mean, t2.mean)


def test_memory_round_trip_gives_same_ids_after_restart(tmp_path) -> None:
    people = People(1)
    tr = ThesisTracker(params())
    run_single(tr, people, [True] * 5)
    save_memory(tmp_path / "m.npz", tr.memory, "colour", extra=tr.export_memory().live_galleries)
    memory, _ = read_memory(tmp_path / "m.npz")
    restarted = ThesisTracker(params(), memory)
    res = run_single(restarted, people, [True] * 3, start=100.0)
    assert res[0].recovered_ids == [1] and [t.id for t in res[-1].confirmed] == [1]


def test_time_mode_estimates_velocity_in_metres_per_second_across_irregular_gaps() -> None:
    tr = ThesisTracker(params())
    rng = np.random.default_rng(2)
    stamps = np.cumsum(rng.choice([1 / FPS, 2 / FPS, 3 / FPS], size=60))  # frames dropped at random
    ids = set()
    res = None
    for t in stamps:
        pos = np.array([[1.5 * t, 0.5, 1.0]]) + rng.normal(scale=0.01, size=(1, 3))
        res = tr.step(float(t), FrameInput.of(pos, None))  # position-only: the motion model carries association
        ids |= {v.id for v in res.tracks}
    assert ids == {1} and res is not None
    assert res.tracks[0].velocity[0] == pytest.approx(1.5, abs=0.15)
    assert res.tracks[0].velocity[2] == 0.0  # z is a random walk
