"""A fixed camera's view of the floor (core/view.py's FloorView) and what the ID memory makes of
it: a person who walked out of the image is told from one lost inside it (hidden, missed), and
with ``recovery.left_weight`` below 1 (an open place) a look-alike walking in is not handed the
ID of someone who walked out, while a person hidden inside the view still gets theirs back."""

from __future__ import annotations

import numpy as np
import pytest

from services.tracker.core import lifecycle
from services.tracker.core.recovery import Departure, RecoveryParams, RecoveryState
from services.tracker.core.robust import AppearanceModel, RobustParams, RobustTracker
from services.tracker.core.view import FloorView, Views
from services.tracker.core.types import FrameInput

DIM = 8
COLOUR = AppearanceModel(0.35, 0.85, 0.40)
_E = np.eye(DIM)
PERSON = (_E[0] + 0.12 * _E[1]) / np.linalg.norm(_E[0] + 0.12 * _E[1])
_D = 0.6  # a look-alike 0.6 from them: log-odds about 0.3 of being them (the mean view is nearer), "new" at prior 0.3
LOOKALIKE = (1 - _D ** 2 / 2) * PERSON + np.sqrt(1 - (1 - _D ** 2 / 2) ** 2) * _E[3]
#: 1000 x 500 pixels seeing the floor x in [0, 10] m, y in [0, 5] m (10 mm a pixel)
VIEW = FloorView(np.diag([0.01, 0.01, 1.0]), 1000, 500)


def test_a_floor_view_holds_the_feet_inside_the_image() -> None:
    pts = np.array([[5.0, 2.5, 1.0], [10.5, 2.5, 1.0], [-0.1, 1.0, 1.0], [5.0, 5.2, 1.0]])
    assert VIEW.contains(pts).tolist() == [True, False, False, False]
    # with a border: half a body (0.25 m, 25 px here) on the left, right and top; none at the
    # bottom, where the body is above the feet
    edge = np.array([[0.2, 2.5, 1.0], [9.8, 2.5, 1.0], [5.0, 0.2, 1.0], [5.0, 4.95, 1.0]])
    assert VIEW.contains(edge, 0.1).tolist() == [False, False, False, True]
    assert VIEW.contains(edge + [[0.1, 0, 0], [-0.1, 0, 0], [0, 0.1, 0], [0, 0, 0]], 0.1).all()
    assert VIEW.contains(edge[:, :2]).all()  # no border; (N, 2) floor points read the same
    # the border follows the perspective: half a body is fewer pixels far away, so near and far
    # alike 0.2 m from the image's left edge (x = 0) is outside it and 0.3 m inside
    tilted = FloorView(np.linalg.inv(np.array([[100.0, 0, 0], [0, 100.0, 0], [0, 0.5, 1.0]])), 1000, 500)
    pts = np.array([[0.2, 0.5, 1.0], [0.2, 4.0, 1.0], [0.3, 0.5, 1.0], [0.3, 4.0, 1.0]])
    assert tilted.contains(pts, 0.1).tolist() == [False, False, True, True]
    assert FloorView(tilted.image_to_floor, 1000, 500, half_width_m=0.0).contains(pts, 0.1).all()
    assert Views((VIEW, FloorView(np.diag([0.01, 0.01, 1.0]) + [[0, 0, 10], [0, 0, 0], [0, 0, 0]], 1000, 500))
                 ).contains(np.array([[15.0, 2.5, 1.0]])).tolist() == [True]  # a second camera beside it


def test_a_floor_view_refuses_a_singular_homography() -> None:
    with pytest.raises(ValueError, match="invertible"):
        FloorView(np.zeros((3, 3)), 640, 480)
    with pytest.raises(ValueError, match="positive"):
        FloorView(np.eye(3), 0, 480)


def test_the_departure_says_whether_they_walked_out() -> None:
    trk = RobustTracker(RobustParams(appearance=COLOUR, classifier=None))
    walks = {"out": (8.0, 1.5), "in": (8.8, -1.5), "middle": (5.0, 1.5)}
    for k, (x, vx) in enumerate(walks.values()):
        for f in range(10):
            pos = np.array([[x + vx * 0.1 * f, 1.0 + k, 1.0]])
            trk.step(10.0 * k + 0.1 * f, FrameInput.of(pos, PERSON[None].astype(np.float32), view=VIEW))
        t = trk.state.tracks
        j = len(t) - 1
        assert lifecycle.walked_out(t, j, VIEW, 1.0) is (k == 0)  # only the one walking out of the image
        assert not lifecycle.walked_out(t, j, None, 1.0) and not lifecycle.walked_out(t, j, VIEW, 0.0)
        for i in sorted(set(trk.memory.entries) | trk.live_ids()):
            trk.forget(i)


def test_the_departure_kind_is_kept_in_the_memory_file_and_old_files_still_read() -> None:
    state = RecoveryState({3: Departure(1.0, 2.0, 3.0, 0.1, left=True, stature=1.74, stature_n=20),
                           4: Departure(2.0, 0.0, 0.0, 0.2)})
    arrays = state.to_arrays()
    assert arrays["recovery_departures"].shape == (2, 7)
    assert RecoveryState.from_arrays(arrays).departures == state.departures  # the stature too
    old = {**arrays, "recovery_departures": arrays["recovery_departures"][:, :4]}  # written before the columns
    assert [d.left for d in RecoveryState.from_arrays(old).departures.values()] == [False, False]
    before_stature = {**arrays, "recovery_departures": arrays["recovery_departures"][:, :5]}
    assert [(d.left, d.stature_n) for d in RecoveryState.from_arrays(before_stature).departures.values()] == \
        [(True, 0), (False, 0)]


def run(trk: RobustTracker, t0: float, t1: float, look: np.ndarray | None, x0: float = 0.0, vx: float = 0.0,
        y: float = 2.5) -> float:
    """One person ``look`` walking along y from x0 at vx m/s (None: nobody), 10 frames/s; returns the end time."""
    rng = np.random.default_rng(int(t0 * 10))
    for t in np.arange(t0, t1 - 1e-9, 0.1):
        if look is None:
            trk.step(float(t), FrameInput.of(np.zeros((0, 3)), np.zeros((0, DIM), np.float32), view=VIEW))
            continue
        d = look + rng.normal(scale=0.005, size=DIM)
        trk.step(float(t), FrameInput.of(np.array([[x0 + vx * (t - t0), y, 1.0]]), (d / np.linalg.norm(d))[None].astype(np.float32),
                   view=VIEW))
    return t1


def ids(trk: RobustTracker) -> set[int]:
    return {t.id for t in trk.tracks if t.id}


@pytest.mark.parametrize("left_weight", [1.0, 0.2])
def test_a_look_alike_walking_in_where_someone_walked_out(left_weight: float) -> None:
    trk = RobustTracker(RobustParams(appearance=COLOUR, classifier=None,
                                     recovery=RecoveryParams(left_weight=left_weight)))
    t = run(trk, 0.0, 2.0, PERSON, 7.0, 1.4)  # walks right, out of the image at x = 10
    (first,) = ids(trk)
    t = run(trk, t, 6.0, None)
    assert not ids(trk) and first in trk.memory.entries
    assert trk.state.recovery.departures[first].left
    run(trk, t, t + 1.5, LOOKALIKE, 9.9, -1.4)  # someone alike walks in at the same edge
    (second,) = ids(trk)
    # a home (1): the ID memory takes them for the same person; an open place (0.2): a stranger
    assert (second == first) is (left_weight == 1.0)


def test_a_person_hidden_inside_the_view_gets_their_id_back_in_an_open_place() -> None:
    trk = RobustTracker(RobustParams(appearance=COLOUR, classifier=None, recovery=RecoveryParams(left_weight=0.2)))
    t = run(trk, 0.0, 2.0, PERSON, 3.0, 1.0)  # walks to x = 5, then behind something
    (first,) = ids(trk)
    t = run(trk, t, 6.0, None)
    assert not ids(trk) and not trk.state.recovery.departures[first].left
    run(trk, t, t + 1.5, PERSON, 6.0, 1.0)  # out from behind it
    assert ids(trk) == {first}


def test_someone_who_walked_out_and_comes_back_with_a_close_look_gets_their_id_back() -> None:
    trk = RobustTracker(RobustParams(appearance=COLOUR, classifier=None, recovery=RecoveryParams(left_weight=0.2)))
    t = run(trk, 0.0, 2.0, PERSON, 7.0, 1.4)
    (first,) = ids(trk)
    t = run(trk, t, 6.0, None)
    run(trk, t, t + 1.5, PERSON, 9.9, -1.4)
    assert ids(trk) == {first}  # the prior is lower, the evidence still carries it
