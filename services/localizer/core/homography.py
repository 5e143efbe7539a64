"""People on the floor through an image-to-floor homography (a fixed RGB-only camera).

``H`` (3, 3) maps the pixel ``(u, v, 1)`` of a foot point to ``(x, y, w)`` on the floor
plane of its frame; the position is ``(x / w, y / w)``. A calibrated camera has
``H = (K [r1 r2 t])^-1`` (``r1, r2, t`` of the floor -> camera transform), so ``w`` is
``1 / z`` of the floor point in the camera frame up to a positive scale: ``w <= 0`` is
behind the camera, at or above the horizon. :func:`homography_from_camera` builds ``H``
from a known camera; :func:`camera_pose_from_homography` recovers the camera's pose from
``H`` and the intrinsics ``K`` (Zhang, "A flexible new technique for camera
calibration", PAMI 2000), which gives the range and depth of each foot point.

A homography maps the image's own pixels: it cannot model lens distortion, so it should
be fitted on the images as they come (as ``pets09_dev/ground_homography.json`` was).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from common.geometry.transforms import PinholeCamera, RigidTransform
from services.localizer.core.floor import (
    REJECT_ABOVE_HORIZON,
    REJECT_BEYOND_RANGE,
    FloorParams,
    box_indices,
    floor_localization,
    foot_points,
)
from services.localizer.core.localize import Localization

__all__ = [
    "MISMATCH_TOLERANCE",
    "FloorHomography",
    "HomographyPose",
    "camera_pose_from_homography",
    "homography_from_camera",
    "homography_in_frame",
    "localize_on_floor_homography",
]

#: :attr:`HomographyPose.mismatch` above which the intrinsics do not fit the homography.
MISMATCH_TOLERANCE = 0.1


@dataclass(frozen=True)
class FloorHomography:
    """``H`` (3, 3): a foot pixel ``(u, v, 1)`` -> floor ``(x, y, w)``, metres after dividing
    by ``w``; ``image_size`` ``(width, height)`` of the pixels it was fitted in (None: any)."""

    H: np.ndarray
    image_size: tuple[int, int] | None = None

    def __post_init__(self) -> None:
        H = np.asarray(self.H, dtype=np.float64)
        if H.shape != (3, 3) or not np.all(np.isfinite(H)):
            raise ValueError(f"a floor homography is a finite 3x3 matrix, got shape {H.shape}")
        if not np.linalg.cond(H) < 1e12:
            raise ValueError("the floor homography is singular")
        if self.image_size is not None:
            w, h = (int(v) for v in self.image_size)
            if w <= 0 or h <= 0:
                raise ValueError(f"the floor homography's image_size must be positive, got {self.image_size}")
            object.__setattr__(self, "image_size", (w, h))
        object.__setattr__(self, "H", H)

    def for_image(self, width: int, height: int) -> FloorHomography:
        """The homography for ``width`` x ``height`` pixels: itself when that is its size (or
        it has none); scaled when the image is the same view at another resolution
        (pixel coordinates scale with the image); ``ValueError`` when the aspect ratio differs."""
        if self.image_size is None or self.image_size == (width, height):
            return self
        hw, hh = self.image_size
        sx, sy = hw / width, hh / height
        if abs(sx / sy - 1.0) > 0.01:
            raise ValueError(f"the floor homography is for {hw}x{hh} images, this image is {width}x{height} "
                             "(another aspect ratio: another view, not a scaled one)")
        return FloorHomography(self.H @ np.diag([sx, sy, 1.0]), (width, height))

    def to_floor(self, pixels: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Floor points (N, 2) of pixels (N, 2) (NaN where ``w <= 0``) and their ``w`` (N,)."""
        px = np.asarray(pixels, dtype=np.float64).reshape(-1, 2)
        g = px @ self.H[:, :2].T + self.H[:, 2]
        w = g[:, 2]
        ahead = w > 0
        xy = g[:, :2] / np.where(ahead, w, 1.0)[:, None]
        xy[~ahead] = np.nan
        return xy, w

    def jacobians(self, pixels: np.ndarray) -> np.ndarray:
        """``d(x, y)/d(u, v)`` (N, 2, 2) at pixels (N, 2): ``(H[:2, :2] - (x, y) H[2, :2]) / w``."""
        px = np.asarray(pixels, dtype=np.float64).reshape(-1, 2)
        xy, w = self.to_floor(px)
        return (self.H[None, :2, :2] - xy[:, :, None] * self.H[None, 2:3, :2]) / w[:, None, None]


@dataclass(frozen=True)
class HomographyPose:
    """The camera that a homography and intrinsics imply: ``camera_to_floor`` maps camera
    (optical) points into the floor's frame; a foot pixel with third component ``w`` is at
    depth ``scale / w`` along the optical axis; ``mismatch`` is how far ``K^-1 H^-1``'s first
    two columns are from orthogonal and of equal length (``max(| |m1| / |m2| - 1 |, |cos|)``;
    0: they fit, inf: the camera comes out below the floor, a mirrored floor frame)."""

    camera_to_floor: RigidTransform
    scale: float
    mismatch: float


def homography_in_frame(hom: FloorHomography, floor_to_frame: RigidTransform, tol: float = 1e-6) -> np.ndarray | None:
    """``hom.H`` carried into another frame: foot pixel ``(u, v, 1)`` -> ``(x, y, w)`` there, for
    ``floor_to_frame`` a turn about z and a shift (the floor stays level); None when it tilts the
    floor, where the floor's points no longer map to that frame's ``(x, y)`` by a homography."""
    m = floor_to_frame.matrix
    if max(abs(m[2, 0]), abs(m[2, 1]), abs(m[0, 2]), abs(m[1, 2])) > tol:
        return None
    return np.array([[m[0, 0], m[0, 1], m[0, 3]], [m[1, 0], m[1, 1], m[1, 3]], [0.0, 0.0, 1.0]]) @ hom.H


def homography_from_camera(camera: PinholeCamera, camera_to_floor: RigidTransform, floor_z_m: float = 0.0
                           ) -> FloorHomography:
    """The floor homography of an undistorted camera whose pose in the floor's frame is
    ``camera_to_floor``, the floor being ``z = floor_z_m`` there (``w = 1 / z`` in the camera)."""
    if camera.distorted:
        raise ValueError("a homography cannot model lens distortion: give an undistorted camera")
    to_cam = camera_to_floor.inverse()
    r, t = to_cam.rotation_matrix, to_cam.translation
    G = camera.K @ np.column_stack([r[:, 0], r[:, 1], floor_z_m * r[:, 2] + t])
    return FloorHomography(np.linalg.inv(G), (camera.width, camera.height))


def camera_pose_from_homography(hom: FloorHomography, K: np.ndarray, floor_z_m: float = 0.0) -> HomographyPose:
    """The camera's pose in the floor's frame from ``hom`` and intrinsics ``K`` (3, 3) of the
    same pixels: ``K^-1 H^-1 = [r1 r2 t] / scale``, the rotation made orthonormal."""
    M = np.linalg.solve(np.asarray(K, dtype=np.float64), np.linalg.inv(hom.H))
    m1, m2, m3 = M.T
    n1, n2 = float(np.linalg.norm(m1)), float(np.linalg.norm(m2))
    scale = 2.0 / (n1 + n2)
    r1, r2 = scale * m1, scale * m2
    u, _, vt = np.linalg.svd(np.column_stack([r1, r2, np.cross(r1, r2)]))
    rot = u @ vt  # floor -> camera
    if np.linalg.det(rot) < 0:
        rot = u @ np.diag([1.0, 1.0, -1.0]) @ vt
    m = np.eye(4)
    m[:3, :3] = rot.T
    m[:3, 3] = -rot.T @ (scale * m3) + np.array([0.0, 0.0, floor_z_m])
    pose = RigidTransform.from_matrix(m)
    mismatch = max(abs(n1 / n2 - 1.0), abs(float(m1 @ m2)) / (n1 * n2))
    if not pose.translation[2] > floor_z_m:
        mismatch = float("inf")
    return HomographyPose(pose, scale, mismatch)


def localize_on_floor_homography(
    hom: FloorHomography,
    boxes: np.ndarray,
    params: FloorParams,
    width: int,
    height: int,
    pose: HomographyPose | None = None,
    indices: np.ndarray | None = None,
    frame: str = "map",
) -> Localization:
    """Place ``boxes`` (N, 4) of a ``width`` x ``height`` image on the floor ``z = floor_z_m``
    of ``frame``, the homography's frame, through ``hom`` (scaled to the image, or
    ``ValueError``: :meth:`FloorHomography.for_image`).

    The (x, y) covariance is ``J diag(s_u^2, s_v^2) J^T`` with ``J`` the homography's
    Jacobian at the foot point and the foot pixel's variances of each box
    (:func:`~services.localizer.core.floor.foot_variances`). With the camera's ``pose`` (:func:`camera_pose_from_homography`),
    feet farther than ``max_floor_range_m`` from the camera's point on the floor are
    rejected and ``depth_m`` is the foot point's depth; without it there is no range
    check and ``depth_m`` is NaN.
    """
    hom = hom.for_image(width, height)
    boxes = np.asarray(boxes, dtype=np.float64).reshape(-1, 4)
    n = len(boxes)
    idx = box_indices(indices, n)
    pixels, reasons = foot_points(boxes, width, height, (params.foot_bias_u, params.foot_bias_v))
    feet, depth, jac = np.zeros((n, 3)), np.full(n, np.nan), np.zeros((n, 2, 2))
    ok = np.flatnonzero([r is None for r in reasons])
    xy, w = hom.to_floor(pixels[ok])
    ahead = np.isfinite(xy).all(axis=1)
    reach = np.zeros(len(ok))
    if pose is not None:
        reach = np.linalg.norm(xy - pose.camera_to_floor.translation[:2], axis=1)
        depth[ok[ahead]] = pose.scale / w[ahead]
    for k, i in enumerate(ok):
        if not ahead[k]:
            reasons[i] = REJECT_ABOVE_HORIZON
        elif not reach[k] <= params.max_floor_range_m:
            reasons[i] = REJECT_BEYOND_RANGE
    keep = ok[ahead]
    feet[keep, :2], feet[:, 2] = xy[ahead], params.floor_z_m
    jac[keep] = hom.jacobians(pixels[keep])
    return floor_localization(frame, idx, pixels, reasons, feet, depth, jac, params, boxes[:, 3] - boxes[:, 1])
