"""The robust profile's ID memory, open-set (core/recovery.py in the tracker): a stranger who
looks like two remembered people gets a new ID, a person who could not have walked there
gets a new ID, a recovery that drifts away is undone and the remembered person kept; the
recovery state is in snapshots and forgotten with the person; a person back in view competes
with a look-alike's coasting track, and with the track of someone who walked out where they walked
in (the memory in the association)."""

from __future__ import annotations

import sys

import numpy as np
import pytest

from services.tracker.core.recovery import RecoveryParams
from services.tracker.core.robust import AppearanceModel, RobustParams, RobustTracker
from services.tracker.core.types import FrameInput

DIM = 8
COLOUR = AppearanceModel(0.35, 0.85, 0.40)
RNG = np.random.default_rng(7)
_E = np.eye(DIM)
_A = 0.18  # people in dark clothes: each is 0.25 from the others, well under t_recover 0.40
DARK = [(_E[0] + _A * _E[k]) / np.linalg.norm(_E[0] + _A * _E[k]) for k in (1, 2, 3)]  # two people and a stranger
RED = _E[5]


@pytest.fixture(autouse=True)
def _same_noise(monkeypatch: pytest.MonkeyPatch) -> None:
    """Each test sees the same noise whichever ran before it (some decisions here are near ties)."""
    monkeypatch.setattr(sys.modules[__name__], "RNG", np.random.default_rng(7))


def view(base: np.ndarray, noise: float = 0.005) -> np.ndarray:
    v = base + RNG.normal(scale=noise, size=DIM)
    return (v / np.linalg.norm(v)).astype(np.float32)


def step(trk: RobustTracker, t: float, people: list[tuple[np.ndarray, tuple[float, float]]]):  # type: ignore[no-untyped-def]
    pos = np.array([[x, y, 1.0] for _, (x, y) in people]).reshape(-1, 3)
    d = np.stack([view(b) for b, _ in people]) if people else np.zeros((0, DIM), np.float32)
    return trk.step(t, FrameInput.of(pos, d))


def run(trk: RobustTracker, t0: float, t1: float, people: list[tuple[np.ndarray, tuple[float, float]]]) -> list:
    return [step(trk, float(t), people) for t in np.arange(t0, t1 - 1e-9, 0.1)]


def id_at(trk: RobustTracker, x: float, y: float) -> int:
    return next(t.id for t in trk.tracks if t.id and np.hypot(t.mean[0] - x, t.mean[1] - y) < 0.5)


def tracker(**recovery: object) -> RobustTracker:
    return RobustTracker(RobustParams(appearance=COLOUR, max_coast_s=0.5, classifier=None,
                                      recovery=RecoveryParams(**recovery)))  # type: ignore[arg-type]


def test_a_stranger_who_looks_like_two_remembered_people_gets_a_new_id() -> None:
    trk = tracker()
    run(trk, 0.0, 2.0, [(DARK[0], (1.0, 0.0)), (DARK[1], (3.0, 0.0))])  # two people in dark clothes, together
    p0, p1 = id_at(trk, 1.0, 0.0), id_at(trk, 3.0, 0.0)
    run(trk, 2.0, 3.0, [])  # both leave: remembered
    assert {p0, p1} <= set(trk.memory.entries) and not trk.live_ids()
    ids, dist = trk.memory.distances(view(DARK[2]))
    assert np.all(dist < COLOUR.t_recover)  # Algorithm 2's nearest-below-t_recover would hand one over
    r = run(trk, 3.0, 4.0, [(DARK[2], (2.0, 1.0))])  # a stranger in dark clothes
    stranger = id_at(trk, 2.0, 1.0)
    assert stranger not in (p0, p1) and not any(x.recovered_ids for x in r)
    run(trk, 4.0, 5.0, [])  # the stranger leaves; the first person comes back
    r = run(trk, 5.0, 6.0, [(DARK[0], (1.5, 0.5))])
    assert id_at(trk, 1.5, 0.5) == p0 and any(p0 in x.recovered_ids for x in r)


def test_someone_who_could_not_have_walked_there_gets_a_new_id() -> None:
    trk = tracker()
    run(trk, 0.0, 1.0, [(RED, (0.0, 0.0))])
    red = id_at(trk, 0.0, 0.0)
    run(trk, 1.0, 1.6, [])  # gone at 0.9 s
    run(trk, 1.6, 2.0, [(RED, (20.0, 0.0))])  # the same look 20 m away 1 s later: another person
    assert id_at(trk, 20.0, 0.0) != red
    run(trk, 2.0, 12.0, [])
    run(trk, 12.0, 12.5, [(RED, (-15.0, 0.0))])  # 11 s later the walk is possible: it is them
    assert id_at(trk, -15.0, 0.0) == red


def test_a_recovery_whose_appearance_drifts_away_is_undone_and_the_person_kept() -> None:
    trk = tracker(p_new=0.5)
    run(trk, 0.0, 2.0, [(DARK[0], (1.0, 0.0))])
    p0 = id_at(trk, 1.0, 0.0)
    run(trk, 2.0, 3.0, [])
    kept = len(trk.memory.entries[p0])
    recovered, undone = drift(trk, 3.0)
    assert recovered == [p0]  # first it was given the remembered ID ...
    assert len(undone) == 1 and undone[0][0] == p0 and trk.state.recovery.undone == 1  # ... then it was taken back
    fresh = undone[0][1]
    assert id_at(trk, 1.5, 0.5) == fresh != p0 and fresh not in trk.memory
    assert p0 in trk.memory and len(trk.memory.entries[p0]) == kept  # the remembered person is untouched
    run(trk, 7.5, 8.5, [])
    run(trk, 8.5, 9.5, [(DARK[0], (1.0, 0.0))])  # the real person comes back and gets their ID
    assert id_at(trk, 1.0, 0.0) == p0


def drift(trk: RobustTracker, t0: float) -> tuple[list[int], list[tuple[int, int]]]:
    """Someone who looks like DARK[0] for half a second, then turns out to wear red (lit, turned
    around), over 4.5 s at (1.5, 0.5); the IDs recovered and the recoveries undone."""
    looks = [DARK[0]] * 5 + [(1 - w) * DARK[0] + w * RED for w in np.linspace(0.1, 1.0, 10)] + [RED] * 30
    recovered, undone = [], []
    for k, look in enumerate(looks):
        r = step(trk, t0 + 0.1 * k, [(look, (1.5, 0.5))])
        recovered += r.recovered_ids
        undone += r.recovery_undone
    return recovered, undone


def test_no_probation_means_no_undo() -> None:
    trk = tracker(p_new=0.5, probation_s=0.0)
    run(trk, 0.0, 2.0, [(DARK[0], (1.0, 0.0))])
    p0 = id_at(trk, 1.0, 0.0)
    run(trk, 2.0, 3.0, [])
    recovered, undone = drift(trk, 3.0)
    assert recovered == [p0] and not undone and trk.state.recovery.undone == 0 and id_at(trk, 1.5, 0.5) == p0


def test_recovery_state_is_snapshotted_and_forgotten_with_the_person() -> None:
    trk = tracker()
    run(trk, 0.0, 1.0, [(DARK[0], (1.0, 0.0)), (RED, (3.0, 0.0))])
    a, b = id_at(trk, 1.0, 0.0), id_at(trk, 3.0, 0.0)
    run(trk, 1.0, 2.0, [])
    assert {a, b} <= set(trk.state.recovery.departures) and trk.state.recovery.together[a] == {b}
    snap = trk.snapshot()
    run(trk, 2.0, 3.0, [(_E[6], (5.0, 5.0)), (_E[7], (2.0, 0.5))])  # two newcomers, seen together
    together = dict(trk.state.recovery.together)
    assert len(together) > 2
    trk.restore(snap)
    assert trk.state.recovery.together == {a: {b}, b: {a}}
    trk.forget(a)
    assert a not in trk.state.recovery.departures and a not in trk.state.recovery.together
    trk.restart_clock()
    assert not trk.state.recovery.departures  # stamps of another clock say nothing of walking times


#: two people whose looks are 0.5 apart: by appearance alone a coasting track could take either
PLAIN, STRIPED = _E[0], (_E[0] + 0.55 * _E[1]) / np.linalg.norm(_E[0] + 0.55 * _E[1])


@pytest.mark.parametrize("compete", [True, False])
def test_a_person_back_in_view_keeps_their_id_instead_of_continuing_a_look_alikes_coasting_track(
        compete: bool) -> None:
    trk = tracker(compete=compete)
    run(trk, 0.0, 2.0, [(PLAIN, (0.0, 0.0)), (STRIPED, (1.5, 0.0))])  # seen together: two people
    plain, striped = id_at(trk, 0.0, 0.0), id_at(trk, 1.5, 0.0)
    run(trk, 2.0, 3.0, [(PLAIN, (0.0, 0.0))])  # the second leaves and is remembered
    assert striped in trk.memory.entries
    run(trk, 3.0, 3.3, [])  # the first is missed: coasting
    run(trk, 3.3, 4.3, [(STRIPED, (0.4, 0.0))])  # the second comes back next to where the first was
    # the ID memory competes with the coasting track: the returning person's own ID, not the first's
    assert id_at(trk, 0.4, 0.0) == (striped if compete else plain)


def test_a_remembered_person_never_seen_with_the_track_does_not_compete_with_it() -> None:
    """Two remembered IDs never detected together may be one person remembered twice: such a
    one is no alternative to a coasting track (it may be that track's own person)."""
    trk = tracker()
    run(trk, 0.0, 1.0, [(STRIPED, (1.5, 0.0))])
    striped = id_at(trk, 1.5, 0.0)
    run(trk, 1.0, 2.0, [])  # remembered, never seen with anyone
    run(trk, 2.0, 4.0, [(PLAIN, (8.0, 0.0))])  # someone too far to be them: a new ID
    plain = id_at(trk, 8.0, 0.0)
    assert striped in trk.memory.entries and plain != striped
    run(trk, 4.0, 4.3, [])
    run(trk, 4.3, 5.3, [(STRIPED, (8.4, 0.0))])  # reachable by now
    assert id_at(trk, 8.4, 0.0) == plain  # position and a fair look keep the coasting track's ID


#: a look 0.65 from PLAIN: by appearance alone a little more likely someone else (log-odds -0.4)
COMER = (_E[0] + 0.78 * _E[1]) / np.linalg.norm(_E[0] + 0.78 * _E[1])


def _walk_in_as_the_other_walks_out(compete: bool) -> tuple[RobustTracker, int, int]:
    trk = tracker(compete=compete)
    run(trk, 0.0, 2.0, [(PLAIN, (0.0, 0.0)), (COMER, (1.5, 0.0))])  # seen together: two people
    plain, comer = id_at(trk, 0.0, 0.0), id_at(trk, 1.5, 0.0)
    run(trk, 2.0, 3.5, [(PLAIN, (0.0, 0.0))])  # the second walks out and is remembered
    assert comer in trk.memory.entries and comer not in trk.live_ids()
    # the first walks out of the spot as the second walks into it, in the next frame: the first's
    # track is confirmed (detected a frame ago), the detection a little unlike its person
    run(trk, 3.5, 4.5, [(COMER, (0.05, 0.0))])
    return trk, plain, comer


@pytest.mark.parametrize("compete", [True, False])
def test_a_person_who_walks_in_where_another_walks_out_keeps_their_own_id(compete: bool) -> None:
    trk, plain, comer = _walk_in_as_the_other_walks_out(compete)
    assert id_at(trk, 0.05, 0.0) == (comer if compete else plain)


def test_a_detection_that_looks_like_the_tracks_person_weighs_no_remembered_alternative() -> None:
    from services.tracker.core import cues

    trk, plain, comer = _walk_in_as_the_other_walks_out(True)
    row = trk.state.tracks.id.index(comer)
    positions, desc = np.array([[0.05, 0.0, 1.0]]), np.stack([view(PLAIN)])  # looks like the remembered one
    r = np.broadcast_to(np.diag([0.04, 0.04, 0.09]), (1, 3, 3))
    gated = np.zeros((1, len(trk.state.tracks)), bool)
    gated[0, row] = True
    alternatives = [cues.memory_alternatives(trk.state, trk.params.appearance, trk.params.appearance_weight,
                                             trk.params.recovery, positions, r, desc, np.array([True]), gated,
                                             np.full(gated.shape, sign)) for sign in (-1.0, 1.0)]
    # the comer's track is confirmed, PLAIN remembered and once seen with the comer: where the pair's
    # appearance says "unlike the track's person", PLAIN is the alternative; where it says "like", none
    assert plain in trk.memory.entries
    assert alternatives[0][0, row] > 3.0 and alternatives[1][0, row] == 0.0
