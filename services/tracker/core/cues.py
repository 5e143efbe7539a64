"""The robust profile's cues (the TU Ilmenau framework's cue fusion) and the measurement
covariance, as pure functions over one frame.

Each cue gives every (detection, track) pair a log-odds that the pair is the same person
(0: no information); the fusion adds them. The functions return what they computed on the
way (the squared Mahalanobis distances of the gate, the squared descriptor distances of
the pairs compared), so nothing is left on the tracker between two steps of a frame.

:func:`usable_covariances` is the project's one test of a detection's covariance: the
tracker service counts the bad ones with it, the cores replace them.
"""

from __future__ import annotations

import numpy as np

__all__ = ["usable_covariances"]


def usable_covariances(covs: np.ndarray) -> np.ndarray:
    """(N,) bool: which covariances (N, 3, 3) are finite, symmetric and positive definite."""
    if not len(covs):
        return np.zeros(0, bool)
    finite = np.all(np.isfinite(covs), axis=(1, 2))
    safe = np.where(finite[:, None, None], covs, np.eye(3))
    sym = 0.5 * (safe + np.swapaxes(safe, 1, 2))
    symmetric = np.all(np.abs(safe - sym) <= 1e-9 + 1e-6 * np.abs(sym), axis=(1, 2))
    return finite & symmetric & np.all(np.linalg.eigvalsh(sym) > 0, axis=1)
