"""Ground-plane estimation for the depth detector (Basso/Munaro, section 4.1).

A plane is ``(normal (3,), offset)`` with ``normal . p + offset = height above the
ground`` for a point ``p`` (3,) in the camera optical frame (x right, y down, z forward)
and ``normal`` the unit up vector. Each frame the previous plane selects candidate
floor points; RANSAC finds the dominant plane among them and least squares refines it
on its inliers, so the estimate follows small slope changes and camera oscillations.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

__all__ = ["GroundParams", "Plane", "acquire_plane", "fit_plane_lsq", "initial_plane", "refine_plane"]


@dataclass(frozen=True)
class Plane:
    """Unit up ``normal`` (3,) float64 and ``offset`` so that ``normal . p + offset`` is the height of ``p``."""

    normal: np.ndarray
    offset: float

    def height(self, points: np.ndarray) -> np.ndarray:
        """Signed height above the plane of ``points`` (N, 3): (N,)."""
        return points @ self.normal + self.offset

    def project(self, points: np.ndarray) -> np.ndarray:
        """Feet of ``points`` (N, 3) on the plane: (N, 3)."""
        return points - self.height(points)[:, None] * self.normal[None, :]

    def angle_to(self, other: Plane) -> float:
        """Angle between the two normals in radians."""
        return float(np.arccos(np.clip(self.normal @ other.normal, -1.0, 1.0)))


def initial_plane(camera_height_m: float, tilt_deg: float) -> Plane:
    """The floor seen by a camera ``camera_height_m`` above it, pitched down by ``tilt_deg``."""
    t = np.deg2rad(tilt_deg)
    return Plane(np.array([0.0, -np.cos(t), -np.sin(t)]), float(camera_height_m))


@dataclass(frozen=True)
class GroundParams:
    """Settings of :func:`refine_plane`."""

    window_m: float = 0.25
    inlier_m: float = 0.04
    iterations: int = 60
    max_step_deg: float = 10.0
    max_step_m: float = 0.3
    min_inliers: int = 30
    #: Re-acquisition when tracking is lost: the widest tilt from the configured plane,
    #: the camera heights allowed, and the RANSAC draws.
    acquire_max_deg: float = 35.0
    acquire_height_m: tuple[float, float] = (0.3, 3.0)
    acquire_iterations: int = 200


def fit_plane_lsq(points: np.ndarray, up_hint: np.ndarray) -> Plane | None:
    """Least-squares plane through ``points`` (N, 3), its normal oriented like ``up_hint``."""
    if len(points) < 3:
        return None
    centroid = points.mean(axis=0)
    _, sv, vt = np.linalg.svd(points - centroid, full_matrices=False)
    if sv[1] < 1e-9:
        return None
    normal = vt[2] if vt[2] @ up_hint >= 0 else -vt[2]
    return Plane(normal, float(-normal @ centroid))


def _sample_planes(points: np.ndarray, up: np.ndarray, count: int,
                   rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray]:
    """Planes through ``count`` random point triples of ``points`` (N, 3), all at once.

    Returns unit normals (K, 3) oriented like ``up`` and offsets (K,); degenerate triples
    (collinear points) are left out.
    """
    idx = rng.integers(0, len(points), size=(count, 3))
    a, b, c = points[idx[:, 0]], points[idx[:, 1]], points[idx[:, 2]]
    normals = np.cross(b - a, c - a)
    norms = np.linalg.norm(normals, axis=1)
    ok = norms > 1e-9
    normals, a = normals[ok] / norms[ok, None], a[ok]
    normals *= np.where(normals @ up >= 0, 1.0, -1.0)[:, None]
    return normals, -np.einsum("ij,ij->i", normals, a)


def refine_plane(points: np.ndarray, previous: Plane, params: GroundParams,
                 rng: np.random.Generator) -> tuple[Plane, int]:
    """One update of the ground plane from ``points`` (N, 3); returns (plane, inlier count).

    Candidates are the points within ``window_m`` of ``previous``. RANSAC samples
    ``iterations`` triples at once (vectorised) and keeps the plane with the most points
    within ``inlier_m`` whose normal is within ``max_step_deg`` of the previous one;
    least squares on its inliers gives the result. With too few inliers, or a step
    larger than ``max_step_deg``/``max_step_m``, the previous plane is kept (count 0).
    """
    cand = points.compress(np.abs(previous.height(points)) < params.window_m, axis=0)  # (4x a mask's gather)
    if len(cand) < params.min_inliers:
        return previous, 0
    normals, offsets = _sample_planes(cand, previous.normal, params.iterations, rng)
    keep = normals @ previous.normal >= np.cos(np.deg2rad(params.max_step_deg))
    if not keep.any():
        return previous, 0
    normals, offsets = normals[keep], offsets[keep]
    inliers = np.abs(cand @ normals.T + offsets[None, :]) < params.inlier_m  # (M, K)
    best = int(np.argmax(inliers.sum(axis=0)))
    support = cand.compress(inliers[:, best], axis=0)
    if len(support) < params.min_inliers:
        return previous, 0
    plane = fit_plane_lsq(support, previous.normal)
    if plane is None:
        return previous, 0
    plane_inliers = np.abs(plane.height(cand)) < params.inlier_m
    if plane_inliers.sum() >= 3:
        plane = fit_plane_lsq(cand.compress(plane_inliers, axis=0), previous.normal) or plane
    if plane.angle_to(previous) > np.deg2rad(params.max_step_deg) or abs(plane.offset - previous.offset) > params.max_step_m:
        return previous, 0
    return plane, int(plane_inliers.sum())


def acquire_plane(points: np.ndarray, configured: Plane, params: GroundParams,
                  rng: np.random.Generator) -> tuple[Plane, int]:
    """Find the floor afresh among all ``points`` (N, 3); returns (plane, inlier count).

    Used when :func:`refine_plane` has lost the floor, e.g. because a pan-tilt head
    pitched further than one frame's step. RANSAC keeps the plane with the most points
    within ``inlier_m`` whose normal is within ``acquire_max_deg`` of the configured one
    and whose camera height lies in ``acquire_height_m``; it is refined by least squares.
    Returns ``(configured, 0)`` when none qualifies.
    """
    if len(points) < params.min_inliers:
        return configured, 0
    normals, offsets = _sample_planes(points, configured.normal, params.acquire_iterations, rng)
    lo, hi = params.acquire_height_m
    keep = (normals @ configured.normal >= np.cos(np.deg2rad(params.acquire_max_deg))) & (offsets >= lo) & (offsets <= hi)
    if not keep.any():
        return configured, 0
    normals, offsets = normals[keep], offsets[keep]
    counts = (np.abs(points @ normals.T + offsets[None, :]) < params.inlier_m).sum(axis=0)
    best = int(np.argmax(counts))
    if counts[best] < params.min_inliers:
        return configured, 0
    support = points[np.abs(points @ normals[best] + offsets[best]) < params.inlier_m]
    plane = fit_plane_lsq(support, configured.normal)
    if plane is None or not lo <= plane.offset <= hi:
        return configured, 0
    return plane, int((np.abs(plane.height(points)) < params.inlier_m).sum())
