"""Synthetic depth images of people standing in front of a wall, with their true positions.

Used by the tests and the benchmark: every pixel's ray is intersected with a
person-shaped silhouette (head, torso, legs) on a fronto-parallel plane at the
person's depth; the other pixels see a wall farther away.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from common.geometry import PinholeCamera

__all__ = ["Person", "render_depth", "person_box"]


@dataclass(frozen=True)
class Person:
    """A person whose body centre is at ``center`` (3,) in the camera frame (z = depth, y down)."""

    center: tuple[float, float, float]
    height_m: float = 1.75
    width_m: float = 0.5


def _silhouette(x: np.ndarray, y: np.ndarray, p: Person) -> np.ndarray:
    """Whether plane points (x, y), relative to the body centre, are on the person."""
    h, w = p.height_m, p.width_m
    head_r = 0.065 * h
    head_cy = -0.5 * h + head_r
    head = (x / (0.8 * head_r)) ** 2 + ((y - head_cy) / head_r) ** 2 <= 1.0
    torso = (np.abs(x) <= 0.5 * w) & (y >= head_cy + head_r) & (y <= 0.05 * h)
    legs = (np.abs(x) <= 0.4 * w) & (np.abs(x) >= 0.03 * w) & (y > 0.05 * h) & (y <= 0.5 * h)
    return head | torso | legs


def render_depth(camera: PinholeCamera, people: list[Person], wall_m: float = 7.0) -> np.ndarray:
    """(H, W) float32 depth in metres: the people (nearest wins) in front of a wall at ``wall_m``."""
    v, u = np.mgrid[0 : camera.height, 0 : camera.width]
    rays = camera.rays(np.column_stack([u.ravel(), v.ravel()]).astype(np.float64))
    depth = np.full(len(rays), wall_m, dtype=np.float64)
    for p in sorted(people, key=lambda q: -q.center[2]):
        cx, cy, cz = p.center
        on = _silhouette(rays[:, 0] * cz - cx, rays[:, 1] * cz - cy, p)
        depth[on] = cz
    return depth.reshape(camera.height, camera.width).astype(np.float32)


def person_box(camera: PinholeCamera, p: Person) -> np.ndarray:
    """(4,) box ``x1, y1, x2, y2`` centred on the projection of the body centre.

    Its half-sizes are the largest distances from that pixel to the projected outline,
    so the box holds the whole silhouette even under lens distortion.
    """
    cx, cy, cz = p.center
    hw, hh = 0.5 * p.width_m, 0.5 * p.height_m
    t = np.linspace(-1.0, 1.0, 21)
    outline = np.concatenate(
        [
            np.column_stack([cx + hw * t, np.full_like(t, cy - hh)]),
            np.column_stack([cx + hw * t, np.full_like(t, cy + hh)]),
            np.column_stack([np.full_like(t, cx - hw), cy + hh * t]),
            np.column_stack([np.full_like(t, cx + hw), cy + hh * t]),
        ]
    )
    pts = np.column_stack([outline, np.full(len(outline), cz)])
    px = camera.project(pts)
    c = camera.project(np.array([[cx, cy, cz]]))[0]
    half = np.abs(px - c).max(axis=0)
    return np.array([c[0] - half[0], c[1] - half[1], c[0] + half[0], c[1] + half[1]])
