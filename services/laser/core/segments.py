"""Cut a scan into segments: the points that belong to one object.

Two valid beams join when their points are less than ``join_m`` apart and their indices differ
by less than ``floor(asin(join_m / r) / angle_increment)`` (r the earlier beam's range): the
rule of Leigh et al.'s leg_tracker, which also lets a leg's points join across the beams of a
nearer object that cuts through it. Segments of fewer than ``min_points`` beams are dropped.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.spatial import cKDTree

from services.laser.core.scan import Beams

__all__ = ["Segments", "centres", "segment"]


@dataclass(frozen=True)
class Segments:
    """``order`` (P,) the beam indices of every segment's points, segment by segment, each in
    increasing beam order; segment ``s`` holds ``order[starts[s]:starts[s] + counts[s]]``;
    ``seg`` (P,) the segment of each entry of ``order``."""

    order: np.ndarray
    starts: np.ndarray
    counts: np.ndarray
    seg: np.ndarray

    def __len__(self) -> int:
        return len(self.counts)

    def beams_of(self, s: int) -> np.ndarray:
        return self.order[self.starts[s]:self.starts[s] + self.counts[s]]


def _empty() -> Segments:
    z = np.zeros(0, np.int64)
    return Segments(z, z, z, z)


def segment(b: Beams, join_m: float = 0.13, min_points: int = 3) -> Segments:
    """The segments of ``b`` (see the module's rule), ordered by their first beam."""
    idx = np.flatnonzero(b.valid)
    if len(idx) < min_points:
        return _empty()
    pts = np.column_stack([b.x[idx], b.y[idx]])
    pairs = cKDTree(pts).query_pairs(join_m, output_type="ndarray")
    if len(pairs):
        i, j = idx[pairs[:, 0]], idx[pairs[:, 1]]
        lo, hi = np.minimum(i, j), np.maximum(i, j)
        ratio = np.minimum(join_m / np.maximum(b.ranges[lo], 1e-9), 1.0)
        window = np.floor(np.arcsin(ratio) / b.geometry.angle_increment)
        keep = (hi - lo) < window
        a, c = pairs[keep, 0], pairs[keep, 1]
    else:
        a = c = np.zeros(0, np.int64)
    label = _components(len(idx), a, c)
    counts_all = np.bincount(label)
    big = counts_all[label] >= min_points
    label, members = label[big], idx[big]
    if not len(members):
        return _empty()
    # number the segments by their first beam, and list each one's beams in order
    first = np.full(counts_all.size, np.iinfo(np.int64).max)
    np.minimum.at(first, label, members)
    rank = np.argsort(np.argsort(first))
    seg = rank[label]
    ordering = np.lexsort((members, seg))
    order, seg = members[ordering], seg[ordering]
    counts = np.bincount(seg)
    starts = np.concatenate([[0], np.cumsum(counts)[:-1]])
    return Segments(order.astype(np.int64), starts, counts, seg.astype(np.int64))


def _components(n: int, a: np.ndarray, c: np.ndarray) -> np.ndarray:
    """(n,) a label per point, the same for two points joined by a chain of pairs (``a``, ``c``):
    union-find in arrays (each pair hooks the larger root under the smaller, then every label
    jumps to its root), a few passes for a scan's pairs; a third of scipy's sparse graph's cost."""
    label = np.arange(n)
    while True:
        la, lc = label[a], label[c]
        crossing = la != lc
        if not crossing.any():
            return label
        la, lc = la[crossing], lc[crossing]
        np.minimum.at(label, np.maximum(la, lc), np.minimum(la, lc))
        while not np.array_equal(jumped := label[label], label):
            label = jumped


def centres(b: Beams, s: Segments) -> np.ndarray:
    """(S, 2) each segment's mean point."""
    n = s.counts.astype(np.float64)
    return np.column_stack([np.bincount(s.seg, b.x[s.order], len(s)) / n, np.bincount(s.seg, b.y[s.order], len(s)) / n])
