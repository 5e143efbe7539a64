"""The depth detector's point-cloud steps against their plain definitions: the clusters are
exactly the connected components of the graph of point pairs within the tolerance (a k-d
tree's pairs), numbered alike; the voxel grid is exactly a sort's (np.unique) centroids."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import connected_components
from scipy.spatial import cKDTree

from services.detector.core import cloud
from services.detector.core.cloud import backproject, cluster_points, voxel_grid


def euclidean_clusters(points: np.ndarray, tolerance: float) -> tuple[int, np.ndarray]:
    """The definition: points at most ``tolerance`` apart are joined; clusters are the components."""
    n = len(points)
    pairs = cKDTree(points).query_pairs(tolerance, output_type="ndarray")
    graph = coo_matrix((np.ones(len(pairs), np.int8), (pairs[:, 0], pairs[:, 1])), shape=(n, n))
    count, labels = connected_components(graph, directed=False)
    return int(count), labels


def voxel_centroids(points: np.ndarray, size: float) -> np.ndarray:
    """The definition: the points' voxels sorted by flat key, each one's points averaged in order."""
    cells = np.floor(points / size).astype(np.int64)
    cells -= cells.min(axis=0)
    dims = cells.max(axis=0) + 1
    flat = (cells[:, 0] * dims[1] + cells[:, 1]) * dims[2] + cells[:, 2]
    _, inverse, counts = np.unique(flat, return_inverse=True, return_counts=True)
    sums = np.zeros((len(counts), 3))
    for axis in range(3):
        sums[:, axis] = np.bincount(inverse, weights=points[:, axis], minlength=len(counts))
    return sums / counts[:, None]


def cloud_of(kind: str, rng: np.random.Generator) -> np.ndarray:
    """Random clouds of the shapes a depth image gives (and some it does not)."""
    if kind == "uniform":  # sparse and dense patches alike, around the tolerance
        return rng.uniform(0, 1.5, (int(rng.integers(50, 3000)), 3))
    if kind == "blobs":  # people, furniture: clumps a little apart
        centres = rng.uniform(-3, 3, (12, 3))
        return np.vstack([c + rng.normal(0, rng.uniform(0.02, 0.3), (int(rng.integers(1, 400)), 3)) for c in centres])
    if kind == "surfaces":  # walls and a floor seen by a camera: voxel centroids on planes, with noise
        u, v = rng.uniform(-2, 2, (2, 4000))
        wall = np.column_stack([u, v, 3 + 0.01 * rng.normal(size=4000)])
        floor = np.column_stack([u, np.full(4000, 1.2) + 0.01 * rng.normal(size=4000), 3 + v])
        box = rng.uniform([-0.3, 0.4, 2.2], [0.3, 1.2, 2.6], (1500, 3))
        return voxel_grid(np.vstack([wall, floor, box]).astype(np.float32), 0.06)
    if kind == "lattice":  # points on (and a hair off) the cells' boundaries, duplicates
        side = 0.13 / np.sqrt(3.0)
        pts = rng.integers(-20, 20, (1500, 3)) * side
        return np.vstack([pts, pts[:200], pts[:300] + rng.choice([-1e-12, 1e-12], (300, 3))])
    if kind == "flat":  # degenerate: a line, a plane, far from the origin
        t = rng.uniform(0, 10, 2000)
        line = np.column_stack([t, np.zeros_like(t), np.zeros_like(t)]) + 1000.0
        plane = np.column_stack([rng.uniform(0, 3, 2000), rng.uniform(0, 3, 2000), np.full(2000, -500.0)])
        return np.vstack([line, plane])
    raise ValueError(kind)


@pytest.mark.parametrize("dense", [True, False], ids=["dense-table", "sorted-keys"])
@pytest.mark.parametrize("kind", ["uniform", "blobs", "surfaces", "lattice", "flat"])
def test_clusters_are_exactly_the_euclidean_clusters(kind: str, dense: bool, monkeypatch: pytest.MonkeyPatch) -> None:
    if not dense:  # the lattices' fallback for a bounding box too large for a table
        monkeypatch.setattr(cloud, "DENSE_MAX", 0)
    rng = np.random.default_rng(["uniform", "blobs", "surfaces", "lattice", "flat"].index(kind))
    for _ in range(4):
        points = cloud_of(kind, rng)
        for tolerance in (0.05, 0.13, 0.4):
            count, labels = cluster_points(points, tolerance)
            want_count, want = euclidean_clusters(points, tolerance)
            assert count == want_count
            np.testing.assert_array_equal(labels, want)


def test_clusters_of_few_points_and_at_the_tolerance() -> None:
    assert cluster_points(np.zeros((0, 3)), 0.1)[0] == 0
    assert cluster_points(np.zeros((1, 3)), 0.1)[0] == 1
    pair = np.array([[0.0, 0.0, 0.0], [0.5, 0.0, 0.0]])
    assert cluster_points(pair, 0.5)[0] == 1  # at the tolerance: joined, as query_pairs (<=)
    assert cluster_points(pair, np.nextafter(0.5, 0.0))[0] == 2
    for tolerance in (0.05, 0.13, 1.0):  # across a cell's diagonal, a hair farther than the tolerance: apart
        c = tolerance / np.sqrt(3.0) * (1.0 + 1e-6)
        assert cluster_points(np.array([[0.0, 0.0, 0.0], [c, c, c]]), tolerance)[0] == 2
    chain = np.column_stack([np.arange(10) * 0.1, np.zeros(10), np.zeros(10)])
    count, labels = cluster_points(np.vstack([chain[::2], chain[1::2]]), 0.11)  # joined only through each other
    assert count == 1 and not labels.any()
    float32 = cloud_of("blobs", np.random.default_rng(7)).astype(np.float32)
    np.testing.assert_array_equal(cluster_points(float32, 0.13)[1], euclidean_clusters(float32, 0.13)[1])


@pytest.mark.parametrize("dense", [True, False], ids=["dense-table", "sorted-keys"])
def test_voxel_grid_is_exactly_the_sorted_centroids(dense: bool, monkeypatch: pytest.MonkeyPatch) -> None:
    if not dense:
        monkeypatch.setattr(cloud, "DENSE_MAX", 0)
    rng = np.random.default_rng(3)
    for dtype in (np.float32, np.float64):
        for scale, size in ((3.0, 0.06), (0.2, 0.06), (1e5, 0.1), (8.0, 0.5)):
            points = (rng.normal(size=(int(rng.integers(1, 20000)), 3)) * scale).astype(dtype)
            np.testing.assert_array_equal(voxel_grid(points, size), voxel_centroids(points, size))
    assert voxel_grid(np.zeros((0, 3), np.float32), 0.06).shape == (0, 3)


def test_backproject_keeps_every_step_th_pixel_in_range() -> None:
    K = np.array([[525.0, 0.0, 319.5], [0.0, 525.0, 239.5], [0.0, 0.0, 1.0]])
    depth = np.random.default_rng(0).uniform(0.0, 10.0, (480, 640)).astype(np.float32)
    depth[::7, ::3] = np.nan
    for step in (1, 2, 3):
        d = depth[::step, ::step]
        rows, cols = np.nonzero((d > 0.3) & (d < 8.0))
        z = d[rows, cols]
        x = (cols.astype(np.float32) * step - K[0, 2]) * z / K[0, 0]
        y = (rows.astype(np.float32) * step - K[1, 2]) * z / K[1, 1]
        np.testing.assert_array_equal(backproject(depth, K, step, 0.3, 8.0),
                                      np.column_stack([x, y, z]).astype(np.float32))


def test_the_detector_process_keeps_freed_memory_with_glibc() -> None:
    import platform

    from services.detector.memory import keep_freed_memory

    assert keep_freed_memory() is (platform.system() == "Linux" and platform.libc_ver()[0] == "glibc")
