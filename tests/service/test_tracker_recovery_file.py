"""The open-set recovery's state survives a restart: where and when each person was last
detected and who was seen with whom go into the ID memory's file with the descriptors, so a
restarted tracker still refuses an ID to someone who could not have walked there; a file from
another clock (a replay or simulator starting over) is not trusted."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from services.tracker.core.recovery import Departure, RecoveryState
from services.tracker.memory_file import read_recovery
from tests.helpers.tracker_rig import PERIOD_NS, S, T0, Rig, config, ids_by_x


def _walk(rig: Rig, t: int, n: int, people: list, seq: int = 0) -> tuple[list, int]:  # type: ignore[type-arg]
    return rig.walk(t, n, people, seq), t + n * PERIOD_NS


def _two_people_leave(tmp_path: Path) -> tuple[int, int, int]:
    """Two people seen together at x = 1 and x = 3, then gone long enough to be remembered; the
    service is closed (its file written). Returns their IDs and the next stamp."""
    rig = Rig(config(tmp_path))
    out, t = _walk(rig, T0, 20, [(0, (1.0, 0.0, 1.0)), (1, (3.0, 0.0, 1.0))])
    ids = ids_by_x(out[-1])
    _, t = _walk(rig, t, 30, [], 20)
    assert {ids[1], ids[3]} <= set(rig.service.tracker.memory.entries)
    rig.service.close()
    return ids[1], ids[3], t


def test_the_recovery_state_is_written_and_read_back(tmp_path: Path) -> None:
    p0, p1, _ = _two_people_leave(tmp_path)
    stored = RecoveryState.from_arrays(read_recovery(tmp_path / "memory.npz"))
    assert {p0, p1} <= set(stored.departures)
    assert stored.departures[p0].x == pytest.approx(1.0, abs=0.2) and stored.departures[p1].x == pytest.approx(3.0, abs=0.2)
    assert p1 in stored.together[p0] and p0 in stored.together[p1]
    again = Rig(config(tmp_path)).service.tracker
    assert again.state.recovery.departures == stored.departures  # type: ignore[attr-defined]
    assert again.state.recovery.together[p0] == stored.together[p0]  # type: ignore[attr-defined]


@pytest.mark.parametrize("keep_file_state", [True, False])
def test_after_a_restart_no_one_gets_the_id_of_a_person_who_could_not_have_walked_there(
        tmp_path: Path, keep_file_state: bool) -> None:
    p0, _, t = _two_people_leave(tmp_path)
    if not keep_file_state:  # the file as it was before the recovery's state was kept in it
        path = tmp_path / "memory.npz"
        with np.load(path) as f:
            arrays = {k: f[k] for k in f.files if not k.startswith("recovery_")}
        np.savez(path, **arrays)
    rig = Rig(config(tmp_path))
    # one second later the first person's look appears 30 m from where they left 4 s before
    out, _ = _walk(rig, t + S, 10, [(0, (31.0, 0.0, 1.0))], 60)
    given = ids_by_x(out[-1])[31]
    if keep_file_state:
        assert given != p0 and not rig.extra.get("ids_recovered")
    else:  # nothing says where they left: the look alone gives the ID back
        assert given == p0


def test_departures_of_another_clock_are_dropped(tmp_path: Path) -> None:
    p0, _, _ = _two_people_leave(tmp_path)
    rig = Rig(config(tmp_path))
    # the stamps start over (a replay from its beginning): the departures lie in the future
    out, _ = _walk(rig, T0 - 3600 * S, 10, [(0, (31.0, 0.0, 1.0))])
    assert ids_by_x(out[-1])[31] == p0 and not rig.service.tracker.state.recovery.departures  # type: ignore[attr-defined]


def test_a_live_track_is_kept_as_having_left_where_it_was() -> None:
    state = RecoveryState({4: Departure(1.0, 0.0, 0.0, 0.01)}, {4: frozenset({7}), 7: frozenset({4})})
    arrays = state.to_arrays({7: Departure(5.0, 2.0, 3.0, 0.02)})
    back = RecoveryState.from_arrays(arrays)
    assert back.departures == {4: Departure(1.0, 0.0, 0.0, 0.01), 7: Departure(5.0, 2.0, 3.0, 0.02)}
    assert back.together == state.together
    old = RecoveryState.from_arrays({**arrays, "recovery_counts": np.array([2.0, 1.0])})  # an older file's
    assert old.departures == back.departures
    assert RecoveryState.from_arrays({}).departures == {}


@pytest.mark.parametrize("key, value", [
    ("recovery_departures", np.zeros((5, 4))),  # more rows than IDs
    ("recovery_departures", np.full((1, 4), np.nan)),
    ("recovery_together_counts", np.array([5])),  # more members than stored
])
def test_an_inconsistent_recovery_block_is_refused_and_the_service_starts_without_it(
        tmp_path: Path, key: str, value: np.ndarray) -> None:
    arrays = RecoveryState({4: Departure(1.0, 0.0, 0.0, 0.01)}, {4: frozenset({7})}).to_arrays()
    arrays[key] = value
    with pytest.raises(ValueError, match="recovery"):
        RecoveryState.from_arrays(arrays)
    p0, _, t = _two_people_leave(tmp_path)
    path = tmp_path / "memory.npz"
    with np.load(path) as f:
        stored = {k: f[k] for k in f.files}
    stored[key] = value
    np.savez(path, **stored)
    rig = Rig(config(tmp_path))  # starts, with the memory and without the recovery's state
    assert p0 in rig.service.tracker.memory and not rig.service.tracker.state.recovery.departures  # type: ignore[attr-defined]
