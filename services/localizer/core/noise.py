"""Measurement covariance of a localized box: axial depth noise plus lateral pixel noise.

Structured-light and time-of-flight RGB-D cameras of the Kinect/Astra class have an
axial (along the optical axis) random error that grows with the square of the distance:
the depth is triangulated from a disparity measured with roughly constant pixel noise,
and ``dz = z^2 / (f b) * dd``. Khoshelham and Elberink (2012, "Accuracy and resolution of
Kinect depth data for indoor mapping applications", Sensors 12(2)) measured
``sigma_z ~= 1.425e-3 * z^2`` m for the Kinect v1 (about 1.4 mm at 1 m, 3.6 cm at 5 m);
Nguyen, Izadi and Lovell (2012, 3DIMPVT) fit ``0.0012 + 0.0019 (z - 0.4)^2`` m.
Basso and Munaro (section 5.1) use the same z^2 growth for their measurement noise.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

__all__ = ["DepthNoiseModel", "point_covariances"]


@dataclass(frozen=True)
class DepthNoiseModel:
    """``sigma_z(z) = axial_a_m + axial_b_per_m * z^2`` and an isotropic pixel sigma.

    ``pixel_sigma_px`` is the standard deviation of the box-centre pixel (detector
    jitter), propagated through the camera model into a lateral error.
    """

    axial_a_m: float = 0.0
    axial_b_per_m: float = 1.425e-3
    pixel_sigma_px: float = 2.0

    def __post_init__(self) -> None:
        if self.axial_a_m < 0 or self.axial_b_per_m < 0 or self.pixel_sigma_px < 0:
            raise ValueError("noise coefficients must be >= 0")

    def axial_sigma(self, z: np.ndarray) -> np.ndarray:
        """Axial standard deviation (N,) m at depths ``z`` (N,) m."""
        z = np.asarray(z, dtype=np.float64)
        return self.axial_a_m + self.axial_b_per_m * z * z


def point_covariances(rays: np.ndarray, ray_jacobians: np.ndarray, z: np.ndarray, model: DepthNoiseModel) -> np.ndarray:
    """Covariances (N, 3, 3) of camera-frame points ``p = z * ray``.

    ``rays`` (N, 3) are z = 1 rays through the box centres, ``ray_jacobians`` (N, 3, 2)
    their derivatives by pixel (u, v), ``z`` (N,) the depths. First-order propagation:
    ``J = [z * dray/du, z * dray/dv, ray]``, ``C = J diag(s_px^2, s_px^2, s_z^2) J^T``.
    """
    z = np.asarray(z, dtype=np.float64)
    jac = np.concatenate([ray_jacobians * z[:, None, None], rays[:, :, None]], axis=2)  # (N, 3, 3)
    s_px2 = model.pixel_sigma_px**2
    var = np.stack([np.full_like(z, s_px2), np.full_like(z, s_px2), model.axial_sigma(z) ** 2], axis=1)  # (N, 3)
    cov = np.einsum("nik,nk,njk->nij", jac, var, jac)
    return 0.5 * (cov + np.transpose(cov, (0, 2, 1)))
