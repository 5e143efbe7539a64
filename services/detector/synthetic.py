"""Synthetic RGB-D scenes (a floor and boxes) rendered by ray casting, for tests and benchmarks.

World frame: X right, Y up, Z forward along the floor; the camera sits at height
``camera_height_m`` above the origin and is pitched down by ``tilt_deg``.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

__all__ = ["Block", "render_depth", "scene_intrinsics"]


@dataclass(frozen=True)
class Block:
    """An axis-aligned box standing on the floor: centre (x, z) on the floor, size (w, h, d) in metres."""

    x: float
    z: float
    width: float
    height: float
    depth: float
    shade: int = 60


def scene_intrinsics(width: int = 640, height: int = 480) -> np.ndarray:
    """A pinhole K (3, 3) with a 525 px focal length at 640x480, scaled to ``width``."""
    f = 525.0 * width / 640.0
    return np.array([[f, 0.0, (width - 1) / 2.0], [0.0, f, (height - 1) / 2.0], [0.0, 0.0, 1.0]])


def render_depth(blocks: list[Block], K: np.ndarray, width: int, height: int, camera_height_m: float,
                 tilt_deg: float, max_range_m: float = 10.0) -> tuple[np.ndarray, np.ndarray]:
    """Depth (H, W) float32 metres (NaN where nothing is hit) and a grey-shaded RGB (H, W, 3) uint8."""
    t = np.deg2rad(tilt_deg)
    x_c, y_c, z_c = np.array([1.0, 0, 0]), np.array([0, -np.cos(t), -np.sin(t)]), np.array([0, -np.sin(t), np.cos(t)])
    u, v = np.meshgrid(np.arange(width, dtype=np.float64), np.arange(height, dtype=np.float64))
    rx, ry = (u - K[0, 2]) / K[0, 0], (v - K[1, 2]) / K[1, 1]
    rays = rx[..., None] * x_c + ry[..., None] * y_c + z_c  # world direction whose camera z is 1
    origin = np.array([0.0, camera_height_m, 0.0])
    best = np.full((height, width), np.inf)
    shade = np.full((height, width), 0, np.uint8)
    with np.errstate(divide="ignore", invalid="ignore"):
        floor_t = np.where(rays[..., 1] < 0, -origin[1] / rays[..., 1], np.inf)
    best = np.minimum(best, floor_t)
    shade[np.isfinite(floor_t)] = 170
    for b in blocks:
        lo = np.array([b.x - b.width / 2, 0.0, b.z - b.depth / 2])
        hi = np.array([b.x + b.width / 2, b.height, b.z + b.depth / 2])
        with np.errstate(divide="ignore", invalid="ignore"):
            t1, t2 = (lo - origin) / rays, (hi - origin) / rays
        t_near = np.nanmax(np.minimum(t1, t2), axis=-1)
        t_far = np.nanmin(np.maximum(t1, t2), axis=-1)
        hit = (t_near <= t_far) & (t_near > 0) & (t_near < best)
        best[hit] = t_near[hit]
        shade[hit] = b.shade
    depth = np.where(best < max_range_m, best, np.nan).astype(np.float32)
    rgb = np.repeat(shade[..., None], 3, axis=2)
    return depth, rgb
