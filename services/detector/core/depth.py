"""Basso/Munaro's RGB-D people detector: depth clusters standing on the ground plane.

Per frame: back-project the (sub-sampled) depth image, average it on a voxel grid,
update the ground plane (RANSAC then least squares, started from the previous
estimate, see :mod:`ground`), drop the floor, split the rest into Euclidean clusters,
keep the clusters of person height and project each one to an image box from its top
down to its foot point on the floor. What is left is searched for seated people (a head,
a torso and a seat or lap, :mod:`seated`). HOG can optionally confirm each box. No model
file, no GPU: this is the detector a CPU-only robot runs at frame rate.
"""

from __future__ import annotations

import logging
from dataclasses import replace

import numpy as np
from scipy import ndimage

from services.detector.core.boxes import DetectorError, as_rgb, clip_boxes, empty_result
from services.detector.core.cloud import backproject, cluster_points, voxel_grid
from services.detector.core.depth_params import DepthParams
from services.detector.core.ground import Plane, acquire_plane, initial_plane, refine_plane
from services.detector.core.hog import HogDetector
from services.detector.core import head
from services.detector.core.seated import find_seated

__all__ = ["DEPTH_PERCENTILE", "DepthClusterDetector", "DepthParams", "backproject", "cluster_points", "voxel_grid"]

log = logging.getLogger(__name__)

#: The percentile of a person's point depths reported as their depth: the localizer's default
#: for a box (services/localizer: the person's front, not the wall behind them).
DEPTH_PERCENTILE = 25.0


def _extent(points: np.ndarray) -> float:
    """The largest of the extents of ``points`` (N, 3) along x, y and z: ``np.ptp(points,
    axis=0).max()``, a column at a time (25 times faster than a reduction down the rows)."""
    return max(float(np.ptp(points[:, axis])) for axis in range(3))


def _linked(cells: np.ndarray, tops: np.ndarray, a: int, b: int, level: float) -> bool:
    """Whether points ``a`` and ``b`` lie in one 8-connected region of the floor grid cells
    (``cells`` (N, 2) int) whose highest point (``tops`` (N,)) reaches ``level``."""
    shape = tuple(cells.max(axis=0) + 1)
    grid = np.full(shape, -np.inf)
    np.maximum.at(grid, (cells[:, 0], cells[:, 1]), tops)
    regions, _ = ndimage.label(grid >= level, structure=np.ones((3, 3), bool))
    return bool(regions[tuple(cells[a])] == regions[tuple(cells[b])])


class DepthClusterDetector:
    """People as person-height depth clusters on the ground plane.

    ``detect(rgb, depth, camera)``: ``rgb`` (H, W, 3) uint8, ``depth`` (H, W) float32
    metres registered to it (NaN invalid), ``camera`` (3, 3) K. Returns boxes (N, 4)
    float32 xyxy and scores (N,) float32: the HOG score when ``hog_confirm`` is on,
    otherwise the height plausibility (1 in the middle of the posture's height range, 0.5
    at its ends). The ground plane is state carried from frame to frame (``plane``);
    ``heights``, ``postures`` ("standing" or "sitting") and ``depths`` describe the last
    detections. ``depths`` (m) is each person's own depth, the :data:`DEPTH_PERCENTILE` of
    their points' distance along the optical axis: what the localizer reads in the box, but
    from the person's points alone, so a nearer person overlapping the box cannot pull it.
    ``statures`` (m) is a standing person's top above the floor, their stature (NaN for a
    seated person and where the image's upper edge cuts the head): the tracker's stature cue.
    """

    name = "depth"
    needs_depth = True
    uses_floor = True  # detect() takes the floor from the robot's transforms

    def __init__(self, params: DepthParams | None = None, hog: HogDetector | None = None, seed: int = 0) -> None:
        self.params = params if params is not None else DepthParams()
        self.initial = initial_plane(self.params.camera_height_m, self.params.tilt_deg)
        self.plane = self.initial
        self.plane_inliers = 0
        #: When the transforms' floor has no support in the depth: the floor the depth shows (or None).
        self.depth_floor: Plane | None = None
        self.heights = np.zeros(0)
        self.postures: list[str] = []
        self.depths = np.zeros(0)
        self.statures = np.zeros(0)
        self._hog = hog if hog is not None else (HogDetector() if self.params.hog_confirm else None)
        self._rng = np.random.default_rng(seed)

    def reset(self) -> None:
        """Forget the tracked ground plane (after the head or the floor changed abruptly)."""
        self.plane = self.initial

    def detect(self, rgb: np.ndarray, depth: np.ndarray | None = None,
               camera: np.ndarray | None = None, floor: Plane | None = None) -> tuple[np.ndarray, np.ndarray]:
        """``floor``: the ground plane in the camera frame from the robot's transforms, if known.
        It is refined on the depth (within ``floor_max_deg``/``floor_max_m``) instead of the
        plane tracked from the previous frame: a head that pitches, or a floor hidden by
        furniture for a while, then cannot lead the estimate astray."""
        image = as_rgb(rgb)
        if depth is None:
            raise DetectorError("the depth backend needs a depth image registered to the colour image")
        if camera is None:
            raise DetectorError("the depth backend needs the camera intrinsics K")
        depth = np.asarray(depth, np.float32)
        K = np.asarray(camera, np.float64).reshape(3, 3)
        if depth.shape != image.shape[:2]:
            raise DetectorError(f"depth shape {depth.shape} differs from the image {image.shape[:2]}")
        p = self.params
        points = voxel_grid(backproject(depth, K, p.pixel_step, p.min_depth_m, p.max_depth_m), p.voxel_m)
        self.depth_floor = None
        if floor is not None:
            bounded = replace(p.ground, max_step_deg=p.floor_max_deg, max_step_m=p.floor_max_m)
            self.plane, self.plane_inliers = refine_plane(points, floor, bounded, self._rng)
            if self.plane_inliers == 0:
                # no floor in the depth near the transforms' floor: where is the depth's floor? (a
                # diagnosis for perception doctor, on its own random stream so detection is unchanged)
                found, inliers = acquire_plane(points, self.initial, p.ground, np.random.default_rng(0))
                self.depth_floor = found if inliers else None
        else:
            self.plane, self.plane_inliers = refine_plane(points, self.plane, p.ground, self._rng)
        if self.plane_inliers == 0 and floor is None:
            # Lost (or never found) the floor: search afresh around the configured plane.
            self.plane, self.plane_inliers = acquire_plane(points, self.initial, p.ground, self._rng)
            if self.plane_inliers == 0:
                log.debug("no ground plane found this frame; keeping the previous estimate")
        height = self.plane.height(points)
        above = (height > p.floor_clearance_m) & (height < p.max_point_height_m)
        points, height = points.compress(above, axis=0), height[above]  # compress: 4x a mask's gather
        cut_low = self._at_lower_edge(points, K, depth.shape[0])
        hidden = self._hidden_below(points, K, depth)
        count, labels = cluster_points(points, p.cluster_tolerance_m)
        boxes, scores, heights, postures, depths, statures = [], [], [], [], [], []
        for member, posture, to_floor in self._postured(points, height, cut_low, hidden, count, labels, K, depth):
            top = float(height[member].max())
            if posture == "standing" and head.flat_topped(points[member], height[member], top, self.plane.normal, K,
                                                          depth, p):
                continue  # no head on top: furniture or a wall piece
            cluster = points[member]
            own_depth = float(np.percentile(cluster[:, 2], DEPTH_PERCENTILE))
            if to_floor:  # down to the foot point; a seated person with a hidden lap: what is seen of them
                cluster = np.vstack([cluster, self.plane.project(cluster).mean(axis=0, keepdims=True)])
            box = self._project(cluster, K)
            if box is None:
                continue
            boxes.append(box)
            heights.append(top)
            postures.append(posture)
            depths.append(own_depth)
            # a standing person's top is their stature where it is the top of their head
            statures.append(top if posture == "standing" and head.top_seen(points[member], height[member], top, K, depth,
                                                                            p, sides=True) else np.nan)
            low, high = (p.min_height_m, p.max_height_m) if posture == "standing" else \
                (p.seated.min_height_m, p.seated.max_height_m)
            scores.append(1.0 - 0.5 * min(abs(top - (low + high) / 2) / ((high - low) / 2), 1.0))
        if not boxes:
            self.heights, self.postures, self.depths, self.statures = np.zeros(0), [], np.zeros(0), np.zeros(0)
            return empty_result()
        h, w = image.shape[:2]
        out_boxes = clip_boxes(np.array(boxes), w, h)
        out_scores = np.array(scores)
        heights_arr, postures_arr, depths_arr = np.array(heights), np.array(postures), np.array(depths)
        statures_arr = np.array(statures)
        if self._hog is not None and p.hog_confirm:
            hog_scores = np.array([self._hog.score_window(image, b) for b in out_boxes])
            keep = hog_scores >= p.hog_min_score
            out_boxes, out_scores, heights_arr = out_boxes[keep], hog_scores[keep], heights_arr[keep]
            postures_arr, depths_arr, statures_arr = postures_arr[keep], depths_arr[keep], statures_arr[keep]
        order = np.argsort(-out_scores, kind="stable")
        self.heights, self.postures = heights_arr[order], [str(x) for x in postures_arr[order]]
        self.depths, self.statures = depths_arr[order], statures_arr[order]
        return out_boxes[order], out_scores[order].astype(np.float32)

    def _at_lower_edge(self, points: np.ndarray, K: np.ndarray, rows: int) -> np.ndarray:
        """(N,) bool: points seen within a voxel (and a sampling step) of the image's lower edge."""
        z = np.maximum(points[:, 2], 1e-3)
        v = K[1, 1] * points[:, 1] / z + K[1, 2]
        return v >= rows - 1 - (self.params.pixel_step + K[1, 1] * self.params.voxel_m / z)

    def _hidden_below(self, points: np.ndarray, K: np.ndarray, depth: np.ndarray) -> np.ndarray:
        """(N,) bool: points under which, a voxel and two sampling steps lower in the image,
        the depth is nearer by ``occluder_gap_m``: something in front hides what is below them."""
        p = self.params
        hidden = np.zeros(len(points), bool)
        if p.occluded_max_bottom_m <= 0 or len(points) == 0:
            return hidden
        z = np.maximum(points[:, 2], 1e-3)
        u = np.rint(K[0, 0] * points[:, 0] / z + K[0, 2]).astype(np.int64)
        v = np.rint(K[1, 1] * points[:, 1] / z + K[1, 2] + K[1, 1] * p.voxel_m / z + 2 * p.pixel_step).astype(np.int64)
        rows, cols = depth.shape
        inside = (u >= 0) & (u < cols) & (v >= 0) & (v < rows)
        below = np.full(len(points), np.nan, np.float32)
        below[inside] = depth[v[inside], u[inside]]
        with np.errstate(invalid="ignore"):
            hidden = below < z - p.occluder_gap_m  # NaN (no depth, outside) compares False
        return hidden

    def _is_person(self, member: np.ndarray, points: np.ndarray, height: np.ndarray, cut_low: np.ndarray | None,
                   hidden: np.ndarray) -> bool:
        """Person-like: enough points, a person's height, down to the floor, a person's width,
        not flat. ``cut_low`` (N,) marks the points at the image's lower edge: a whole cluster
        may reach that edge instead of the floor (a person close to the camera, seen from the
        knees up); a part split from a wider cluster (``cut_low`` None) may not. ``hidden``
        (N,) marks the points hidden from below by something nearer: a cluster or part most of
        whose lowest points are hidden need only come down to ``occluded_max_bottom_m`` (a
        person behind a sofa or a table, seen from the waist up)."""
        p = self.params
        if member.sum() < p.min_cluster_points:
            return False
        top = float(height[member].max())
        if not (p.min_height_m <= top <= p.max_height_m and self._grounded(member, height, cut_low, hidden)):
            return False
        feet = self.plane.project(points[member])
        return bool(_extent(feet) <= p.max_width_m and self._thickness(feet) >= p.min_thickness_m)

    def _grounded(self, member: np.ndarray, height: np.ndarray, cut_low: np.ndarray | None,
                  hidden: np.ndarray) -> bool:
        """Whether the cluster comes down to the floor, or to where it is cut or hidden (see _is_person)."""
        p = self.params
        bottom = float(height[member].min())
        if bottom <= p.max_bottom_m or (cut_low is not None and bool(cut_low[member].any())):
            return True
        if bottom > p.occluded_max_bottom_m:
            return False
        return float(hidden[member & (height <= bottom + p.voxel_m)].mean()) >= 0.5

    @staticmethod
    def _thickness(feet: np.ndarray) -> float:
        """Std (m) of floor points (N, 3) across their main direction: the second of the three
        principal spreads (the third is along the plane's normal, ~0)."""
        if len(feet) < 3:
            return 0.0
        spreads = np.linalg.eigvalsh(np.cov((feet - feet.mean(axis=0)).T))
        return float(np.sqrt(max(float(spreads[1]), 0.0)))

    def _postured(self, points: np.ndarray, height: np.ndarray, cut_low: np.ndarray, hidden: np.ndarray,
                  count: int, labels: np.ndarray, K: np.ndarray, depth: np.ndarray) -> list[tuple[np.ndarray, str, bool]]:
        """(member (N,) bool, posture, whether the box goes down to the floor) per person: the
        standing people of :meth:`_people`, then the seated people among the points left."""
        p = self.params
        people = [(member, "standing", True) for member in self._people(points, height, cut_low, hidden, count, labels)]
        if not p.seated.enabled:
            return people
        free = np.ones(len(points), bool)
        for member, _, _ in people:
            free &= ~member
        for s in find_seated(points, height, self.plane.normal, labels, free, K, depth, p.seated,
                             p.min_cluster_points, p.voxel_m, p.pixel_step):
            if s.hidden or self._grounded(s.member, height, cut_low, hidden):
                feet = self.plane.project(points[s.member])
                if np.ptp(feet, axis=0).max() <= p.max_width_m and self._thickness(feet) >= p.min_thickness_m:
                    people.append((s.member, "sitting", not s.hidden))
        return people

    def _people(self, points: np.ndarray, height: np.ndarray, cut_low: np.ndarray, hidden: np.ndarray, count: int,
                labels: np.ndarray) -> list[np.ndarray]:
        """Member masks (N,) bool of the person-like clusters, splitting over-wide ones."""
        p = self.params
        out = []
        ground = self.plane.project(points)
        for label in range(count):
            member = labels == label
            if member.sum() < p.min_cluster_points:
                continue
            heads = self._heads(member, points, ground, height)
            if len(heads) >= 2:  # two people side by side: one part per head
                mine = np.flatnonzero(member)
                to_head = np.linalg.norm(ground[mine, None, :] - heads[None, :, :], axis=2)  # (M, H)
                owner = np.argmin(to_head, axis=1)
                close = to_head[np.arange(len(mine)), owner] <= p.person_radius_m
                for k in range(len(heads)):
                    part = np.zeros_like(member)
                    part[mine[close & (owner == k)]] = True
                    if self._is_person(part, points, height, None, hidden):
                        out.append(part)
                continue
            if self._is_person(member, points, height, cut_low, hidden):
                out.append(member)
                continue
            top = float(height[member].max())
            wide = _extent(ground[member]) > p.max_width_m
            if not (wide and p.min_height_m <= top <= p.max_height_m and self._grounded(member, height, None, hidden)):
                continue
            # Over-wide: split by the parts above furniture height (heads and shoulders).
            upper = member & (height > p.split_height_m)
            idx = np.flatnonzero(upper)
            n_up, up_labels = cluster_points(points[idx], p.cluster_tolerance_m)
            for sub in range(n_up):
                part = idx[up_labels == sub]
                if len(part) < max(3, p.min_cluster_points // 3):
                    continue
                centre = ground[part].mean(axis=0)
                near = member & (np.linalg.norm(ground - centre, axis=1) <= p.person_radius_m)
                if self._is_person(near, points, height, None, hidden):
                    out.append(near)
        return out

    def _heads(self, member: np.ndarray, points: np.ndarray, ground: np.ndarray, height: np.ndarray) -> np.ndarray:
        """Floor positions (H, 3) of the cluster's heads: greedily, its highest points above
        ``min_height_m`` with no higher head within ``head_separation_m`` (none when off)."""
        p = self.params
        top = np.flatnonzero(member & (height >= p.min_height_m))
        if p.head_separation_m <= 0 or len(top) == 0 or float(height[top].max()) > p.max_height_m:
            return np.zeros((0, 3))
        order = top[np.argsort(-height[top], kind="stable")]
        peaks = []  # greedy: the highest point left, then none within head_separation_m of it
        while len(order):
            peaks.append(order[0])
            order = order[np.linalg.norm(ground[order] - ground[order[0]], axis=1) >= p.head_separation_m]
        if len(peaks) < 2:
            return ground[peaks]
        # A head is a peak: the cluster dips (a neck and shoulders, or a gap) between it and
        # every higher head, i.e. on a floor grid of cluster_tolerance_m cells they are apart
        # among the cells whose top reaches the lower one less head_dip_m (Basso/Munaro's height
        # map). The flat top of a wall or of a box has peaks but no dip.
        mine = np.flatnonzero(member)
        normal = self.plane.normal
        e1 = np.cross(normal, [1.0, 0.0, 0.0] if abs(normal[0]) < 0.9 else [0.0, 1.0, 0.0])
        e1 /= np.linalg.norm(e1)
        uv = ground[mine] @ np.column_stack([e1, np.cross(normal, e1)])  # (M, 2) on the floor
        cells = np.floor((uv - uv.min(axis=0)) / p.cluster_tolerance_m).astype(int)
        at = np.searchsorted(mine, peaks)  # the peaks' rows in cells
        heads = [0]
        for n in range(1, len(peaks)):
            if not any(_linked(cells, height[mine], at[n], at[k], min(height[peaks[n]], height[peaks[k]]) - p.head_dip_m)
                       for k in heads):
                heads.append(n)
        return ground[[peaks[k] for k in heads]]

    def _project(self, points: np.ndarray, K: np.ndarray) -> np.ndarray | None:
        """Image box (4,) of ``points`` (N, 3), padded by half a voxel; None if behind the camera."""
        z = points[:, 2]
        if np.any(z <= 1e-3):
            return None
        u = K[0, 0] * points[:, 0] / z + K[0, 2]
        v = K[1, 1] * points[:, 1] / z + K[1, 2]
        pad = K[0, 0] * self.params.voxel_m / 2 / z
        return np.array([(u - pad).min(), (v - pad).min(), (u + pad).max(), (v + pad).max()])
