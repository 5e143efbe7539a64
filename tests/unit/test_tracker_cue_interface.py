"""Adding a cue to the robust tracker is its module and one line of ``cues.build``: a cue made
here, outside the tracker, changes who is matched to whom, keeps its own per-track state in step
with the tracks (births, deaths, hand-overs, snapshots, forgetting) and learns from the matches,
without a change to the tracker."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
import pytest

from services.tracker.core import cues
from services.tracker.core.cues import Cue, Pairing
from services.tracker.core.robust import RobustParams, RobustTracker
from services.tracker.core.tracks import RobustTrackerState
from services.tracker.core.types import FrameInput


@dataclass
class SideColumns:
    """Per track (a cue's own state): the side of x = 0 it was last detected on, and how many
    detections it was matched with."""

    side: list[float] = field(default_factory=list)
    seen: list[int] = field(default_factory=list)

    def append(self, k: int) -> None:
        self.side += [0.0] * k
        self.seen += [0] * k

    def keep(self, idx: np.ndarray) -> None:
        self.side = [self.side[j] for j in idx.tolist()]
        self.seen = [self.seen[j] for j in idx.tolist()]

    def copy(self) -> SideColumns:
        return SideColumns(list(self.side), list(self.seen))

    def merge(self, j: int, old: int) -> None:
        self.seen[j] += self.seen[old]

    def clear(self, j: int) -> None:
        self.seen[j] = 0


class SideCue(Cue):
    """A wall along x = 0: a detection on the other side of it than the track is someone else."""

    name = "side"

    def columns(self) -> SideColumns:
        return SideColumns()

    def log_odds(self, pairing: Pairing, state: RobustTrackerState) -> np.ndarray:
        cols: SideColumns = state.tracks.extra[self.name]  # type: ignore[assignment]
        det_side = np.sign(pairing.positions[:, 0])[:, None]
        return np.where(det_side == np.array(cols.side)[None, :], 0.0, -30.0)

    def learn(self, pairing: Pairing, state: RobustTrackerState, rows: np.ndarray) -> None:
        cols: SideColumns = state.tracks.extra[self.name]  # type: ignore[assignment]
        for d, j in zip(*rows.tolist()):
            cols.seen[j] += 1
            cols.side[j] = float(np.sign(pairing.positions[d, 0]))

    def born(self, pairing: Pairing, state: RobustTrackerState, first: int, dets: np.ndarray) -> None:
        cols: SideColumns = state.tracks.extra[self.name]  # type: ignore[assignment]
        for k, d in enumerate(dets.tolist()):
            cols.side[first + k] = float(np.sign(pairing.positions[d, 0]))


def walk(trk: RobustTracker, xs: list[float]) -> list[set[int]]:
    """One person walking through ``xs`` at 10 Hz; the confirmed IDs of each frame."""
    out = []
    for k, x in enumerate(xs):
        r = trk.step(0.1 * k, FrameInput.of(np.array([[x, 0.0, 1.0]]), scores=np.array([3.0])))
        out.append({v.id for v in trk.reported(r)})
    return out


@pytest.fixture
def with_side_cue(monkeypatch: pytest.MonkeyPatch) -> None:
    built = cues.build
    monkeypatch.setattr(cues, "build", lambda p: built(p) + [SideCue()])  # the one line


CROSSING = [-1.0 + 0.1 * k for k in range(8)] + [0.05 + 0.1 * k for k in range(8)]


def test_without_the_cue_a_person_crossing_x_0_keeps_their_id() -> None:
    ids = walk(RobustTracker(RobustParams()), CROSSING)
    assert ids[6] == ids[-1] and len(ids[-1]) == 1


def test_a_cue_added_in_one_line_changes_the_association(with_side_cue: None) -> None:
    trk = RobustTracker(RobustParams())
    assert [c.name for c in trk.cues][-1] == "side"
    ids = walk(trk, CROSSING)
    assert ids[6] and ids[-1] and ids[6] != ids[-1]  # across the wall: another track


def test_a_cues_own_state_follows_the_tracks(with_side_cue: None) -> None:
    trk = RobustTracker(RobustParams())
    walk(trk, [-1.0 + 0.1 * k for k in range(6)])
    t = trk.state.tracks
    cols: SideColumns = t.extra["side"]  # type: ignore[assignment]
    assert len(cols.seen) == len(t) == 1 and cols.seen == [t.total_hits[0] - 1]  # the birth is no match
    snap = trk.snapshot()
    trk.step(0.6, FrameInput.of(np.array([[-0.4, 0.0, 1.0], [3.0, 3.0, 1.0]]), scores=np.array([3.0, 3.0])))
    assert len(trk.state.tracks.extra["side"].seen) == 2  # type: ignore[attr-defined]
    trk.restore(snap)
    assert trk.state.tracks.extra["side"].seen == [5]  # type: ignore[attr-defined]
    trk.forget(trk.state.tracks.id[0])
    assert trk.state.tracks.extra["side"].seen == [0]  # type: ignore[attr-defined]
    for k in range(40):  # nobody any more: the track ends, and its row goes with it
        trk.step(0.7 + 0.1 * k, FrameInput.of(np.zeros((0, 3))))
    assert len(trk.state.tracks) == 0 and trk.state.tracks.extra["side"].seen == []  # type: ignore[attr-defined]
