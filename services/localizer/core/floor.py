"""People on the floor from an RGB-only camera: a box's foot point -> a point on the floor.

Without a depth image the only metric cue in a box is where the person stands: the
foot point, the bottom centre of the box. Its ray from a camera whose pose is known
meets the floor plane (``z = floor_z_m`` of the target frame) at the person's feet
(:func:`localize_on_floor`); a fixed camera can instead be given an image-to-floor
homography (:mod:`services.localizer.core.homography`). Either way the position
reported is the point ``centre_height_m`` above the feet, the height of the body
centre that the depth path reports (the box centre's 3-D point), so both paths give the
tracker the same kind of point.

The covariance is the foot point's pixel uncertainty (a share of the box's height,
``foot_sigma_share_u`` and ``_v``, on top of a pixel's ``foot_sigma_u_px`` and ``_v``: a
detector's box errs in proportion to the box) carried to
the floor to first order through the ray-plane intersection (or the homography's
Jacobian), plus the spread of the body centre's height (``centre_height_sigma_m``) on z.
A pixel at distance ``d`` from a camera ``h`` above the floor moves the foot about
``d^2 / (f h)`` metres along the line of sight, so the covariance grows with distance
as the error really does.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from common.geometry.transforms import PinholeCamera, RigidTransform
from services.localizer.core.localize import REJECT_EMPTY_BOX, REJECT_INVALID_BOX, Localization

__all__ = [
    "REJECT_ABOVE_HORIZON",
    "REJECT_BEYOND_RANGE",
    "REJECT_CAMERA_BELOW_FLOOR",
    "REJECT_FOOT_OUTSIDE_IMAGE",
    "FloorParams",
    "box_indices",
    "floor_covariances",
    "foot_variances",
    "floor_localization",
    "foot_points",
    "localize_on_floor",
]

#: The foot point is not inside the image, or the box reaches its lower edge (the feet are cut off).
REJECT_FOOT_OUTSIDE_IMAGE = "foot_outside_image"
#: The foot point's ray never meets the floor in front of the camera (at or above the horizon).
REJECT_ABOVE_HORIZON = "foot_above_horizon"
#: The feet are farther than ``max_floor_range_m`` from the camera's point on the floor.
REJECT_BEYOND_RANGE = "beyond_floor_range"
#: The camera is not above the floor plane (a wrong ``floor_z_m`` or transform).
REJECT_CAMERA_BELOW_FLOOR = "camera_below_floor"


@dataclass(frozen=True)
class FloorParams:
    """Settings of the floor paths (:func:`localize_on_floor`, the homography's).

    ``floor_z_m``: height of the floor plane in its frame; ``centre_height_m``: how far
    above the feet the reported point is (the body centre, as the depth path reports);
    ``centre_height_sigma_m``: its standard deviation (the z variance);
    ``max_floor_range_m``: farthest foot point kept, horizontally from the camera;
    the foot pixel's standard deviation across (u) and down (v) is
    ``sqrt(foot_sigma_u_px^2 + (foot_sigma_share_u * h)^2)`` for a box ``h`` pixels high (v alike):
    measured on PETS09's HOG boxes against its ground truth (about 0.043 h across, 0.022 to 0.032 h
    down, for boxes 45 to 140 px high; services/localizer/README.md). ``foot_bias_u``,
    ``foot_bias_v``: the detector's mean foot error as a share of the box's height (+: right,
    down; ``perception calibrate-localizer`` measures it), taken off the foot pixel.
    """

    floor_z_m: float = 0.0
    centre_height_m: float = 0.9
    centre_height_sigma_m: float = 0.15
    max_floor_range_m: float = 10.0
    foot_sigma_u_px: float = 1.0
    foot_sigma_v_px: float = 1.0
    foot_sigma_share_u: float = 0.05
    foot_sigma_share_v: float = 0.04
    foot_bias_u: float = 0.0
    foot_bias_v: float = 0.0

    def __post_init__(self) -> None:
        if not np.isfinite(self.floor_z_m):
            raise ValueError(f"floor_z_m must be finite, got {self.floor_z_m}")
        if not 0.0 <= self.centre_height_m <= 3.0:
            raise ValueError(f"centre_height_m must be in [0, 3], got {self.centre_height_m}")
        if not self.max_floor_range_m > 0:
            raise ValueError(f"max_floor_range_m must be > 0, got {self.max_floor_range_m}")
        if not (self.centre_height_sigma_m > 0 and self.foot_sigma_u_px > 0 and self.foot_sigma_v_px > 0):
            raise ValueError("centre_height_sigma_m, foot_sigma_u_px and foot_sigma_v_px must be > 0")
        if not (0 <= self.foot_sigma_share_u < 1 and 0 <= self.foot_sigma_share_v < 1):
            raise ValueError("foot_sigma_share_u and foot_sigma_share_v must be in [0, 1)")
        if not (abs(self.foot_bias_u) < 0.5 and abs(self.foot_bias_v) < 0.5):
            raise ValueError(f"foot_bias_u and foot_bias_v must be in (-0.5, 0.5), got {self.foot_bias_u}, "
                             f"{self.foot_bias_v}")


def foot_points(boxes: np.ndarray, width: int | None = None, height: int | None = None,
                bias: tuple[float, float] = (0.0, 0.0)) -> tuple[np.ndarray, list[str | None]]:
    """Foot points (N, 2) ``((x1 + x2) / 2, y2)`` of boxes (N, 4) ``x1, y1, x2, y2``, less the
    detector's ``bias`` (u, v) times the box's height, and a rejection reason or None per box.

    With the image size given, a box's bottom centre must lie in ``[0, width] x [0, height - 1)``
    (detectors clip their boxes to ``[0, width] x [0, height]``): a box whose bottom
    reaches the image's lower edge has its feet cut off, and its bottom would put the
    person too far away.
    """
    boxes = np.asarray(boxes, dtype=np.float64).reshape(-1, 4)
    pixels = np.column_stack([0.5 * (boxes[:, 0] + boxes[:, 2]), boxes[:, 3]])
    reasons: list[str | None] = [None] * len(boxes)
    for i, (x1, y1, x2, y2) in enumerate(boxes):
        if not np.all(np.isfinite(boxes[i])):
            reasons[i] = REJECT_INVALID_BOX
        elif x2 <= x1 or y2 <= y1:
            reasons[i] = REJECT_EMPTY_BOX
        elif width is not None and height is not None:
            u, v = pixels[i]
            if not (0.0 <= u <= width and 0.0 <= v < height - 1.0):
                reasons[i] = REJECT_FOOT_OUTSIDE_IMAGE
    if bias[0] or bias[1]:
        pixels -= np.asarray(bias, np.float64)[None, :] * (boxes[:, 3] - boxes[:, 1])[:, None]
    return pixels, reasons


def foot_variances(heights_px: np.ndarray, params: FloorParams) -> np.ndarray:
    """The foot pixel's variances (N, 2), across and down, of boxes ``heights_px`` (N,) high."""
    h2 = np.asarray(heights_px, np.float64).reshape(-1, 1) ** 2
    return (np.array([params.foot_sigma_u_px, params.foot_sigma_v_px]) ** 2
            + np.array([params.foot_sigma_share_u, params.foot_sigma_share_v]) ** 2 * h2)


def floor_covariances(jac_xy: np.ndarray, params: FloorParams, heights_px: np.ndarray) -> np.ndarray:
    """Covariances (N, 3, 3) of floor positions whose (x, y) move with the foot pixel as
    ``jac_xy`` (N, 2, 2) ``d(x, y)/d(u, v)``: ``J diag(s_u^2, s_v^2) J^T`` on (x, y), with the
    foot pixel's variances of boxes ``heights_px`` (N,) high (:func:`foot_variances`), and
    ``centre_height_sigma_m^2`` on z."""
    n = len(jac_xy)
    var = foot_variances(heights_px, params)
    cov = np.zeros((n, 3, 3))
    cov[:, :2, :2] = np.einsum("nik,nk,njk->nij", jac_xy, var, jac_xy)
    cov[:, :2, :2] = 0.5 * (cov[:, :2, :2] + np.swapaxes(cov[:, :2, :2], 1, 2))
    cov[:, 2, 2] = params.centre_height_sigma_m**2
    return cov


def floor_localization(frame: str, indices: np.ndarray, pixels: np.ndarray, reasons: list[str | None],
                       feet: np.ndarray, depth_m: np.ndarray, jac_xy: np.ndarray, params: FloorParams,
                       heights_px: np.ndarray) -> Localization:
    """The :class:`Localization` of the boxes whose ``reasons`` are None, from the feet (N, 3) on
    the floor in ``frame``, their optical-axis depths (N,), Jacobians (N, 2, 2) and the boxes'
    heights (N,)."""
    keep = np.array([r is None for r in reasons], dtype=bool)
    positions = feet[keep].reshape(-1, 3).copy()
    positions[:, 2] += params.centre_height_m
    return Localization(
        frame=frame,
        indices=indices[keep],
        pixels=pixels[keep].reshape(-1, 2),
        depth_m=depth_m[keep],
        valid_pixels=np.zeros(int(keep.sum()), dtype=np.int64),
        positions=positions,
        covs=floor_covariances(jac_xy[keep].reshape(-1, 2, 2), params, heights_px[keep]),
        rejected={int(indices[i]): r for i, r in enumerate(reasons) if r is not None},
    )


def box_indices(indices: np.ndarray | None, n: int) -> np.ndarray:
    """``indices`` (n,) as int64, or ``0..n-1`` when None; ``ValueError`` on a length mismatch."""
    idx = np.arange(n) if indices is None else np.asarray(indices, dtype=np.int64).reshape(-1)
    if len(idx) != n:
        raise ValueError(f"{len(idx)} indices for {n} boxes")
    return idx


def localize_on_floor(
    camera: PinholeCamera,
    camera_to_frame: RigidTransform,
    boxes: np.ndarray,
    params: FloorParams,
    indices: np.ndarray | None = None,
    frame: str = "map",
) -> Localization:
    """Place ``boxes`` (N, 4) on the floor ``z = floor_z_m`` of ``frame``, into which
    ``camera_to_frame`` maps camera (optical) points.

    The ray through each foot point (distortion removed) meets the floor at
    ``c + s d`` (``c`` the camera centre, ``d`` the ray in ``frame`` with ``d_z < 0``,
    ``s = (floor_z - c_z) / d_z``); the position is ``centre_height_m`` above it. Its
    (x, y) covariance is ``J diag(s_u^2, s_v^2) J^T`` with
    ``J = s (I - d e_z^T / d_z) R d(ray)/d(u, v)``. ``depth_m`` is the foot point's
    depth along the optical axis (``s``, the ray having z = 1 in the camera frame).
    """
    boxes = np.asarray(boxes, dtype=np.float64).reshape(-1, 4)
    n = len(boxes)
    idx = box_indices(indices, n)
    pixels, reasons = foot_points(boxes, camera.width, camera.height, (params.foot_bias_u, params.foot_bias_v))
    feet, depth, jac = np.zeros((n, 3)), np.full(n, np.nan), np.zeros((n, 2, 2))
    feet[:, 2] = params.floor_z_m
    ok = np.flatnonzero([r is None for r in reasons])
    c, rot = camera_to_frame.translation, camera_to_frame.rotation_matrix
    height = float(c[2]) - params.floor_z_m
    if len(ok) and not height > 0:
        for i in ok:
            reasons[i] = REJECT_CAMERA_BELOW_FLOOR
    elif len(ok):
        d = camera.rays(pixels[ok]) @ rot.T  # (M, 3): the rays in frame, z = 1 in the camera
        down = d[:, 2] < -1e-9
        s = height / -np.where(down, d[:, 2], -1.0)
        reach = np.hypot(s * d[:, 0], s * d[:, 1])
        for k, i in enumerate(ok):
            if not down[k]:
                reasons[i] = REJECT_ABOVE_HORIZON
            elif not reach[k] <= params.max_floor_range_m:
                reasons[i] = REJECT_BEYOND_RANGE
        hit, d, s = ok[down], d[down], s[down]
        if len(hit):
            dd = np.einsum("ij,njk->nik", rot, camera.ray_jacobians(pixels[hit]))  # (K, 3, 2) d(ray)/d(u, v)
            # d(foot)/d(u, v) = s (dd - d dd_z / d_z); its z row is zero
            j = s[:, None, None] * (dd - d[:, :, None] * (dd[:, 2:3, :] / d[:, 2, None, None]))
            feet[hit, :2] = c[:2] + s[:, None] * d[:, :2]
            depth[hit], jac[hit] = s, j[:, :2, :]
    return floor_localization(frame, idx, pixels, reasons, feet, depth, jac, params, boxes[:, 3] - boxes[:, 1])
