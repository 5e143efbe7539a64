"""The top of a standing person's depth cluster is a head: where it is seen whole, it gives their
stature (:func:`top_seen`), and a flat top wider than a head is furniture (:func:`flat_topped`).

Both read the cluster's *crown*, its points within a voxel of its top, against the depth image
just above it: a shelf, a person in front or the image's edge would hide the head, and then the
top is lower than the head's (a shoulder) and says nothing of its shape. Pure numpy.
"""

from __future__ import annotations

import numpy as np

from services.detector.core.depth_params import DepthParams
from services.detector.core.seated import floor_coordinates

__all__ = ["FLAT_BIN_M", "FLAT_SHARE", "FLAT_TOP_M", "HEAD_HALF_WIDTH_M", "flat_topped", "top_seen"]

#: Half a head's width (m): where :func:`top_seen` looks beside the top.
HEAD_HALF_WIDTH_M = 0.12
#: A flat top (:func:`flat_topped`): along its span, at least this share of bins this wide (m)
#: reach within this much (m) of the top.
FLAT_BIN_M, FLAT_TOP_M, FLAT_SHARE = 0.05, 0.05, 0.8


def top_seen(points: np.ndarray, height: np.ndarray, top: float, K: np.ndarray, depth: np.ndarray,
             p: DepthParams, sides: bool) -> bool:
    """Whether the top of a cluster's ``points`` (camera frame; ``height`` above the floor, highest
    ``top``) is seen: above its crown (a voxel and two sampling steps up in the image, and a voxel
    more) and, with ``sides``, a head's half-width to either side, the image goes on and nothing is
    nearer by ``occluder_gap_m``. The image's edges, a shelf or a person in front would hide the
    head (a person cut by the image's side shows a shoulder), and the top would be lower."""
    crown = points[height >= top - p.voxel_m]
    if len(crown) == 0:
        return False
    z = np.maximum(crown[:, 2], 1e-3)
    u0 = K[0, 0] * crown[:, 0] / z + K[0, 2]
    v0 = K[1, 1] * crown[:, 1] / z + K[1, 2] - K[1, 1] * p.voxel_m / z - 2 * p.pixel_step
    up = K[1, 1] * p.voxel_m / z
    if sides:
        side = K[0, 0] * HEAD_HALF_WIDTH_M / z
        u, v, zz = np.concatenate([u0, u0 - side, u0 + side, u0]), np.concatenate([v0, v0, v0, v0 - up]), np.tile(z, 4)
    else:
        u, v, zz = np.concatenate([u0, u0]), np.concatenate([v0, v0 - up]), np.tile(z, 2)
    u, v = np.rint(u).astype(np.int64), np.rint(v).astype(np.int64)
    rows, cols = depth.shape
    if v.min() < 0 or u.min() < 0 or u.max() >= cols or v.max() >= rows:
        return False  # the image ends beside or above the head: it may lie beyond
    with np.errstate(invalid="ignore"):  # NaN (no depth) is no occluder
        return not bool(np.any(depth[v, u] < zz - p.occluder_gap_m))


def flat_topped(points: np.ndarray, height: np.ndarray, top: float, normal: np.ndarray, K: np.ndarray,
                depth: np.ndarray, p: DepthParams) -> bool:
    """Whether a standing cluster's top, seen whole from above, is a flat slab wider than a head
    (``p.head_max_width_m``; 0: never): a cupboard, a door or a piece of wall, not a person. Its
    points within ``seated.head_depth_m`` of the top (and ``head_separation_m`` of the highest
    point on the floor, the plane's ``normal``) span more than a head, and along that span nearly
    every :data:`FLAT_BIN_M` reaches within :data:`FLAT_TOP_M` of the top. Two heads close
    together also span more than a head, but the top dips between them."""
    if p.head_max_width_m <= 0:
        return False
    upper = height >= top - p.seated.head_depth_m  # only the top's points: the floor coordinates of a few
    uv, up_height = floor_coordinates(points[upper], normal), height[upper]
    peak = int(np.argmax(up_height))
    near = np.hypot(*(uv - uv[peak]).T) < p.head_separation_m
    if near.sum() < 2:
        return False
    centred = uv[near] - uv[near].mean(axis=0)
    _, vectors = np.linalg.eigh(centred.T @ centred)
    along = centred @ vectors[:, -1]
    if float(np.ptp(along)) <= p.head_max_width_m:
        return False
    bins = np.floor((along - along.min()) / FLAT_BIN_M).astype(np.int64)
    profile = np.full(int(bins.max()) + 1, -np.inf)
    np.maximum.at(profile, bins, up_height[near])
    if np.mean(profile >= top - FLAT_TOP_M) < FLAT_SHARE:
        return False  # the top dips: heads, not a slab
    return top_seen(points, height, top, K, depth, p, sides=False)
