"""The Kalman filter of Pinto's thesis (III-C) as pure functions: state ``(x, y, z, vx, vy, vz)``
in the tracking frame, x and y at constant velocity, z a random walk (``vz`` is 0 after every
predict), the position ``(x, y, z)`` measured. No function mutates its inputs; leading batch
dimensions are allowed (``mean`` (..., 6), ``cov`` (..., 6, 6), ``z`` (..., 3), ``R`` (3, 3) or
(..., 3, 3)), so all tracks are predicted or updated at once.
"""

from __future__ import annotations

from functools import lru_cache

import numpy as np

__all__ = ["H", "initiate", "predict", "process_noise", "project", "transition", "update", "white_acceleration"]

#: Measurement matrix: selects (x, y, z) from the state. (3, 6)
H = np.hstack([np.eye(3), np.zeros((3, 3))])


@lru_cache(maxsize=16)
def transition(dt: float) -> np.ndarray:
    """The (6, 6) transition matrix ``A`` for a step of ``dt`` (seconds, or 1 per frame);
    read-only (the steps of a stream repeat: each is built once)."""
    a = np.eye(6)
    a[0, 3] = dt
    a[1, 4] = dt
    a[5, 5] = 0.0  # z is a random walk: vz is reset by every predict
    a.flags.writeable = False
    return a


def process_noise(sigma: np.ndarray, scale: float = 1.0) -> np.ndarray:
    """``Q = diag(sigma**2) * scale`` (6, 6); ``scale`` is the step length in nominal frames."""
    return np.diag(np.asarray(sigma, dtype=np.float64) ** 2 * scale)


def white_acceleration(dt: float, q_accel: float, q_z: float) -> np.ndarray:
    """The (6, 6) process noise of a step ``dt`` in seconds when x and y follow white
    acceleration of spectral density ``q_accel`` (m^2/s^3),
    ``[[dt^3/3, dt^2/2], [dt^2/2, dt]] * q_accel`` on (x, vx) and (y, vy), and z is a random
    walk of ``q_z`` (m^2/s): the robust profile's, in time rather than nominal frames."""
    q = np.zeros((6, 6))
    for i in (0, 1):
        q[i, i] = q_accel * dt ** 3 / 3.0
        q[i, i + 3] = q[i + 3, i] = q_accel * dt ** 2 / 2.0
        q[i + 3, i + 3] = q_accel * dt
    q[2, 2] = q_z * dt
    return q


def initiate(position: np.ndarray, sigma0: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``mean`` (..., 6) and ``cov`` (..., 6, 6) of a new track at ``position`` (..., 3), at rest,
    ``P0 = diag(sigma0**2)``."""
    pos = np.asarray(position, dtype=np.float64)
    mean = np.concatenate([pos, np.zeros_like(pos)], axis=-1)
    cov = np.broadcast_to(np.diag(np.asarray(sigma0, dtype=np.float64) ** 2), pos.shape[:-1] + (6, 6)).copy()
    return mean, cov


def predict(mean: np.ndarray, cov: np.ndarray, dt: float, q: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``x' = A x``, ``P' = A P A^T + Q`` for a step ``dt``; ``q`` is the (6, 6) process noise."""
    if dt < 0:
        raise ValueError(f"dt must not be negative, got {dt}")
    a = transition(dt)
    return mean @ a.T, a @ cov @ a.T + q


def project(cov: np.ndarray, r: np.ndarray) -> np.ndarray:
    """The innovation covariance ``S = H P H^T + R`` (..., 3, 3)."""
    return cov[..., :3, :3] + r


def update(mean: np.ndarray, cov: np.ndarray, z: np.ndarray, r: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The measurement update with position ``z`` (..., 3) and noise ``r``: ``y = z - H x``,
    ``S = H P H^T + R``, ``K = P H^T S^-1``, ``x' = x + K y``, ``P' = (I - K H) P``."""
    s = project(cov, r)
    ph_t = cov[..., :, :3]  # P H^T, (..., 6, 3)
    # K = P H^T S^-1  <=>  K^T = S^-1 (H P)  (S is symmetric)
    k = np.swapaxes(np.linalg.solve(s, np.swapaxes(ph_t, -1, -2)), -1, -2)
    innovation = np.asarray(z, dtype=np.float64) - mean[..., :3]
    new_mean = mean + (k @ innovation[..., None])[..., 0]
    new_cov = cov - k @ cov[..., :3, :]  # (I - K H) P
    return new_mean, new_cov
