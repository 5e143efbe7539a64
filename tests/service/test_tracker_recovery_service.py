"""The tracker service's ID memory, open-set: a stranger who looks like remembered people does not
inherit an ID, and a recovery taken back is counted (``ids_recovery_undone``) and the remembered
ID's query state says it is not live."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from tests.helpers import tracker_rig
from tests.helpers.tracker_rig import DIM, PERIOD_NS, T0, Rig, config, ids_by_x

_E = np.eye(DIM)
_A = 0.18  # each dark look is 0.25 from the others, under the colour model's t_recover 0.38


def _dark(k: int) -> np.ndarray:
    return (_E[0] + _A * _E[k]) / np.linalg.norm(_E[0] + _A * _E[k])


#: looks 0, 1: two people in dark clothes; 2: a stranger in dark clothes; 3..12: look 0 turning into red (13)
LOOKS = np.stack([_dark(1), _dark(2), _dark(3)] + [(1 - w) * _dark(1) + w * _E[8] for w in np.linspace(0.1, 1.0, 10)]
                 + [_E[8]])
LOOKS /= np.linalg.norm(LOOKS, axis=1, keepdims=True)


@pytest.fixture()
def rig(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> Rig:
    monkeypatch.setattr(tracker_rig, "LOOKS", LOOKS)
    monkeypatch.setattr(tracker_rig, "RNG", np.random.default_rng(0))  # the same noise whatever ran before
    # a public place, where most people confirmed are new (P(new) 0.7): the default 0.3 is a home's
    # prior, where a stranger this alike would get an ID (at 0.5 it depends on the noise)
    return Rig(config(tmp_path, robust={"recovery": {"p_new": 0.7}}))


def test_a_stranger_does_not_inherit_a_remembered_id_and_an_undone_recovery_is_counted(rig: Rig) -> None:
    t, seq = T0, 0

    def walk(n: int, people: list) -> list:  # type: ignore[type-arg]
        nonlocal t, seq
        out = rig.walk(t, n, people, seq)
        t, seq = t + n * PERIOD_NS, seq + n
        return out

    out = walk(20, [(0, (1.0, 0.0, 1.0)), (1, (3.0, 0.0, 1.0))])  # two people in dark clothes, together
    people = ids_by_x(out[-1])
    p0, p1 = people[1], people[3]
    walk(30, [])  # they leave; after max_coast_s they are remembered
    assert {p0, p1} <= set(rig.service.tracker.memory.entries)
    out = walk(10, [(2, (2.0, 1.0, 1.0))])  # a stranger in dark clothes, as near to both
    stranger = ids_by_x(out[-1])[2]
    assert stranger not in (p0, p1) and not rig.extra.get("ids_recovered")
    walk(30, [])
    # someone like the first person, who turns out to wear red as they turn into the light
    out = walk(5, [(0, (1.5, 0.5, 1.0))]) + [m for k in range(3, 14) for m in walk(1, [(k, (1.5, 0.5, 1.0))])]
    out += walk(30, [(13, (1.5, 0.5, 1.0))])
    given = [tr.id for m in out for tr in m.tracks]
    assert given[0] == p0 and rig.extra["ids_recovered"] == 1  # recovered at first ...
    assert rig.extra["ids_recovery_undone"] == 1 and given[-1] not in (p0, p1, stranger)  # ... and taken back
    assert rig.service.ledger._last_state[p0].status == "deleted"  # the remembered ID is not live any more
    assert p0 in rig.service.tracker.memory
