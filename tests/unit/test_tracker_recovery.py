"""The ID memory's open-set decision (services/tracker/core/recovery.py): the posterior over
"someone new" and the remembered candidates, the margin to rivals, reachability, the stranger's
log-odds from the people in view, the online P(new), and that a larger memory is never more eager."""

from __future__ import annotations

import math

import numpy as np
import pytest

from services.tracker.core import recovery as rec
from services.tracker.core.recovery import Departure, RecoveryParams, RecoveryState

P = RecoveryParams()


def test_posterior_is_a_distribution_over_new_and_the_candidates() -> None:
    p_new, post = rec.posterior(np.array([2.0, 0.0, -np.inf]), 0.5)
    assert math.isclose(p_new + post.sum(), 1.0) and post[2] == 0.0
    # prior odds 0.5 : 0.5/3 each; likelihood ratios e^2, 1
    assert math.isclose(post[0] / p_new, math.exp(2.0) / 3) and math.isclose(post[1] / p_new, 1 / 3)
    assert rec.posterior(np.zeros(0), 0.3) == (1.0, pytest.approx(np.zeros(0)))


def test_a_clear_match_is_recovered_and_no_evidence_is_not() -> None:
    assert rec.decide(np.array([4.0, -2.0]), np.ones(2, bool), 0.5, P).index == 0
    none = rec.decide(np.array([0.0, 0.0]), np.ones(2, bool), 0.5, P)  # as likely as anyone: someone new
    assert none.index is None and none.p_new > 0.4


def test_it_refuses_when_the_margin_to_a_rival_is_small() -> None:
    alike = np.array([4.0, 4.0])  # two different people (seen together) the newcomer looks like
    rivals = lambda k: np.arange(2) != k  # noqa: E731
    d = rec.decide(alike, np.ones(2, bool), 0.5, P, rivals=rivals)
    assert d.index is None and d.p < P.p_recover and d.p_new < 0.1  # someone remembered, but not sure who
    near = np.array([4.0, 3.5])  # a slight margin: 0.58 against the rival and "new", refused by a stricter bar
    assert rec.decide(near, np.ones(2, bool), 0.5, P, rivals=rivals).index == 0
    assert rec.decide(near, np.ones(2, bool), 0.5, RecoveryParams(p_recover=0.7), rivals=rivals).index is None
    clear = rec.decide(np.array([4.0, 1.0]), np.ones(2, bool), 0.5, P, rivals=rivals)
    assert clear.index == 0
    # never seen together, the two may be one person remembered twice: either ID is right
    assert rec.decide(alike, np.ones(2, bool), 0.5, P, rivals=lambda k: np.zeros(2, bool)).index == 0


def test_it_refuses_a_candidate_who_could_not_have_walked_there() -> None:
    gone = Departure(stamp=10.0, x=0.0, y=0.0, var=0.01)
    far = rec.reachable(11.0, 8.0, 0.0, 0.01, [gone, None], P)  # 8 m in 1 s; no departure known
    assert far.tolist() == [False, True]
    assert rec.reachable(14.0, 8.0, 0.0, 0.01, [gone], P).tolist() == [True]  # 8 m in 4 s: a brisk walk
    assert rec.reachable(11.0, 2.5 + 3 * math.sqrt(0.02) - 1e-3, 0.0, 0.01, [gone], P).tolist() == [True]
    assert rec.decide(np.array([5.0]), far[:1], 0.5, P).index is None
    assert rec.decide(np.array([5.0]), np.ones(1, bool), 0.5, P).index == 0


@pytest.mark.parametrize("seed", range(5))
def test_a_larger_memory_is_never_more_eager(seed: int) -> None:
    """Whatever the other candidates' evidence, adding one never raises a candidate's support,
    rival or not: its share of the prior thins."""
    rng = np.random.default_rng(seed)
    for _ in range(200):
        k = int(rng.integers(1, 8))
        llr = rng.normal(1.0, 2.5, size=k)
        p_new = float(rng.uniform(0.05, 0.95))
        new_llr = float(rng.uniform(0, 2))
        for rival in (True, False):
            mask = np.ones(k, bool)
            mask[0] = False
            before = rec.support(*rec.posterior(llr, p_new, new_llr), 0, mask)
            more = np.append(llr, rng.normal(1.0, 2.5))
            after = rec.support(*rec.posterior(more, p_new, new_llr), 0, np.append(mask, rival))
            assert after <= before + 1e-12
    # and the same evidence in a memory of 2 and of 50 people: recovered in the first only
    assert rec.decide(np.array([3.0, -3.0]), np.ones(2, bool), 0.5, P).index == 0
    assert rec.decide(np.r_[3.0, np.full(49, -3.0)], np.ones(50, bool), 0.5, P).index is None


def test_the_stranger_log_odds_come_from_the_people_in_view() -> None:
    assert rec.stranger_llr(np.zeros(0)) == 0.0  # nobody to compare with: the calibration stands
    assert rec.stranger_llr(np.array([-3.0, -1.0])) == 0.0  # people unlike the newcomer: never below 0
    crowd = rec.stranger_llr(np.array([3.0, 3.0, 2.5]))  # everyone around looks like the newcomer
    assert crowd > 1.5
    # a match no better than the crowd's is no reason to give a remembered ID
    assert rec.decide(np.array([2.5]), np.ones(1, bool), 0.5, P).index == 0
    assert rec.decide(np.array([2.5]), np.ones(1, bool), 0.5, P, new_llr=crowd).index is None


def test_a_decision_says_whether_anyone_remembered_could_be_the_person() -> None:
    empty = rec.decide(np.zeros(0), np.zeros(0, bool), 0.5, P)  # nobody remembered
    far = rec.decide(np.array([3.0, 1.0]), np.zeros(2, bool), 0.5, P)  # nobody who could have walked here
    assert empty.index is None and far.index is None and not empty.contested and not far.contested
    assert rec.decide(np.array([-2.0, 1.0]), np.array([True, False]), 0.5, P).contested  # a real open-set decision


def test_state_copies_are_independent_and_forgetting_prunes() -> None:
    state = RecoveryState()
    state.departures[1] = Departure(0.0, 0.0, 0.0, 0.1)
    state.seen_together([1, 2, 3])
    copy = state.copy()
    state.seen_together([1, 4])
    state.forget(drop=2)
    assert copy.together[1] == {2, 3} and 2 in copy.together
    assert state.together[1] == {2, 3, 4} and 2 not in state.together
    state.forget(keep={1, 3})
    assert state.together == {1: {3}, 3: {1}} and list(state.departures) == [1]


def test_params_are_checked() -> None:
    with pytest.raises(ValueError):
        RecoveryParams(p_undo=0.6, p_recover=0.5)
    with pytest.raises(ValueError):
        RecoveryParams(p_new=1.0)
    with pytest.raises(ValueError):
        RecoveryParams(max_speed=0.0)


def test_the_config_section_reaches_the_core_and_is_checked() -> None:
    from pydantic import ValidationError

    from services.tracker.config import TrackerConfig

    cfg = TrackerConfig(robust={"recovery": {"p_new": 0.2}})
    assert cfg.robust.recovery.params().p_new == 0.2
    with pytest.raises(ValidationError, match="prior_window"):  # the online P(new) left: never better than 0.3
        TrackerConfig(robust={"recovery": {"prior_window": 20.0}})
    assert TrackerConfig().robust.recovery.params() == RecoveryParams()
    with pytest.raises(ValidationError, match="p_undo"):
        TrackerConfig(robust={"recovery": {"p_undo": 0.6, "p_recover": 0.5}})
    with pytest.raises(ValidationError):
        TrackerConfig(robust={"classifier": {"recover_score": 1.5}})  # gone: the open-set decision replaced it
