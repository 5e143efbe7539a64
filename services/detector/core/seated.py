"""Seated people for the depth detector: a head above a torso above a seat.

Basso/Munaro's rule keeps clusters 1.4-2.3 m tall standing on the floor: a person sitting
on a chair or a sofa has their head 1.1-1.4 m above the floor and is merged with the seat
into one cluster, so it fails. The TU Ilmenau framework classifies a person's posture
(standing, sitting, squatting) from the point cloud; here the posture is read from the
height map and the shape of what is left of each cluster once the standing people are
taken. A seated person is:

- **a head-shaped top** 1.0-1.6 m above the floor (``min_height_m``, ``max_height_m``): a
  peak of the height map (nothing higher within ``head_separation_m`` on the floor) whose
  points down to ``head_depth_m`` below it fit in a head's width (``head_max_width_m``). The
  top of a chair's or a sofa's back, of a table or of a TV is a bar or a slab, wider than
  that, and a seat's top is below 1 m. The head's outline must be seen: left of, right of
  and above it in the image the depth is not nearer by ``outline_gap_m``, and the image goes
  on. A slab seen through a gap between nearer things, or cut by the image's side, is as
  narrow as a head there;
- **shoulders and a torso under it**: the points of the chest band, from ``head_depth_m`` to
  ``chest_depth_m`` below the top and within ``torso_radius_m`` of the head's axis, are at
  least ``torso_min_width_m`` across and ``shoulder_ratio`` times the head's width (a post,
  a loudspeaker or a box is as wide under its top as at it);
- **a seat or a lap beside the torso**: at seat height (``seat_band_m``) something reaches
  ``lap_reach_m`` or more from the head's axis: the thighs and knees forward, or the seat of
  the chair or sofa under them. A narrow standing thing of seated height has nothing there.
  When the torso's column ends above the seat band instead, its lowest points must be hidden
  from below by something nearer by ``hidden_gap_m`` (a table in front, or the chair's back
  when the sitter is seen from behind): the seat and lap cannot be seen, and are not asked for;
- down to the floor, or hidden (as Basso/Munaro's standing rule; :mod:`depth` checks that
  and the footprint's width and flatness).

Known limit: a chair's back that reaches within ``head_depth_m`` of the sitter's head top (a
wing chair, for a short sitter) makes the head look as wide as the back.

Pure numpy: everything is computed on the voxel centroids the detector already has.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

__all__ = ["Seated", "SeatedParams", "find_seated", "floor_coordinates", "hidden_below", "outline_seen", "seated_at"]


@dataclass(frozen=True)
class SeatedParams:
    """Settings of :func:`find_seated` (see the module's docstring)."""

    #: Look for seated people among what the standing rule left (False: Basso/Munaro's rule alone).
    enabled: bool = True
    #: A seated person's head top, above the floor (m): 1.1-1.4 m for adults on a 0.4-0.5 m seat.
    min_height_m: float = 1.0
    max_height_m: float = 1.6
    #: A peak of the height map: nothing higher within this on the floor (m; on a grid of half this).
    head_separation_m: float = 0.4
    #: The head: the points within this below the top (m) ...
    head_depth_m: float = 0.2
    #: ... fit within this on the floor (m): a head is ~0.2 m across; a chair's back ~0.45 m.
    head_max_width_m: float = 0.35
    #: The chest band reaches down to this below the top (m) ...
    chest_depth_m: float = 0.5
    #: ... within this of the head's axis on the floor (m) ...
    torso_radius_m: float = 0.3
    #: ... and is at least this wide on the floor (m): a chest is ~0.25 m deep, ~0.4 m across ...
    torso_min_width_m: float = 0.2
    #: ... and this many times as wide as the head: the shoulders (~0.4 m across, ~0.25 m deep
    #: with the arm from the side) are wider than the head (~0.15 m across, ~0.2 m long). The
    #: top of a post, a box or a slab is as wide as what is under it.
    shoulder_ratio: float = 1.25
    #: Seat and lap heights above the floor (m).
    seat_band_m: tuple[float, float] = (0.3, 0.75)
    #: At seat height something reaches this far from the head's axis on the floor (m).
    lap_reach_m: float = 0.3
    #: ... looked for within this of the head's axis (m): knees and feet are ~0.5 m forward.
    reach_radius_m: float = 0.8
    #: The seated person's points (their box): within this of the head's axis on the floor (m).
    person_radius_m: float = 0.45
    #: The head's outline is hidden where the depth beside it is nearer by this (m).
    outline_gap_m: float = 0.25
    #: The torso's lowest points are hidden where the depth below them is nearer by this (m):
    #: a chair's back just behind the sitter hides their hips ~0.1 m nearer, a table more.
    hidden_gap_m: float = 0.05

    def __post_init__(self) -> None:
        if not 0 < self.min_height_m < self.max_height_m:
            raise ValueError(f"seated: need 0 < min_height_m < max_height_m, got {self.min_height_m}, "
                             f"{self.max_height_m}")
        if not self.seat_band_m[0] < self.seat_band_m[1] < self.min_height_m:
            raise ValueError(f"seated: the seat band {self.seat_band_m} must lie below min_height_m")


@dataclass(frozen=True)
class Seated:
    """A seated person: ``member`` (N,) bool over the detector's points, the head's ``top``
    height (m), and ``hidden``: their lap is hidden from the camera (their box then ends at
    what is seen of them instead of the floor)."""

    member: np.ndarray
    top: float
    hidden: bool


def floor_coordinates(points: np.ndarray, normal: np.ndarray) -> np.ndarray:
    """(N, 2) coordinates of ``points`` (N, 3) on a plane with unit ``normal`` (3,): two axes across it."""
    e1 = np.cross(normal, [1.0, 0.0, 0.0] if abs(normal[0]) < 0.9 else [0.0, 1.0, 0.0])
    e1 /= np.linalg.norm(e1)
    return points @ np.column_stack([e1, np.cross(normal, e1)])


def _peaks(uv: np.ndarray, height: np.ndarray, low: float, high: float, separation: float,
           cell: float) -> list[int]:
    """Indices of the height map's peaks between ``low`` and ``high``: the points highest on a
    floor grid of ``cell`` m within ``separation`` around them (a square of cells; Basso/Munaro's
    height map), then greedily the highest left with no other within ``separation`` on the floor."""
    ij = np.floor((uv - uv.min(axis=0)) / cell).astype(np.int64)
    shape = tuple(ij.max(axis=0) + 1)
    top = np.full(shape, -np.inf)
    np.maximum.at(top, (ij[:, 0], ij[:, 1]), height)
    r = int(np.ceil(separation / cell))
    rows = np.pad(top, ((r, r), (0, 0)), constant_values=-np.inf)
    around = rows[: shape[0]].copy()  # the highest within r cells, along one axis then the other
    for k in range(1, 2 * r + 1):
        np.maximum(around, rows[k:k + shape[0]], out=around)
    cols = np.pad(around, ((0, 0), (r, r)), constant_values=-np.inf)
    around = cols[:, : shape[1]].copy()
    for k in range(1, 2 * r + 1):
        np.maximum(around, cols[:, k:k + shape[1]], out=around)
    order = np.flatnonzero((height >= low) & (height <= high) & (height >= around[ij[:, 0], ij[:, 1]]))
    order = order[np.argsort(-height[order], kind="stable")]
    peaks = []
    while len(order):
        peaks.append(int(order[0]))
        order = order[np.hypot(*(uv[order] - uv[order[0]]).T) >= separation]
    return peaks


def _width(uv: np.ndarray) -> float:
    """The largest extent (m) of floor points (K, 2) along their main direction (0 for < 2 points)."""
    if len(uv) < 2:
        return 0.0
    centred = uv - uv.mean(axis=0)
    _, vectors = np.linalg.eigh(centred.T @ centred)
    return float(np.ptp(centred @ vectors[:, -1]))


def _pixels(points: np.ndarray, K: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Image columns u, rows v (float) and depths z of camera-frame ``points`` (K, 3)."""
    z = np.maximum(points[:, 2], 1e-3)
    return K[0, 0] * points[:, 0] / z + K[0, 2], K[1, 1] * points[:, 1] / z + K[1, 2], z


def _depth_at(depth: np.ndarray, u: np.ndarray, v: np.ndarray) -> np.ndarray:
    """Depth (K,) at the pixels nearest (u, v), NaN outside the image."""
    col, row = np.rint(u).astype(np.int64), np.rint(v).astype(np.int64)
    rows, cols = depth.shape
    inside = (col >= 0) & (col < cols) & (row >= 0) & (row < rows)
    out = np.full(len(u), np.nan, np.float32)
    out[inside] = depth[row[inside], col[inside]]
    return out


def outline_seen(points: np.ndarray, K: np.ndarray, depth: np.ndarray, pad_m: float, step_px: int,
                 gap_m: float) -> bool:
    """Whether the image left of, right of and above ``points`` (K, 3) in the camera frame (a
    head), by ``pad_m`` at their depth and ``step_px`` pixels, is inside the image and nowhere
    nearer than them by ``gap_m``."""
    u, v, z = _pixels(points, K)
    pad = K[0, 0] * pad_m / z + step_px
    rows, cols = depth.shape
    for col, row in ((u - pad, v), (u + pad, v), (u, v - pad)):
        if np.any((col < -0.5) | (col > cols - 0.5) | (row < -0.5) | (row > rows - 0.5)):
            return False  # cut by the image's side or top
        with np.errstate(invalid="ignore"):
            if np.any(_depth_at(depth, col, row) < float(z.min()) - gap_m):  # NaN (no depth) compares False
                return False
    return True


def hidden_below(points: np.ndarray, K: np.ndarray, depth: np.ndarray, pad_m: float, step_px: int,
                 gap_m: float) -> np.ndarray:
    """(K,) bool: ``points`` (K, 3) under which in the image, ``pad_m`` at their depth and two
    ``step_px`` lower, the depth is nearer by ``gap_m``: something in front hides what is below."""
    u, v, z = _pixels(points, K)
    with np.errstate(invalid="ignore"):
        return _depth_at(depth, u, v + K[1, 1] * pad_m / z + 2 * step_px) < z - gap_m  # NaN compares False


def seated_at(peak: int, uv: np.ndarray, height: np.ndarray, params: SeatedParams) -> tuple[bool, np.ndarray | None]:
    """Whether the cluster points (``uv`` (K, 2) on the floor, ``height`` (K,)) around the
    height map's peak ``peak`` have a seated person's shape above the seat; and, when no
    seat or lap is seen beside the torso, the lowest points of the torso's column (K,) bool,
    which must then be hidden from below (None when the seat or the lap is seen)."""
    p = params
    top = float(height[peak])
    if not p.min_height_m <= top <= p.max_height_m:
        return False, None
    axis = np.hypot(*(uv - uv[peak]).T)
    head = (axis < p.head_separation_m) & (height >= top - p.head_depth_m)
    head_width = _width(uv[head])
    if head_width > p.head_max_width_m:
        return False, None
    column = axis <= p.torso_radius_m
    chest = column & (height < top - p.head_depth_m) & (height >= top - p.chest_depth_m)
    if _width(uv[chest]) < max(p.torso_min_width_m, p.shoulder_ratio * head_width):
        return False, None
    seat = (axis <= p.reach_radius_m) & (height >= p.seat_band_m[0]) & (height <= p.seat_band_m[1])
    if seat.any() and float(axis[seat].max()) >= p.lap_reach_m:
        return True, None
    bottom = float(height[column].min())
    if bottom <= p.seat_band_m[0]:
        return False, None  # the column comes down to the floor with nothing beside it at seat height
    return True, column & (height <= bottom + p.head_depth_m / 2)


def find_seated(points: np.ndarray, height: np.ndarray, normal: np.ndarray, labels: np.ndarray, free: np.ndarray,
                K: np.ndarray, depth: np.ndarray, params: SeatedParams, min_points: int, voxel_m: float,
                step_px: int) -> list[Seated]:
    """Seated people among the detector's points (N, 3) in the camera frame (``K`` (3, 3),
    ``depth`` (H, W) metres, sampled every ``step_px`` pixels on ``voxel_m`` voxels) above the
    floor (``height`` (N,), the floor's unit ``normal`` (3,)), clustered (``labels`` (N,)), of
    which ``free`` (N,) bool are not yet a person's. Each person's ``member`` holds the free
    points of their cluster within ``person_radius_m`` of their head's axis, at least
    ``min_points`` of them."""
    p = params
    out: list[Seated] = []
    if not p.enabled or not free.any():
        return out
    upper = free & (height >= p.min_height_m)  # what can be a head, or stand higher than one
    labelled = np.unique(labels[upper & (height <= p.max_height_m)])
    if len(labelled) == 0:
        return out
    floor_uv = floor_coordinates(points, normal)
    for label in labelled:
        mine = labels == label
        idx = np.flatnonzero(free & mine)
        if len(idx) < min_points:
            continue
        top = np.flatnonzero(upper & mine)
        peaks = _peaks(floor_uv[top], height[top], p.min_height_m, p.max_height_m, p.head_separation_m,
                       p.head_separation_m / 2)
        if not peaks:
            continue
        uv, h = floor_uv[idx], height[idx]
        for peak in np.searchsorted(idx, top[peaks]):
            ok, lowest = seated_at(int(peak), uv, h, p)
            if not ok:
                continue
            if lowest is not None and hidden_below(points[idx[lowest]], K, depth, voxel_m, step_px,
                                                   p.hidden_gap_m).mean() < 0.5:
                continue
            axis = np.hypot(*(uv - uv[peak]).T)
            head = idx[(axis < p.head_separation_m) & (h >= h[peak] - p.head_depth_m)]
            if not outline_seen(points[head], K, depth, voxel_m, step_px, p.outline_gap_m):
                continue
            mine = idx[axis <= p.person_radius_m]
            if len(mine) < min_points:
                continue
            member = np.zeros(len(points), bool)
            member[mine] = True
            out.append(Seated(member, float(h[peak]), lowest is not None))
    return out
