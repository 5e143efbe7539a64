"""The depth detector's point-cloud steps: back-projection, the voxel grid, Euclidean clusters.

Each is exact (the same points, centroids and clusters as the plain definitions: a sort of
every point for the voxel grid, a k-d tree's pairs within the tolerance and the graph's
connected components for the clusters) and works on occupied cells of a regular lattice
indexed by a dense table, so that no step sorts or pairs up every point:

- :func:`voxel_grid` finds each point's voxel through a table over the voxels' bounding
  box (a sort of the keys when that box is too large), and sums in the points' order.
- :func:`cluster_points` first joins the points whose cells (of side ``tolerance / sqrt(3)``,
  so that a cell's points are all within the tolerance of each other) touch with one pair
  of points closer than the tolerance, then looks for the missing joins only among the
  points with two of those clusters within reach (a k-d tree over a few hundred points).
"""

from __future__ import annotations

import numpy as np
from scipy.sparse import csr_matrix
from scipy.sparse.csgraph import connected_components
from scipy.spatial import cKDTree

__all__ = ["backproject", "cluster_points", "voxel_grid"]

#: The largest lattice (cells) indexed by a dense table; a larger one sorts its keys instead.
DENSE_MAX = 1 << 23
#: The 13 neighbours of a cell ahead of it in key order (its 26 neighbours, each pair once).
_AHEAD_ALL = np.array([(x, y, z) for x in (-1, 0, 1) for y in (-1, 0, 1) for z in (-1, 0, 1) if (x, y, z) > (0, 0, 0)])
#: Neighbour cells compared by their representative points: the faces and edges ahead of a
#: cell (any subset of the true joins is exact; these find nearly all of them, cheaply).
_AHEAD = _AHEAD_ALL[np.abs(_AHEAD_ALL).sum(axis=1) <= 2]


def backproject(depth: np.ndarray, K: np.ndarray, step: int, min_m: float, max_m: float) -> np.ndarray:
    """Camera-frame points (N, 3) float32 of every ``step``-th pixel of ``depth`` (H, W) metres in
    range, row by row."""
    d = np.ascontiguousarray(depth[::step, ::step])
    width = d.shape[1]
    flat = d.ravel()
    at = np.flatnonzero((flat > min_m) & (flat < max_m))  # NaN compares False
    z = flat[at].astype(np.float32)
    rows, cols = np.divmod(at, width)
    u = cols.astype(np.float32) * step
    v = rows.astype(np.float32) * step
    out = np.empty((len(at), 3), np.float32)
    out[:, 0] = (u - K[0, 2]) * z / K[0, 0]  # float64 (K's), rounded to float32 as before
    out[:, 1] = (v - K[1, 2]) * z / K[1, 1]
    out[:, 2] = z
    return out


class _Lattice:
    """The occupied cells of a lattice, given each point's flat cell key (< ``size``): ``keys``
    (K,) sorted, ``of`` (N,) each point's cell index, and, with ``find``, :meth:`find` for
    other keys."""

    def __init__(self, flat: np.ndarray, size: int, find: bool = False) -> None:
        self._lut: np.ndarray | None = None
        if size <= DENSE_MAX:
            occupied = np.zeros(size, bool)
            occupied[flat] = True
            self.keys = np.flatnonzero(occupied)
            # -1 where no point is, for find (else only read where occupied: no need to fill it)
            self._lut = np.full(size, -1, np.int32) if find else np.empty(size, np.int32)
            self._lut[self.keys] = np.arange(len(self.keys), dtype=np.int32)
            self.of = self._lut[flat].astype(np.intp)  # (indexing with intp is faster)
        else:
            self.keys, self.of = np.unique(flat, return_inverse=True)

    def find(self, query: np.ndarray) -> np.ndarray:
        """The cell index of each key in ``query`` (in [0, size)), -1 where no point is."""
        if self._lut is not None:
            return self._lut[query]
        at = np.minimum(np.searchsorted(self.keys, query), len(self.keys) - 1)
        return np.where(self.keys[at] == query, at, -1)


def voxel_grid(points: np.ndarray, size: float) -> np.ndarray:
    """Centroids (M, 3) float64 of the points (N, 3) falling in each occupied ``size`` m voxel,
    in the order of the voxels' flat keys (x, then y, then z cell)."""
    if len(points) == 0:
        return np.zeros((0, 3))
    scaled = np.floor(points / size)
    columns = [scaled[:, axis] for axis in range(3)]  # a column at a time: reductions down rows are slow
    lo = [ci.min() for ci in columns]
    dims = [int(ci.max() - low) + 1 for ci, low in zip(columns, lo)]
    total = dims[0] * dims[1] * dims[2]
    # (the cells are whole numbers: exact in float32 below 2**24, as the keys in int32 below 2**31)
    small = total < 2**31 and max(abs(float(low)) for low in lo) + max(dims) < 2**24 and scaled.dtype == np.float32
    c = [(ci - low).astype(np.int32 if small else np.int64) for ci, low in zip(columns, lo)]
    flat = ((c[0] * dims[1] + c[1]) * dims[2] + c[2]).astype(np.intp)  # as a sort of the keys would order them
    voxels = _Lattice(flat, total)
    m = len(voxels.keys)
    counts = np.bincount(voxels.of, minlength=m)
    sums = np.empty((m, 3))
    for axis in range(3):  # each voxel's points added in their order, as with a sort's inverse
        sums[:, axis] = np.bincount(voxels.of, weights=points[:, axis], minlength=m)
    return sums / counts[:, None]


def _padded_cells(columns: list[np.ndarray], lo: list[float], side: float) -> tuple[np.ndarray, list[int]]:
    """Flat keys (N,) of the points' cells of ``side`` m from ``lo``, with an empty cell on every
    side (so that a neighbour's key never wraps), and the lattice's dimensions."""
    c = [np.floor((col - low) / side).astype(np.int64) + 1 for col, low in zip(columns, lo)]
    dims = [int(ci.max()) + 2 for ci in c]
    return (c[0] * dims[1] + c[1]) * dims[2] + c[2], dims


def _steps(offsets: np.ndarray, dims: list[int]) -> np.ndarray:
    """Flat key steps of the cell ``offsets`` (K, 3), ascending."""
    return np.sort((offsets[:, 0] * dims[1] + offsets[:, 1]) * dims[2] + offsets[:, 2])


def cluster_points(points: np.ndarray, tolerance: float) -> tuple[int, np.ndarray]:
    """Euclidean clusters: (count, labels (N,)); points closer than ``tolerance`` share a cluster.

    Exactly the connected components of the graph joining every two points at most
    ``tolerance`` apart (what ``cKDTree.query_pairs`` and ``connected_components`` give),
    numbered as those are: in the order of each cluster's first point.
    """
    n = len(points)
    if n == 0:
        return 0, np.zeros(0, np.intp)
    columns = [np.ascontiguousarray(points[:, axis], dtype=np.float64) for axis in range(3)]
    lo = [float(col.min()) for col in columns]
    # 1. Cells of side tolerance / sqrt(3) (a hair less): a cell's points are within the
    # tolerance of each other, so one cluster. Two neighbouring cells are joined when a point
    # of each (the last in index order) are within the tolerance: true joins, not all of them.
    flat, dims = _padded_cells(columns, lo, tolerance / np.sqrt(3.0) * (1.0 - 1e-9))
    cells = _Lattice(flat, dims[0] * dims[1] * dims[2], find=True)
    k = len(cells.keys)
    rep = np.empty(k, np.intp)
    rep[cells.of] = np.arange(n)
    rx, ry, rz = (col[rep] for col in columns)
    ahead = cells.find(cells.keys[:, None] + _steps(_AHEAD, dims)[None, :])  # (K, 9), ascending per row
    d2 = np.square(rx[:, None] - rx[ahead])  # (where ahead is -1: some cell, left out below)
    d2 += np.square(ry[:, None] - ry[ahead])
    d2 += np.square(rz[:, None] - rz[ahead])
    near = (d2 <= tolerance * tolerance) & (ahead >= 0)
    indptr = np.zeros(k + 1, np.int32)
    np.cumsum(np.count_nonzero(near, axis=1), out=indptr[1:])
    graph = csr_matrix((np.ones(int(indptr[-1])), ahead[near], indptr), shape=(k, k))  # rows' columns ascending
    count, cell_label = connected_components(graph, directed=False)
    label = cell_label[cells.of]
    # 2. The joins missed: between two points of different clusters within the tolerance, so
    # in the same or neighbouring cells of side tolerance. Only the points of cells that hold
    # two clusters, or neighbour a cell of another cluster, can have one.
    if count > 1:
        label = _join_across(columns, lo, tolerance, label, count)
    # 3. Numbered by each cluster's first point.
    count = int(label.max()) + 1
    first = np.full(count, n, np.intp)
    np.minimum.at(first, label, np.arange(n))
    rank = np.empty(count, np.intp)
    rank[np.argsort(first)] = np.arange(count)
    return count, rank[label]


def _join_across(columns: list[np.ndarray], lo: list[float], tolerance: float, label: np.ndarray,
                 count: int) -> np.ndarray:
    """``label`` (N,) of ``count`` clusters, each connected, with those that have two points
    within ``tolerance`` of each other merged (labels of the merged clusters' components)."""
    flat, dims = _padded_cells(columns, lo, tolerance)
    cells = _Lattice(flat, dims[0] * dims[1] * dims[2], find=True)
    k = len(cells.keys)
    value = np.empty(k, np.intp)  # the cell's cluster, or -1 when it holds two
    value[cells.of] = label
    value[cells.of[value[cells.of] != label]] = -1
    ahead = cells.find(cells.keys[:, None] + _steps(_AHEAD_ALL, dims)[None, :])  # (K, 13)
    other = (ahead >= 0) & (value[ahead] != value[:, None])
    border = value < 0
    border[np.any(other, axis=1)] = True
    border[ahead[other]] = True
    near = np.flatnonzero(border[cells.of])
    if len(near) < 2:
        return label
    points = np.column_stack([col[near] for col in columns])
    pairs = cKDTree(points).query_pairs(tolerance, output_type="ndarray")
    la, lb = label[near[pairs[:, 0]]], label[near[pairs[:, 1]]]
    cross = la != lb
    if not cross.any():
        return label
    # union-find over the few distinct cluster pairs
    parent = list(range(count))

    def root(i: int) -> int:
        while parent[i] != i:
            parent[i] = parent[parent[i]]
            i = parent[i]
        return i

    la, lb = la[cross], lb[cross]
    for join in np.unique(np.minimum(la, lb).astype(np.int64) * count + np.maximum(la, lb)).tolist():
        i, j = divmod(join, count)
        ri, rj = root(i), root(j)
        if ri != rj:
            parent[max(ri, rj)] = min(ri, rj)
    roots = np.array([root(i) for i in range(count)])
    return np.unique(roots, return_inverse=True)[1][label]
