"""An unscented Kalman filter with a coordinated-turn motion model, as pure functions.

The option "a UKF beside the constant-velocity Kalman filter, on ground-plane (x, y) with
z as a random walk" (after Basso/Munaro, section 5.1). A UKF around a linear model is just
a Kalman filter, so the motion here is genuinely nonlinear: a person walks at constant speed
along an arc of constant turn rate.

State ``(x, y, z, vx, vy, vz, omega)`` (7), in metres, m/s and rad/s. Over a step ``dt``:

* the velocity ``(vx, vy)`` rotates by ``omega * dt``;
* ``(x, y)`` follows the arc: ``x += (vx sin(w dt) - vy (1 - cos(w dt))) / w`` and
  ``y += (vx (1 - cos(w dt)) + vy sin(w dt)) / w``, written with ``sinc`` so that
  ``w -> 0`` is the straight line with no branch and no cancellation (see :func:`motion`);
* z is a random walk and ``vz`` is 0 after every predict, as in :mod:`kalman`; the
  first six entries keep :mod:`kalman`'s layout, so :func:`to_cv` gives a view's state;
* ``omega`` is a random walk, its standard deviation capped (``max_turn_std``, see
  :func:`predict`).

Process noise (:func:`process_noise`) is added after the transform: white acceleration
``q_accel`` (m^2/s^3) on (x, y), the same matrix as the robust profile's, ``q_z`` (m^2/s)
on z and ``q_turn`` (rad^2/s^3) on omega. With ``omega = 0``, no turn-rate variance and
``q_turn = 0`` the predict is :func:`kalman.predict` with that Q.

Tuning. The turn explains what white acceleration had to absorb on curves, so the model
pays off with a smaller ``q_accel`` than the constant-velocity filter's. Walking a 3 m
circle at 1.2 m/s, seen at 10 Hz with 0.1 m noise, with ``q_accel = 0.1``,
``q_turn = 0.01``, ``sigma0_turn = 0.5``: position RMS error 0.076 m and 1 s coasting
error 0.24 m, against 0.085 m and 0.49 m for the constant-velocity filter at its best
``q_accel``; walking straight it costs 2 % in position and 12 % in coasting at the same
``q_accel``. At ``q_accel = 3`` (the robust profile's default) the two are nearly equal.

The measurement is the position ``(x, y, z)``, a linear function of the state, so the
update is the ordinary Kalman update and is not duplicated here:
:func:`services.tracker.core.kalman.update` (and ``kalman.project``) use only
``mean[..., :3]``, ``cov[..., :3, :3]`` and ``cov[..., :, :3]`` and work unchanged on
this 7-entry state (tested in ``tests/unit/test_tracker_ukf.py``).

Every function takes and returns plain arrays, never mutates its inputs, and accepts
leading batch dimensions: ``mean`` (..., 7), ``cov`` (..., 7, 7). Tracks and sigma points
are vectorised; there is no Python loop over tracks.
"""

from __future__ import annotations

import math
from functools import lru_cache

import numpy as np

from services.tracker.core import kalman

__all__ = ["DIM", "initiate", "motion", "predict", "process_noise", "sigma_weights", "to_cv"]

#: Length of the state ``(x, y, z, vx, vy, vz, omega)``.
DIM = 7
#: The entries that enter the unscented transform. ``vz`` (5) is not one: predict sets it
#: to 0 and nothing depends on it (z is a random walk), so it would only add sigma points.
_UT = np.array([0, 1, 2, 3, 4, 6])
_N_UT = len(_UT)


def initiate(position: np.ndarray, sigma0_position: float, sigma0_velocity: float,
             sigma0_turn: float) -> tuple[np.ndarray, np.ndarray]:
    """A new track at ``position`` (..., 3), standing still and not turning.

    ``cov = diag(sp^2, sp^2, sp^2, sv^2, sv^2, 0, st^2)`` with the three standard
    deviations (m, m/s, rad/s); ``vz`` has no variance, like the robust profile's P0.
    Returns ``mean`` (..., 7) and ``cov`` (..., 7, 7).
    """
    for name, value in (("sigma0_position", sigma0_position), ("sigma0_velocity", sigma0_velocity),
                        ("sigma0_turn", sigma0_turn)):
        if not value >= 0:
            raise ValueError(f"{name} must be >= 0, got {value}")
    pos = np.asarray(position, dtype=np.float64)
    if pos.shape[-1:] != (3,):
        raise ValueError(f"position must be (..., 3), got shape {pos.shape}")
    mean = np.concatenate([pos, np.zeros(pos.shape[:-1] + (4,))], axis=-1)
    diag = np.array([sigma0_position] * 3 + [sigma0_velocity] * 2 + [0.0, sigma0_turn], dtype=np.float64) ** 2
    cov = np.broadcast_to(np.diag(diag), pos.shape[:-1] + (DIM, DIM)).copy()
    return mean, cov


def process_noise(dt: float, q_accel: float, q_z: float, q_turn: float) -> np.ndarray:
    """The (7, 7) process noise of a step ``dt``.

    (x, vx) and (y, vy): white acceleration of spectral density ``q_accel``, z: ``q_z * dt``,
    as the constant-velocity filter's (:func:`kalman.white_acceleration`); omega:
    ``q_turn * dt``; vz: 0.
    """
    q = np.zeros((DIM, DIM))
    q[:6, :6] = kalman.white_acceleration(dt, q_accel, q_z)
    q[6, 6] = q_turn * dt
    return q


def motion(state: np.ndarray, dt: float) -> np.ndarray:
    """The noise-free coordinated turn of ``state`` (..., 7) over ``dt``; returns (..., 7).

    With ``theta = omega * dt``: ``sin(theta) / omega = dt * sinc(theta / 2) cos(theta / 2)``
    and ``(1 - cos(theta)) / omega = dt * sinc(theta / 2) sin(theta / 2)``, where
    ``sinc(u) = sin(u) / u`` and ``sinc(0) = 1`` (from ``sin(theta) = 2 sin cos`` and
    ``1 - cos(theta) = 2 sin^2`` of the half angle). Both are analytic in omega and free of
    cancellation, so the straight line (``omega = 0``) and its neighbourhood need no
    series expansion and no branch other than ``sinc(0)``.
    """
    x, y, z, vx, vy, _, w = np.moveaxis(state, -1, 0)
    half = 0.5 * dt * w
    s_h, c_h = np.sin(half), np.cos(half)
    nonzero = half != 0.0
    sinc_h = np.divide(s_h, half, out=np.ones_like(half), where=nonzero)  # sin(half) / half
    f1, f2 = sinc_h * c_h, sinc_h * s_h  # sin(theta) / theta, (1 - cos(theta)) / theta
    sin_t, cos_t = 2.0 * s_h * c_h, 1.0 - 2.0 * s_h * s_h
    out = np.empty(np.shape(state), dtype=np.float64)
    out[..., 0] = x + dt * (vx * f1 - vy * f2)
    out[..., 1] = y + dt * (vx * f2 + vy * f1)
    out[..., 2] = z
    out[..., 3] = vx * cos_t - vy * sin_t
    out[..., 4] = vx * sin_t + vy * cos_t
    out[..., 5] = 0.0  # z is a random walk: vz is reset by every predict
    out[..., 6] = w
    return out


def sigma_weights(alpha: float = 1.0, beta: float = 2.0, kappa: float = 0.0) -> tuple[np.ndarray, np.ndarray, float]:
    """Van der Merwe's scaled unscented weights for the ``n = 6`` transformed entries.

    ``lambda = alpha^2 (n + kappa) - n``; returns the mean weights (2n+1,), the covariance
    weights (2n+1,) and the spread ``sqrt(n + lambda)`` of the sigma points.

    The defaults ``alpha = 1, beta = 2, kappa = 0`` give ``lambda = 0``: mean weights
    ``0, 1/2n, ...``, covariance weights ``2, 1/2n, ...``. Every covariance weight is then
    non-negative, so the predicted covariance is a sum of positive semi-definite outer
    products plus Q and stays positive definite for any state, however nonlinear the step.
    The popular ``alpha = 1e-3`` gives a centre covariance weight near ``-1e6``, which can
    make the covariance indefinite; ``kappa = 3 - n`` (points at ``sqrt(3)`` standard
    deviations, the Gaussian's kurtosis) keeps the covariance weights non-negative too but
    makes the centre mean weight negative. beta = 2 is optimal for a Gaussian prior.
    """
    wm, wc, spread = _weights(float(alpha), float(beta), float(kappa))
    return wm.copy(), wc.copy(), spread


@lru_cache(maxsize=8)
def _weights(alpha: float, beta: float, kappa: float) -> tuple[np.ndarray, np.ndarray, float]:
    """:func:`sigma_weights`, cached; the arrays are read-only."""
    n = _N_UT
    lam = alpha**2 * (n + kappa) - n
    if not (alpha > 0 and n + lam > 0):
        raise ValueError(f"need alpha > 0 and n + lambda = alpha^2 (n + kappa) > 0 with n = {n}; "
                         f"got alpha={alpha}, kappa={kappa}")
    wm = np.full(2 * n + 1, 0.5 / (n + lam))
    wc = wm.copy()
    wm[0] = lam / (n + lam)
    wc[0] = wm[0] + (1.0 - alpha**2 + beta)
    wm.flags.writeable = wc.flags.writeable = False
    return wm, wc, math.sqrt(n + lam)


def predict(mean: np.ndarray, cov: np.ndarray, dt: float, q_accel: float, q_z: float, q_turn: float, *,
            alpha: float = 1.0, beta: float = 2.0, kappa: float = 0.0,
            max_turn_std: float | None = 0.5) -> tuple[np.ndarray, np.ndarray]:
    """The unscented predict of ``mean`` (..., 7), ``cov`` (..., 7, 7) over ``dt`` seconds.

    Sigma points of the six entries other than ``vz`` (from a Cholesky factor of their
    covariance, see :func:`_sqrt`) go through :func:`motion`; their weighted mean and
    covariance plus :func:`process_noise` are the prediction. ``alpha``, ``beta``,
    ``kappa``: see :func:`sigma_weights`. ``dt = 0`` returns the state unchanged (``vz``
    reset, as ``kalman.predict`` does). Returns ``(mean, cov)``, new arrays.

    ``max_turn_std`` (rad/s, None: no cap) bounds the turn rate's standard deviation by
    scaling its row and column of the covariance (``D P D``, still positive definite).
    While a person stands still nothing observes omega (there is no velocity to turn), so
    its random walk would widen without bound, and sigma points far apart in omega turn
    the velocity every which way: their mean velocity shrinks each step, a drag on a
    person who then walks off. Standing 60 s and then walking 10 s at 1.2 m/s (10 Hz,
    0.1 m noise, ``q_accel = 0.1``, ``q_turn = 0.1``, 8 noise draws), the position RMS
    error of the walk was 0.22 m uncapped, 0.097 m with a cap of 1 rad/s, 0.086 m with
    0.5 rad/s (constant velocity: 0.082 m). While a person walks the filter keeps omega's
    deviation well below 0.5 rad/s and the cap does nothing (a circle, 90 degree corners
    at 1.6 rad/s, a slalom: the same errors with 0.5 and 1 rad/s).
    """
    if not dt >= 0:
        raise ValueError(f"dt must not be negative, got {dt}")
    for name, value in (("q_accel", q_accel), ("q_z", q_z), ("q_turn", q_turn)):
        if not value >= 0:
            raise ValueError(f"{name} must be >= 0, got {value}")
    if max_turn_std is not None and not max_turn_std > 0:
        raise ValueError(f"max_turn_std must be positive or None, got {max_turn_std}")
    wm, wc, spread = _weights(float(alpha), float(beta), float(kappa))
    mean = np.asarray(mean, dtype=np.float64)
    cov = np.asarray(cov, dtype=np.float64)
    if mean.shape[-1:] != (DIM,) or cov.shape != mean.shape + (DIM,):
        raise ValueError(f"need mean (..., 7) and cov (..., 7, 7), got {mean.shape} and {cov.shape}")
    batch = mean.shape[:-1]
    m = mean.reshape(-1, DIM).copy()
    p = cov.reshape(-1, DIM, DIM)
    if not (np.all(np.isfinite(m)) and np.all(np.isfinite(p))):
        raise ValueError("mean and cov must be finite")
    m[:, 5] = 0.0
    if dt == 0:
        p = p.copy()
        p[:, 5, :] = p[:, :, 5] = 0.0
        return m.reshape(mean.shape), p.reshape(cov.shape)
    n = _N_UT
    # sigma points: the mean, then mean +/- spread * (column j of L), L L^T = P of the 6 entries
    offsets = spread * np.swapaxes(_sqrt(p[:, _UT[:, None], _UT]), 1, 2)  # (T, 6, 6), row j: column j of L
    points = np.repeat(m[:, None, :], 2 * n + 1, axis=1)  # (T, 13, 7)
    points[:, 1:n + 1, :5] += offsets[:, :, :5]
    points[:, 1:n + 1, 6] += offsets[:, :, 5]
    points[:, n + 1:, :5] -= offsets[:, :, :5]
    points[:, n + 1:, 6] -= offsets[:, :, 5]
    moved = motion(points, dt)
    new_mean = wm @ moved  # (T, 7)
    dev = moved - new_mean[:, None, :]
    new_cov = np.swapaxes(dev * wc[:, None], 1, 2) @ dev + process_noise(dt, q_accel, q_z, q_turn)
    new_cov = 0.5 * (new_cov + np.swapaxes(new_cov, 1, 2))
    if max_turn_std is not None:  # a congruence D P D: stays positive definite
        var = new_cov[:, 6, 6]
        scale = np.sqrt(max_turn_std**2 / np.maximum(var, max_turn_std**2))
        new_cov[:, 6, :] *= scale[:, None]
        new_cov[:, :, 6] *= scale[:, None]
    return new_mean.reshape(batch + (DIM,)), new_cov.reshape(batch + (DIM, DIM))


def to_cv(mean: np.ndarray, cov: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The constant-velocity part ``(x, y, z, vx, vy, vz)``: ``mean`` (..., 6), ``cov``
    (..., 6, 6), copies, in :mod:`kalman`'s layout, for track views and consumers of it."""
    return np.array(mean[..., :6], dtype=np.float64), np.array(cov[..., :6, :6], dtype=np.float64)


def _sqrt(p: np.ndarray) -> np.ndarray:
    """A square root ``L`` (T, n, n) with ``L L^T = p`` for each covariance in ``p`` (T, n, n).

    The Cholesky factor of the symmetrised matrix. A matrix that is not numerically
    positive definite (a zero turn-rate variance, rounding that made an eigenvalue
    slightly negative) gets ``V sqrt(max(Lambda, 0))`` from its eigendecomposition
    instead: exact for a singular positive semi-definite matrix, with no jitter to bias
    it. Only those matrices take that path, so a track's sigma points do not depend on
    the other tracks in the batch (except for a matrix whose condition number is near
    ``1 / (64 n eps)``, ~1e13, which may take either path; both are square roots).
    """
    p = 0.5 * (p + np.swapaxes(p, -1, -2))
    try:
        return np.linalg.cholesky(p)
    except np.linalg.LinAlgError:
        pass
    eig = np.linalg.eigvalsh(p)
    n = p.shape[-1]
    ok = eig[:, 0] > 64 * n * np.finfo(np.float64).eps * np.maximum(eig[:, -1], np.finfo(np.float64).tiny)
    out = np.empty_like(p)
    if ok.any():
        try:
            out[ok] = np.linalg.cholesky(p[ok])
        except np.linalg.LinAlgError:  # at the threshold's edge: all of them by eigenvalues
            ok[:] = False
    if (~ok).any():
        lam, vec = np.linalg.eigh(p[~ok])
        out[~ok] = vec * np.sqrt(np.clip(lam, 0.0, None))[:, None, :]
    return out
