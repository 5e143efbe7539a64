"""The coordinated-turn UKF (services/tracker/core/ukf.py): its exact limits (a straight
line is the constant-velocity Kalman filter, dt = 0 moves nothing, batches equal single
tracks), kalman.update on its 7-entry state, a covariance that stays positive definite,
and tracking quality against the constant-velocity filter on a circle and a line."""

from __future__ import annotations

from typing import Literal

import numpy as np
import pytest

from services.tracker.core import kalman, ukf
from services.tracker.core.robust import RobustParams, RobustTracker

Q_Z = 0.05
SIGMA0 = (0.3, 2.0, 0.5)  # position m, velocity m/s, turn rate rad/s
NOISE = 0.1  # m, std of every measured coordinate
R = np.eye(3) * NOISE**2
HZ = 10.0
DT = 1.0 / HZ


def random_state(rng: np.random.Generator, turn_var: bool = True) -> tuple[np.ndarray, np.ndarray]:
    """A random mean (7,) and symmetric positive definite cov (7, 7); no turn-rate variance
    (or correlation) unless ``turn_var``."""
    mean = np.concatenate([rng.normal(size=3), rng.normal(scale=1.2, size=3), rng.normal(scale=0.5, size=1)])
    a = rng.normal(size=(7, 7)) * 0.3
    cov = a @ a.T + 0.01 * np.eye(7)
    if not turn_var:
        mean[6] = 0.0
        cov[6, :] = cov[:, 6] = 0.0
    return mean, cov


def cv_q(dt: float, q_accel: float) -> np.ndarray:
    return ukf.process_noise(dt, q_accel, Q_Z, 0.0)[:6, :6]


# ------------------------------------------------------------------ exact limits
@pytest.mark.parametrize("dt", [0.01, 0.1, 0.5, 2.0])
def test_process_noise_is_the_robust_profiles(dt: float) -> None:
    q = ukf.process_noise(dt, 3.0, 0.05, 0.2)
    np.testing.assert_allclose(q[:6, :6], RobustTracker(RobustParams(q_accel=3.0, q_z=0.05))._q(dt), rtol=0, atol=1e-15)
    assert q[6, 6] == pytest.approx(0.2 * dt)
    assert not q[6, :6].any() and not q[5].any()


@pytest.mark.parametrize("alpha, kappa", [(1.0, 0.0), (1.0, -3.0), (0.5, 0.0)])
@pytest.mark.parametrize("dt", [0.01, 0.1, 0.5])
def test_without_turning_the_predict_is_the_constant_velocity_kalman_filter(alpha: float, kappa: float,
                                                                            dt: float) -> None:
    rng = np.random.default_rng(1)
    for _ in range(5):
        mean, cov = random_state(rng, turn_var=False)
        m, p = ukf.predict(mean, cov, dt, 0.7, Q_Z, 0.0, alpha=alpha, kappa=kappa)
        m_cv, p_cv = kalman.predict(mean[:6], cov[:6, :6], dt, cv_q(dt, 0.7))
        np.testing.assert_allclose(m[:6], m_cv, rtol=0, atol=1e-9)
        np.testing.assert_allclose(p[:6, :6], p_cv, rtol=0, atol=1e-9)
        assert m[6] == 0.0 and np.abs(p[6]).max() < 1e-9


def test_motion_follows_the_circle_exactly() -> None:
    r, v = 3.0, 1.2
    w = v / r
    state = np.array([r, 0.0, 1.0, 0.0, v, 0.0, w])
    for t in (0.1, 1.0, 5.0):
        moved = ukf.motion(state, t)
        np.testing.assert_allclose(moved, [r * np.cos(w * t), r * np.sin(w * t), 1.0,
                                           -v * np.sin(w * t), v * np.cos(w * t), 0.0, w], atol=1e-12)
    # ten small steps are one big one: the model is exact for a constant turn
    step = state
    for _ in range(10):
        step = ukf.motion(step, 0.5)
    np.testing.assert_allclose(step, ukf.motion(state, 5.0), atol=1e-12)


@pytest.mark.parametrize("w", [0.0, 1e-300, 1e-12, -1e-8, 1e-5, 1e-3, -0.02])
def test_the_straight_line_limit_is_smooth(w: float) -> None:
    vx, vy, dt = 1.1, -0.7, 0.4
    moved = ukf.motion(np.array([0.5, -2.0, 1.0, vx, vy, 0.3, w]), dt)
    th = w * dt
    # Taylor series of sin(th)/th and (1 - cos(th))/th, accurate to 1e-16 for |th| <= 0.01
    f1 = 1 - th**2 / 6 + th**4 / 120
    f2 = th / 2 - th**3 / 24 + th**5 / 720
    np.testing.assert_allclose(moved[:2], [0.5 + dt * (vx * f1 - vy * f2), -2.0 + dt * (vx * f2 + vy * f1)],
                               rtol=0, atol=1e-15)
    np.testing.assert_allclose(moved[3:5], [vx * np.cos(th) - vy * np.sin(th), vx * np.sin(th) + vy * np.cos(th)],
                               rtol=0, atol=1e-15)
    assert moved[5] == 0.0 and moved[6] == w


def test_dt_zero_leaves_the_state_unchanged() -> None:
    mean, cov = random_state(np.random.default_rng(2))
    mean[5] = 0.0
    cov[5, :] = cov[:, 5] = 0.0
    m, p = ukf.predict(mean, cov, 0.0, 3.0, Q_Z, 0.1)
    np.testing.assert_array_equal(m, mean)
    np.testing.assert_array_equal(p, cov)


def test_batched_equals_one_by_one_and_inputs_are_not_mutated() -> None:
    rng = np.random.default_rng(3)
    states = [random_state(rng) for _ in range(5)] + [random_state(rng, turn_var=False)]  # one takes the eigh path
    means = np.stack([m for m, _ in states])
    covs = np.stack([c for _, c in states])
    before = means.copy(), covs.copy()
    bm, bp = ukf.predict(means, covs, 0.3, 0.5, Q_Z, 0.05)
    np.testing.assert_array_equal(means, before[0])
    np.testing.assert_array_equal(covs, before[1])
    for i, (m, c) in enumerate(states):
        om, op = ukf.predict(m, c, 0.3, 0.5, Q_Z, 0.05)
        np.testing.assert_allclose(bm[i], om, rtol=1e-13, atol=1e-14)
        np.testing.assert_allclose(bp[i], op, rtol=1e-13, atol=1e-14)
    # any leading batch shape
    gm, gp = ukf.predict(means.reshape(2, 3, 7), covs.reshape(2, 3, 7, 7), 0.3, 0.5, Q_Z, 0.05)
    np.testing.assert_allclose(gm.reshape(6, 7), bm, rtol=1e-13, atol=1e-14)
    np.testing.assert_allclose(gp.reshape(6, 7, 7), bp, rtol=1e-13, atol=1e-14)


def test_kalman_update_works_unchanged_on_the_7_entry_state() -> None:
    rng = np.random.default_rng(4)
    h = np.hstack([np.eye(3), np.zeros((3, 4))])
    means, covs, zs, rs = [], [], [], []
    for _ in range(4):
        m, c = random_state(rng)
        b = rng.normal(size=(3, 3)) * 0.2
        means.append(m)
        covs.append(c)
        zs.append(m[:3] + rng.normal(size=3) * 0.3)
        rs.append(b @ b.T + 0.01 * np.eye(3))
    new_m, new_p = kalman.update(np.stack(means), np.stack(covs), np.stack(zs), np.stack(rs))
    for i in range(4):
        s = h @ covs[i] @ h.T + rs[i]
        k = covs[i] @ h.T @ np.linalg.inv(s)
        np.testing.assert_allclose(new_m[i], means[i] + k @ (zs[i] - h @ means[i]), atol=1e-12)
        np.testing.assert_allclose(new_p[i], (np.eye(7) - k @ h) @ covs[i], atol=1e-12)
    assert new_m.shape == (4, 7) and new_p.shape == (4, 7, 7)


def test_covariance_stays_symmetric_positive_definite_over_1000_random_steps() -> None:
    rng = np.random.default_rng(5)
    truth = np.array([0.0, 0.0, 1.0, 1.2, 0.0, 0.0, 0.3])
    mean, cov = ukf.initiate(truth[:3], *SIGMA0)
    blind = set(range(400, 520))  # a long occlusion: predicts only
    for step in range(1000):
        dt = float(rng.uniform(0.01, 0.5))
        truth = ukf.motion(truth, dt)
        truth[6] = np.clip(truth[6] + rng.normal(scale=0.3 * np.sqrt(dt)), -1.5, 1.5)
        mean, cov = ukf.predict(mean, cov, dt, 0.3, Q_Z, 0.05)
        if step not in blind and rng.random() < 0.8:
            mean, cov = kalman.update(mean, cov, truth[:3] + rng.normal(scale=NOISE, size=3), R)
        assert np.all(np.isfinite(mean)) and np.all(np.isfinite(cov))
        assert np.abs(cov - cov.T).max() <= 1e-9 * np.abs(cov).max()
        assert not cov[5].any() and not cov[:, 5].any() and mean[5] == 0.0
        sub = cov[np.ix_([0, 1, 2, 3, 4, 6], [0, 1, 2, 3, 4, 6])]
        assert np.linalg.eigvalsh(0.5 * (sub + sub.T)).min() > 0
        assert cov[6, 6] <= 0.5**2 + 1e-12  # max_turn_std
    # it still tracks after all that
    assert np.linalg.norm(mean[:2] - truth[:2]) < 0.5


# ------------------------------------------------------------------ tracking quality
def _walk(kind: Literal["cv", "ukf"], truth: np.ndarray, seed: int, q_accel: float, q_turn: float = 0.01,
          max_turn_std: float | None = 0.5, from_s: float = 3.0) -> tuple[float, float, np.ndarray]:
    """Track ``truth`` (N, 3) seen at 10 Hz with noise. Returns the RMS (x, y) error of the
    filtered position from ``from_s`` on, the RMS error of 1 s coasts (10 predicts with no
    measurement) started every second, and the turn rates estimated, from ``from_s`` on."""
    rng = np.random.default_rng(seed)
    meas = truth + rng.normal(scale=NOISE, size=truth.shape)
    mean, cov = ukf.initiate(meas[0], *SIGMA0)
    if kind == "cv":
        mean, cov = ukf.to_cv(mean, cov)

    def step(m: np.ndarray, c: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        if kind == "cv":
            return kalman.predict(m, c, DT, cv_q(DT, q_accel))
        return ukf.predict(m, c, DT, q_accel, Q_Z, q_turn, max_turn_std=max_turn_std)

    err, coast, omega = [], [], []
    for i in range(1, len(truth)):
        mean, cov = kalman.update(*step(mean, cov), meas[i], R)
        if i < from_s * HZ:
            continue
        err.append(np.linalg.norm(mean[:2] - truth[i, :2]))
        omega.append(mean[6] if kind == "ukf" else np.nan)
        if i % int(HZ) == 0 and i + int(HZ) < len(truth):
            m, c = mean, cov
            for _ in range(int(HZ)):
                m, c = step(m, c)
            coast.append(np.linalg.norm(m[:2] - truth[i + int(HZ), :2]))
    return float(np.sqrt(np.mean(np.square(err)))), float(np.sqrt(np.mean(np.square(coast)))), np.array(omega)


T30 = np.arange(0.0, 30.0, DT)
SPEED, RADIUS = 1.2, 3.0
CIRCLE = np.stack([RADIUS * np.cos(SPEED / RADIUS * T30), RADIUS * np.sin(SPEED / RADIUS * T30),
                   np.ones_like(T30)], axis=1)
LINE = np.stack([SPEED * T30 * 0.8, SPEED * T30 * 0.6, np.ones_like(T30)], axis=1)
Q_GRID = (0.03, 0.1, 0.3, 1.0, 3.0)


def _mean_over_seeds(kind: Literal["cv", "ukf"], truth: np.ndarray, q_accel: float) -> tuple[float, float, np.ndarray]:
    runs = [_walk(kind, truth, seed, q_accel) for seed in range(3)]
    return (float(np.mean([r[0] for r in runs])), float(np.mean([r[1] for r in runs])),
            np.concatenate([r[2] for r in runs]))


def test_a_walk_in_a_circle_is_tracked_and_coasted_better_than_by_the_best_cv_filter() -> None:
    rms, coast, omega = _mean_over_seeds("ukf", CIRCLE, 0.1)
    cv = [_mean_over_seeds("cv", CIRCLE, q) for q in Q_GRID]  # the CV filter at each of its settings
    best_rms, best_coast = min(r[0] for r in cv), min(r[1] for r in cv)
    assert rms < 0.92 * best_rms, (rms, best_rms)
    assert coast < 0.6 * best_coast, (coast, best_coast)
    true_w = SPEED / RADIUS  # 0.4 rad/s
    assert abs(np.mean(omega) - true_w) < 0.03
    assert np.percentile(np.abs(omega - true_w), 90) < 0.1


@pytest.mark.parametrize("q_accel", [0.1, 0.3, 3.0])
def test_a_straight_walk_is_tracked_about_as_well_as_by_the_cv_filter(q_accel: float) -> None:
    rms, coast, omega = _mean_over_seeds("ukf", LINE, q_accel)
    cv_rms, cv_coast, _ = _mean_over_seeds("cv", LINE, q_accel)
    assert rms < 1.05 * cv_rms, (rms, cv_rms)
    assert coast < 1.2 * cv_coast, (coast, cv_coast)
    assert abs(np.mean(omega)) < 0.1


def test_the_turn_rate_cap_keeps_a_person_who_stood_still_for_a_minute_trackable() -> None:
    t = np.arange(0.0, 70.0, DT)
    truth = np.stack([np.where(t < 60.0, 0.0, SPEED * (t - 60.0)), np.zeros_like(t), np.ones_like(t)], axis=1)

    def walk_rms(kind: Literal["cv", "ukf"], cap: float | None) -> float:
        """The RMS error of the walk after the minute standing, over 4 noise draws."""
        return float(np.mean([_walk(kind, truth, seed, 0.1, q_turn=0.1, max_turn_std=cap, from_s=60.0)[0]
                              for seed in range(4)]))

    cv_rms, capped, uncapped = walk_rms("cv", None), walk_rms("ukf", 0.5), walk_rms("ukf", None)
    assert capped < 1.1 * cv_rms, (capped, cv_rms)
    assert uncapped > 2 * capped, (uncapped, capped)  # why the cap exists


# ------------------------------------------------------------------ small API
def test_initiate_and_to_cv() -> None:
    mean, cov = ukf.initiate(np.array([[1.0, 2.0, 0.9], [0.0, 0.0, 1.0]]), 0.3, 2.0, 0.5)
    assert mean.shape == (2, 7) and cov.shape == (2, 7, 7)
    np.testing.assert_array_equal(mean[0], [1, 2, 0.9, 0, 0, 0, 0])
    np.testing.assert_allclose(cov[1], np.diag([0.09, 0.09, 0.09, 4.0, 4.0, 0.0, 0.25]))
    m6, p6 = ukf.to_cv(mean, cov)
    assert m6.shape == (2, 6) and p6.shape == (2, 6, 6)
    m6[0, 0] = 99.0
    assert mean[0, 0] == 1.0  # copies, not views


def test_bad_arguments_fail_with_a_message() -> None:
    mean, cov = ukf.initiate(np.zeros(3), *SIGMA0)
    with pytest.raises(ValueError, match="dt must not be negative"):
        ukf.predict(mean, cov, -0.1, 1.0, Q_Z, 0.1)
    with pytest.raises(ValueError, match="q_turn"):
        ukf.predict(mean, cov, 0.1, 1.0, Q_Z, -0.1)
    with pytest.raises(ValueError, match="mean \\(..., 7\\)"):
        ukf.predict(mean[:6], cov[:6, :6], 0.1, 1.0, Q_Z, 0.1)
    with pytest.raises(ValueError, match="alpha"):
        ukf.predict(mean, cov, 0.1, 1.0, Q_Z, 0.1, kappa=-6.0)
    with pytest.raises(ValueError, match="finite"):
        ukf.predict(np.full(7, np.nan), cov, 0.1, 1.0, Q_Z, 0.1)
    with pytest.raises(ValueError, match="sigma0_turn"):
        ukf.initiate(np.zeros(3), 0.3, 2.0, -1.0)
