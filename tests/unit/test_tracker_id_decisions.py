"""Why a track has its ID (core/id_decisions.py in the tracker): each decision of the robust
profile's open-set ID memory comes with its evidence, the same the decision weighed; a
stranger's, a returning person's, an unreachable candidate's and an undone recovery's read
as such; the thesis profile's Algorithm 2 is explained by its descriptor distances against
t_recover; ``perception track --id-log`` writes them for either profile."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from perception.cli import main
from services.tracker.core import AppearanceGate, ThesisTracker, ThesisParams
from services.tracker.core.recovery import RecoveryParams
from services.tracker.core.robust import AppearanceModel, RobustParams, RobustTracker
from services.tracker.core.types import FrameInput, IdDecision

DIM = 8
COLOUR = AppearanceModel(0.35, 0.85, 0.40)
_E = np.eye(DIM)
DARK = [(_E[0] + 0.18 * _E[k]) / np.linalg.norm(_E[0] + 0.18 * _E[k]) for k in (1, 2, 3)]  # look-alikes
RED = _E[5]


class Scene:
    """A robust tracker fed people (look, (x, y)) at 10 Hz; every ID decision it made."""

    def __init__(self, **recovery: object) -> None:
        self.trk = RobustTracker(RobustParams(appearance=COLOUR, max_coast_s=0.5, classifier=None,
                                              recovery=RecoveryParams(**recovery)))  # type: ignore[arg-type]
        self.rng = np.random.default_rng(7)
        self.decisions: list[IdDecision] = []

    def run(self, t0: float, t1: float, people: list[tuple[np.ndarray, tuple[float, float]]]) -> None:
        for t in np.arange(t0, t1 - 1e-9, 0.1):
            self.frame(float(t), people)

    def frame(self, t: float, people: list[tuple[np.ndarray, tuple[float, float]]]) -> None:
        pos = np.array([[x, y, 1.0] for _, (x, y) in people]).reshape(-1, 3)
        views = [b + self.rng.normal(scale=0.005, size=DIM) for b, _ in people]
        d = np.stack([v / np.linalg.norm(v) for v in views]).astype(np.float32) if people else np.zeros((0, DIM))
        self.decisions += self.trk.step(t, FrameInput.of(pos, d)).id_decisions

    def id_at(self, x: float, y: float) -> int:
        return next(t.id for t in self.trk.tracks if t.id and np.hypot(t.mean[0] - x, t.mean[1] - y) < 0.5)


def test_a_stranger_and_a_returning_person_are_explained() -> None:
    s = Scene()
    s.run(0.0, 2.0, [(DARK[0], (1.0, 0.0)), (DARK[1], (3.0, 0.0))])  # two look-alikes, together
    assert not s.decisions  # the first people met an empty memory: new by necessity, nothing weighed
    p0, p1 = s.id_at(1.0, 0.0), s.id_at(3.0, 0.0)
    s.run(2.0, 3.0, [])
    s.run(3.0, 4.0, [(DARK[2], (2.0, 1.0))])  # a stranger who looks like both
    [d] = s.decisions
    assert d.outcome == "new" and d.id == s.id_at(2.0, 1.0) not in (p0, p1)
    assert {c.id for c in d.candidates} == {p0, p1} and all(c.reachable for c in d.candidates)
    assert d.support < d.threshold == 0.5 and d.candidates[0].support == d.support
    assert d.candidates[0].log_odds > 0  # alike, yet not more probable than "new" and the rival together
    assert d.summary().startswith(f"new ID {d.id} at (2.0") and "support" in d.summary()
    s.run(4.0, 5.0, [])
    s.run(5.0, 6.0, [(DARK[0], (1.5, 0.5))])  # the first person comes back
    d = s.decisions[-1]
    assert (d.outcome, d.id, d.candidates[0].id) == ("recovered", p0, p0) and d.support >= 0.5
    c = d.candidates[0]
    assert c.walked_out is False and 2.5 < c.away_s < 4.0 and c.distance_m == pytest.approx(np.hypot(0.5, 0.5), abs=0.1)
    assert f"ID {p0} recovered" in d.summary() and "last seen" in d.summary()
    json.dumps(d.as_dict())  # plain values


def test_a_candidate_who_could_not_have_walked_there_is_named_as_such() -> None:
    s = Scene()
    s.run(0.0, 1.0, [(RED, (0.0, 0.0))])
    red = s.id_at(0.0, 0.0)
    s.run(1.0, 1.6, [])
    s.run(1.6, 2.0, [(RED, (20.0, 0.0))])  # the same look 20 m away a second later
    [d] = s.decisions
    assert d.outcome == "new" and [c.id for c in d.candidates] == [red] and not d.candidates[0].reachable
    assert "no remembered person could have walked here" in d.summary()
    assert "could not have walked here" in d.candidates[0].describe()


def test_an_undone_recovery_names_the_person_taken_back() -> None:
    s = Scene(p_new=0.5)
    s.run(0.0, 2.0, [(DARK[0], (1.0, 0.0))])
    p0 = s.id_at(1.0, 0.0)
    s.run(2.0, 3.0, [])
    looks = [DARK[0]] * 5 + [(1 - w) * DARK[0] + w * RED for w in np.linspace(0.1, 1.0, 10)] + [RED] * 30
    for k, look in enumerate(looks):  # looks like them at first, then turns out to wear red
        s.frame(3.0 + 0.1 * k, [(look, (1.5, 0.5))])
    first, last = s.decisions
    assert (first.outcome, first.id) == ("recovered", p0)
    assert (last.outcome, last.previous_id, last.candidates[0].id) == ("undone", p0, p0)
    assert last.id == s.id_at(1.5, 0.5) != p0 and last.support < last.threshold == 0.25
    assert f"recovery of ID {p0} undone, now ID {last.id}" in last.summary()


def test_the_thesis_profile_explains_algorithm_2_when_the_track_is_confirmed() -> None:
    """Pinto's Algorithm 2 decides at birth (nearest remembered person within t_recover); the
    decision is told once, when the track is confirmed (its ID becomes visible), and survives
    a snapshot and restore (a rewind) as the track does."""
    trk = ThesisTracker(ThesisParams(gate=AppearanceGate(COLOUR.t_lower, COLOUR.t_upper), t_recover=COLOUR.t_recover,
                                n_init=3, max_misses=2))
    told: list[tuple[float, IdDecision]] = []

    def run(t0: float, t1: float, people: list[tuple[np.ndarray, tuple[float, float]]]) -> None:
        for t in np.arange(t0, t1 - 1e-9, 0.1):
            pos = np.array([[x, y, 1.0] for _, (x, y) in people]).reshape(-1, 3)
            d = np.stack([v for v, _ in people]).astype(np.float32) if people else np.zeros((0, DIM), np.float32)
            told.extend((float(t), d) for d in trk.step(float(t), FrameInput.of(pos, d)).id_decisions)

    run(0.0, 1.0, [(DARK[0], (1.0, 0.0)), (RED, (4.0, 0.0))])
    assert not told  # nobody remembered: new by necessity, nothing weighed
    first = {round(float(t.mean[0])): t.id for t in trk.tracks}
    run(1.0, 1.5, [])  # both leave; their galleries go to the memory
    run(1.5, 1.6, [(DARK[2], (2.0, 0.0))])  # born: a look-alike of the first person
    state = trk.snapshot()
    run(1.6, 1.7, [(DARK[2], (2.0, 0.0))])
    assert not told  # decided at birth, not told before the track is confirmed (its third hit)
    run(1.7, 1.9, [(DARK[2], (2.0, 0.0))])
    [(t, d)] = told
    assert d.rule == "nearest" and d.outcome == "recovered" and d.id == first[1] and t == pytest.approx(1.7)
    assert [c.id for c in d.candidates] == [first[1], first[4]] and d.candidates[0].distance < d.threshold
    assert d.candidates[0].distance < d.candidates[1].distance and d.candidates[0].support == d.support == 1.0
    assert d.stamp == pytest.approx(1.5) and d.p_new == 0.0
    assert d.summary().startswith(f"ID {first[1]} recovered at (2.00, 0.00) m, t=1.50 s (Algorithm 2)")
    assert f"descriptor distance {d.candidates[0].distance:.2f} < t_recover 0.40" in d.summary()
    assert IdDecision.from_dict(json.loads(json.dumps(d.as_dict()))) == d
    trk.restore(state)  # a rewind: the decision is told again, the same, on confirmation
    del told[:]
    run(1.6, 1.9, [(DARK[2], (2.0, 0.0))])
    assert [d2 for _, d2 in told] == [d]
    run(1.9, 2.5, [])
    run(2.5, 2.9, [(_E[7], (3.0, 0.0))])  # someone like nobody remembered
    d = told[-1][1]
    assert d.outcome == "new" and d.support == 0.0 and d.p_new == 1.0 and d.id not in first.values()
    assert d.candidates[0].distance >= d.threshold and d.candidates[0].log_odds < 0
    assert f"new ID {d.id}" in d.summary() and ">= t_recover 0.40" in d.summary()


def test_perception_track_writes_the_id_log(tmp_path: Path) -> None:
    """One person walks, is gone for 4 s, and comes back nearby: one line, a recovery."""
    rng = np.random.default_rng(0)
    look = rng.normal(size=DIM)
    look /= np.linalg.norm(look)
    lines = ["frame,stamp,x,y,z,score" + "".join(f",e{i}" for i in range(DIM))]
    for k in list(range(0, 60)) + list(range(180, 240)):  # 30 Hz; frames 60-179 empty
        e = look + rng.normal(scale=0.01, size=DIM)
        lines.append(",".join([str(k), f"{k / 30:.6f}", f"{1.0 + (0.3 if k >= 180 else 0.0):.3f}", "0.0", "1.0", "0.9"]
                              + [f"{v:.5f}" for v in e / np.linalg.norm(e)]))
    dets, out, ids = tmp_path / "dets.csv", tmp_path / "tracks.csv", tmp_path / "ids.jsonl"
    dets.write_text("\n".join(lines) + "\n")
    assert main(["track", "--detections", str(dets), "--output", str(out), "--id-log", str(ids)]) == 0
    [entry] = [json.loads(line) for line in ids.read_text().splitlines()]
    track_ids = set(np.loadtxt(out, delimiter=",", skiprows=1, ndmin=2)[:, 2].astype(int))
    assert entry["outcome"] == "recovered" and track_ids == {entry["id"]} and 180 <= entry["frame"] < 190
    assert entry["candidates"][0]["id"] == entry["id"] and entry["candidates"][0]["away_s"] > 3.5
    thesis = tmp_path / "ids_thesis.jsonl"  # the thesis profile: Algorithm 2's line
    assert main(["track", "--detections", str(dets), "--output", str(out), "--profile", "thesis",
                 "--id-log", str(thesis)]) == 0
    [entry] = [json.loads(line) for line in thesis.read_text().splitlines()]
    assert (entry["rule"], entry["outcome"]) == ("nearest", "recovered") and 180 <= entry["frame"] < 190
    assert entry["candidates"][0]["distance"] < entry["threshold"]
