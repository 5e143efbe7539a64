"""How every view draws a track: the operator's page (``tools.viewer``), Foxglove
(``tools.foxglove``) and the evaluation's plots give an ID the same colour, and the page and
Foxglove label an image box with the same track.

Numpy only: it takes and returns arrays and plain values.
"""

from __future__ import annotations

import numpy as np

__all__ = ["PALETTE", "colour_rgb", "label_boxes", "project_to_image"]

#: Twelve colours that stay apart from each other and readable on a dark background.
PALETTE: tuple[tuple[int, int, int], ...] = (
    (230, 25, 75), (60, 180, 75), (255, 225, 25), (67, 99, 216), (245, 130, 49), (145, 30, 180),
    (70, 240, 240), (240, 50, 230), (188, 246, 12), (250, 190, 190), (0, 128, 128), (220, 190, 255),
)


def colour_rgb(track_id: int) -> tuple[int, int, int]:
    """The colour of ``track_id``: the same in every run and every view (the page, Foxglove,
    the plots); IDs up to twelve apart get different colours."""
    return PALETTE[track_id % len(PALETTE)]


def project_to_image(points: np.ndarray, camera_to_frame: np.ndarray, K: np.ndarray, width: int,
                     height: int) -> np.ndarray:
    """Pixels of ``points`` (N, 3) in the positions' frame, seen by a pinhole camera.

    ``camera_to_frame`` (4, 4) maps camera points (z forward) into that frame, ``K`` (3, 3)
    is the intrinsic matrix. Returns (N, 2) float64 pixels; a point behind the camera or
    outside the image is NaN.
    """
    points = np.asarray(points, np.float64).reshape(-1, 3)
    frame_to_camera = np.linalg.inv(camera_to_frame)
    cam = points @ frame_to_camera[:3, :3].T + frame_to_camera[:3, 3]
    out = np.full((len(points), 2), np.nan)
    ahead = cam[:, 2] > 1e-6
    if ahead.any():
        uvw = cam[ahead] @ np.asarray(K, np.float64).T
        out[ahead] = uvw[:, :2] / uvw[:, 2:3]
    inside = (out[:, 0] >= 0) & (out[:, 0] < width) & (out[:, 1] >= 0) & (out[:, 1] < height)
    out[~inside] = np.nan
    return out


def label_boxes(boxes_xyxy: np.ndarray, pixels: np.ndarray, ids: np.ndarray) -> list[int | None]:
    """Which track each image box shows.

    ``boxes_xyxy`` (N, 4), ``pixels`` (M, 2) the tracks' projected positions (NaN when not
    in the image), ``ids`` (M,). A track labels the box that contains its pixel, the one
    whose centre column is nearest when several do; each box and each track is used once,
    nearest pairs first. Returns N labels, None for a box no track falls in.
    """
    boxes = np.asarray(boxes_xyxy, np.float64).reshape(-1, 4)
    pixels = np.asarray(pixels, np.float64).reshape(-1, 2)
    labels: list[int | None] = [None] * len(boxes)
    if not len(boxes) or not len(pixels):
        return labels
    u, v = pixels[:, 0][None, :], pixels[:, 1][None, :]
    inside = (u >= boxes[:, 0:1]) & (u <= boxes[:, 2:3]) & (v >= boxes[:, 1:2]) & (v <= boxes[:, 3:4])
    cost = np.abs(u - (boxes[:, 0:1] + boxes[:, 2:3]) / 2)
    cost = np.where(inside, cost, np.inf)
    used_tracks: set[int] = set()
    for flat in np.argsort(cost, axis=None):
        b, m = divmod(int(flat), cost.shape[1])
        if not np.isfinite(cost[b, m]):
            break
        if labels[b] is None and m not in used_tracks:
            labels[b] = int(ids[m])
            used_tracks.add(m)
    return labels
