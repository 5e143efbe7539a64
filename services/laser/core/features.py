"""Each segment's shape as numbers, computed for all segments of a scan at once.

The first 16 are Leigh et al.'s (ICRA 2015, Table I; as their ``cluster_features.cpp`` computes
them, less the radius it always sets to 0), most of them from Arras et al.'s boosted features
(ICRA 2007). The rest are this project's, chosen to hold across scanners and ranges: the fitted
circle's radius, how far the middle of the segment bulges towards the scanner, the gaps to the
neighbouring beams, and the width against the width its beams span at that range.
"""

from __future__ import annotations

import numpy as np

from services.laser.core.scan import Beams
from services.laser.core.segments import Segments

__all__ = ["BACKGROUND", "LEIGH", "MODEL", "MODEL_COLUMNS", "NAMES", "features"]

#: Leigh et al.'s features, in their order.
LEIGH = ("n_points", "std", "avg_median_dev", "width", "linearity", "circularity", "boundary_length",
         "boundary_regularity", "mean_curvature", "mean_angular_difference", "iav", "std_iav", "distance",
         "distance_per_point", "occluded_right", "occluded_left")
#: This project's, after them.
OURS = ("circle_radius", "bulge", "jump_near", "jump_far", "width_per_span", "beam_gap")
NAMES = LEIGH + OURS
#: What depends on the scan beside the segment, not on the segment: in Leigh et al.'s training
#: scans most legs have no return beside them (an open hall past the range) while the empty rooms
#: have walls, so a classifier that reads these learns the recording, and misses a person in
#: front of a wall (benchmarks/legs.py, "background filled"). Computed, never classified on.
BACKGROUND = ("occluded_right", "occluded_left", "jump_near", "jump_far")
#: The features the leg classifier reads, and their columns in :func:`features`.
MODEL = tuple(n for n in NAMES if n not in BACKGROUND)
MODEL_COLUMNS = [NAMES.index(n) for n in MODEL]


def _sum(v: np.ndarray, where: np.ndarray, seg: np.ndarray, n: int) -> np.ndarray:
    """Per segment, the sum of ``v`` over the entries where ``where`` holds."""
    return np.bincount(seg[where], weights=v[where], minlength=n)


def _median(v: np.ndarray, s: Segments) -> np.ndarray:
    order = np.lexsort((v, s.seg))
    sv = v[order]
    return 0.5 * (sv[s.starts + (s.counts - 1) // 2] + sv[s.starts + s.counts // 2])


def _angle(ax: np.ndarray, ay: np.ndarray, bx: np.ndarray, by: np.ndarray) -> np.ndarray:
    """The angle from vector b to vector a in [0, 2 pi)."""
    th = np.arctan2(ax * by - ay * bx, ax * bx + ay * by)
    return np.where(th < 0, th + 2 * np.pi, th)


def _spread(x: np.ndarray, y: np.ndarray, s: Segments, n: np.ndarray) -> tuple[np.ndarray, ...]:
    k = len(s)
    mx, my = np.bincount(s.seg, x, k) / n, np.bincount(s.seg, y, k) / n
    dx, dy = x - mx[s.seg], y - my[s.seg]
    sxx, syy, sxy = np.bincount(s.seg, dx * dx, k), np.bincount(s.seg, dy * dy, k), np.bincount(s.seg, dx * dy, k)
    std = np.sqrt((sxx + syy) / (n - 1))
    half = 0.5 * (sxx - syy)
    linearity = np.maximum(0.5 * (sxx + syy) - np.sqrt(half * half + sxy * sxy), 0.0)
    medx, medy = _median(x, s), _median(y, s)
    med_dev = np.bincount(s.seg, np.hypot(x - medx[s.seg], y - medy[s.seg]), k) / n
    return mx, my, std, linearity, medx, medy, med_dev


def _circle(x: np.ndarray, y: np.ndarray, s: Segments, n: np.ndarray, mx: np.ndarray,
            my: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Kasa's least-squares circle (centred on the segment's mean, for conditioning): its
    radius and the sum of squared radial residuals."""
    k = len(s)
    u, v = x - mx[s.seg], y - my[s.seg]
    suu, svv, suv = np.bincount(s.seg, u * u, k), np.bincount(s.seg, v * v, k), np.bincount(s.seg, u * v, k)
    q = u * u + v * v
    a = np.stack([np.stack([suu, suv], -1), np.stack([suv, svv], -1)], -2)
    rhs = 0.5 * np.stack([np.bincount(s.seg, u * q, k), np.bincount(s.seg, v * q, k)], -1)
    det = suu * svv - suv * suv
    ok = det > 1e-12 * np.maximum(suu + svv, 1e-12) ** 2
    safe = np.where(ok[:, None, None], a, np.eye(2))
    c = np.linalg.solve(safe, rhs[..., None])[..., 0]
    cu, cv = np.where(ok, c[:, 0], 0.0), np.where(ok, c[:, 1], 0.0)
    rc = np.sqrt(cu * cu + cv * cv + np.bincount(s.seg, q, k) / n)
    resid = rc[s.seg] - np.hypot(u - cu[s.seg], v - cv[s.seg])
    circ = np.bincount(s.seg, resid * resid, k)
    big = 10.0  # points on a line: a circle as large as a room fits them
    return np.where(ok, np.minimum(rc, big), big), np.where(ok, circ, 0.0)


def _boundary(x: np.ndarray, y: np.ndarray, s: Segments, n: np.ndarray) -> tuple[np.ndarray, ...]:
    k = len(s)
    same = s.seg[1:] == s.seg[:-1]
    step = np.hypot(np.diff(x), np.diff(y))
    length = _sum(step, same, s.seg[:-1], k)
    sq = _sum(step * step, same, s.seg[:-1], k)
    regularity = np.sqrt(np.maximum(sq - length ** 2 / n, 0.0) / (n - 1))
    # triplets right (i), mid (i + 1), left (i + 2)
    tri = s.seg[2:] == s.seg[:-2]
    mlx, mly = x[2:] - x[1:-1], y[2:] - y[1:-1]
    mrx, mry = x[:-2] - x[1:-1], y[:-2] - y[1:-1]
    l_ml, l_mr = np.hypot(mlx, mly), np.hypot(mrx, mry)
    l_lr = np.hypot(x[2:] - x[:-2], y[2:] - y[:-2])
    th = _angle(mlx, mly, mrx, mry)
    half = 0.5 * (l_ml + l_mr + l_lr)
    area = np.sqrt(np.maximum(half * (half - l_ml) * (half - l_mr) * (half - l_lr), 0.0))
    denom = np.maximum(l_ml * l_mr * l_lr, 1e-12)
    curv = np.where(th > 0, 1.0, -1.0) * 4.0 * area / denom
    seg3 = s.seg[:-2]
    mean_curv = _sum(curv, tri, seg3, k) / n
    ang = _sum(th, tri, seg3, k) / n
    return length, regularity, mean_curv, ang


def _iav(x: np.ndarray, y: np.ndarray, s: Segments, n: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The inscribed angle at every inner point between the segment's first and last points."""
    k = len(s)
    first, last = s.starts, s.starts + s.counts - 1
    pos = np.arange(len(s.seg))
    inner = (pos != first[s.seg]) & (pos != last[s.seg])
    fx, fy = x[first][s.seg], y[first][s.seg]
    lx, ly = x[last][s.seg], y[last][s.seg]
    th = _angle(fx - x, fy - y, lx - x, ly - y)
    total = _sum(th, inner, s.seg, k)
    sq = _sum(th * th, inner, s.seg, k)
    return total / n, np.sqrt(np.maximum(sq - total ** 2 / n, 0.0) / (n - 1))


def _neighbours(b: Beams, s: Segments) -> tuple[np.ndarray, ...]:
    """The gaps to the beams just outside each end (0 when invalid), and Leigh's occlusion
    flags: 1 unless that beam is valid and farther (or reads under 1 cm)."""
    first, last = s.order[s.starts], s.order[s.starts + s.counts - 1]
    out = []
    for end, nb in ((first, first - 1), (last, last + 1)):
        inside = (nb >= 0) & (nb < len(b))
        nbc = np.clip(nb, 0, len(b) - 1)
        ok = inside & b.valid[nbc]
        jump = np.where(ok, np.hypot(b.x[end] - b.x[nbc], b.y[end] - b.y[nbc]), 0.0)
        free = ok & ((b.ranges[end] < b.ranges[nbc]) | (b.ranges[nbc] < 0.01))
        out.append((jump, np.where(free, 0.0, 1.0)))
    (jump_prev, occ_left), (jump_next, occ_right) = out
    return jump_prev, jump_next, occ_left, occ_right


def features(b: Beams, s: Segments) -> np.ndarray:
    """(S, len(NAMES)) float64: every segment's features, finite."""
    if not len(s):
        return np.zeros((0, len(NAMES)))
    x, y = b.x[s.order], b.y[s.order]
    n = s.counts.astype(np.float64)
    mx, my, std, linearity, medx, medy, med_dev = _spread(x, y, s, n)
    rc, circ = _circle(x, y, s, n, mx, my)
    length, regularity, curv, ang = _boundary(x, y, s, n)
    iav, std_iav = _iav(x, y, s, n)
    jump_prev, jump_next, occ_left, occ_right = _neighbours(b, s)
    first, last = s.starts, s.starts + s.counts - 1
    fx, fy, lx, ly = x[first], y[first], x[last], y[last]
    width = np.hypot(fx - lx, fy - ly)
    distance = np.hypot(medx, medy)
    # how far the segment's mean lies nearer the scanner than its chord, per metre of width
    cx, cy = 0.5 * (fx + lx), 0.5 * (fy + ly)
    bulge = (np.hypot(cx, cy) - np.hypot(mx, my)) / np.maximum(width, 1e-3)
    span = (s.order[last] - s.order[first] + 1).astype(np.float64)
    arc = distance * b.geometry.angle_increment * np.maximum(span - 1, 1.0)
    out = np.column_stack([
        n, std, med_dev, width, linearity, circ, length, regularity, curv, ang, iav, std_iav, distance,
        distance / n, occ_right, occ_left,
        rc, bulge, np.minimum(jump_prev, jump_next), np.maximum(jump_prev, jump_next), width / np.maximum(arc, 1e-6),
        span / n,
    ])
    return np.nan_to_num(out, nan=0.0, posinf=1e6, neginf=-1e6)
