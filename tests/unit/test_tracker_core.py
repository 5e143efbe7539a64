"""Unit tests of the tracker core: Kalman filter, Algorithm 1 gating, galleries, ID memory."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from services.tracker.core import kalman
from services.tracker.core.association import (
    AppearanceGate,
    appearance_cost,
    chi2_gate,
    gate_appearance,
    gate_position,
    match,
    spatial_distance,
)
from services.tracker.core.gallery import Gallery, pairwise_sq_distances
from services.tracker.core.identity import IdentityMemory
from services.tracker.memory_file import read_memory, save_memory

SIGMA = np.array([0.2, 0.2, 0.2, 1.0, 1.0, 1.0])
R = np.diag([0.04, 0.04, 0.04])


# ------------------------------------------------------------------- Kalman
def test_initiate_zero_velocity_and_p0() -> None:
    mean, cov = kalman.initiate(np.array([1.0, 2.0, 0.9]), SIGMA)
    np.testing.assert_array_equal(mean, [1, 2, 0.9, 0, 0, 0])
    np.testing.assert_allclose(cov, np.diag([0.04, 0.04, 0.04, 1, 1, 1]))


def test_predict_frame_mode_matches_hand_computation() -> None:
    mean = np.array([1.0, 2.0, 3.0, 0.5, -0.5, 0.3])
    cov = np.diag(SIGMA**2)
    m, p = kalman.predict(mean, cov, 1.0, kalman.process_noise(SIGMA))
    np.testing.assert_allclose(m, [1.5, 1.5, 3.0, 0.5, -0.5, 0.0])  # vz reset: z is a random walk
    assert p[0, 0] == pytest.approx(0.04 + 1.0 + 0.04)
    assert p[0, 3] == pytest.approx(1.0) and p[3, 0] == pytest.approx(1.0)
    assert p[3, 3] == pytest.approx(2.0)
    assert p[2, 2] == pytest.approx(0.08) and p[2, 5] == 0.0
    assert p[5, 5] == pytest.approx(1.0)
    np.testing.assert_array_equal(mean, [1.0, 2.0, 3.0, 0.5, -0.5, 0.3])  # inputs untouched


def test_predict_time_mode_scales_process_noise_with_elapsed_frames() -> None:
    cov = np.diag(SIGMA**2)
    m, p = kalman.predict(np.array([0, 0, 1, 1.0, 0, 0]), cov, 0.1, kalman.process_noise(SIGMA, 0.1 * 30))
    assert m[0] == pytest.approx(0.1)
    assert p[0, 0] == pytest.approx(0.04 + 0.01 * 1.0 + 0.04 * 3)
    assert p[3, 3] == pytest.approx(1.0 + 3.0)


def test_update_matches_hand_computation() -> None:
    mean = np.array([1.5, 1.5, 3.0, 0.5, -0.5, 0.0])
    cov = np.zeros((6, 6))
    cov[np.ix_([0, 3], [0, 3])] = [[1.08, 1.0], [1.0, 2.0]]
    cov[np.ix_([1, 4], [1, 4])] = [[1.08, 1.0], [1.0, 2.0]]
    cov[2, 2], cov[5, 5] = 0.08, 1.0
    m, p = kalman.update(mean, cov, np.array([2.0, 1.0, 3.0]), R)
    assert m[0] == pytest.approx(1.5 + 1.08 / 1.12 * 0.5)
    assert m[3] == pytest.approx(0.5 + 1.0 / 1.12 * 0.5)
    assert m[1] == pytest.approx(1.5 - 1.08 / 1.12 * 0.5)
    assert m[2] == pytest.approx(3.0)
    assert p[0, 0] == pytest.approx(1.08 - 1.08**2 / 1.12)
    assert p[3, 3] == pytest.approx(2.0 - 1.0 / 1.12)
    assert p[2, 2] == pytest.approx(0.08 - 0.08**2 / 0.12)
    np.testing.assert_allclose(p, p.T, atol=1e-12)


def test_batched_predict_and_update_equal_single_calls() -> None:
    rng = np.random.default_rng(0)
    means = rng.normal(size=(4, 6))
    covs = np.stack([np.diag(SIGMA**2) * (1 + i) for i in range(4)])
    z = rng.normal(size=(4, 3))
    q = kalman.process_noise(SIGMA)
    bm, bc = kalman.update(*kalman.predict(means, covs, 1.0, q), z, R)
    for i in range(4):
        sm, sc = kalman.update(*kalman.predict(means[i], covs[i], 1.0, q), z[i], R)
        np.testing.assert_allclose(bm[i], sm)
        np.testing.assert_allclose(bc[i], sc)


def test_negative_dt_is_refused() -> None:
    with pytest.raises(ValueError, match="dt"):
        kalman.predict(np.zeros(6), np.eye(6), -0.1, np.eye(6))


# --------------------------------------------------------- Algorithm 1 gating
GATE = AppearanceGate(t_lower=300.0, t_upper=700.0, s_max=0.05)


@pytest.mark.parametrize(
    ("c", "s", "admitted"),
    [
        (200.0, 50.0, True),  # below t_lower: appearance decides, however far
        (300.0, 50.0, True),  # exactly t_lower is not inside the band
        (500.0, 0.01, True),  # ambiguous band, spatially close: admitted
        (500.0, 0.05, True),  # S == s_max is not "> s_max"
        (500.0, 0.06, False),  # ambiguous band, spatially far: rejected
        (700.0, 0.0, False),  # at t_upper: rejected even on top of the track
        (900.0, 0.0, False),  # above t_upper
        (np.nan, 0.01, True),  # no descriptor: treated as the band, close -> admitted
        (np.nan, 1.0, False),  # no descriptor, far -> rejected
    ],
)
def test_gating_cases(c: float, s: float, admitted: bool) -> None:
    gated = gate_appearance(np.array([[c]]), np.array([[s]]), GATE)
    assert bool(gated[0, 0] < GATE.inf) is admitted
    if admitted and not np.isnan(c):
        assert gated[0, 0] == c  # an admitted pair keeps its appearance cost


def test_match_drops_inf_pairs_and_reports_unmatched() -> None:
    cost = np.array([[100.0, 1e5], [1e5, 1e5], [1e5, 50.0]])
    m, ud, ut = match(cost)
    assert m.tolist() == [[0, 0], [2, 1]]
    assert ud.tolist() == [1] and ut.tolist() == []
    m, ud, ut = match(np.full((2, 2), 1e5))
    assert len(m) == 0 and ud.tolist() == [0, 1] and ut.tolist() == [0, 1]
    m, ud, ut = match(np.zeros((0, 3)))
    assert ut.tolist() == [0, 1, 2]


def test_hungarian_prefers_global_optimum() -> None:
    cost = np.array([[1.0, 2.0], [1.5, 10.0]])
    m, _, _ = match(cost)
    assert sorted(map(tuple, m.tolist())) == [(0, 1), (1, 0)]


def test_spatial_distance_is_squared_mahalanobis_on_xy() -> None:
    pos = np.array([[1.0, 0.0], [0.0, 2.0]])
    means = np.array([[0.0, 0.0], [0.0, 1.0]])
    covs = np.stack([np.diag([0.25, 1.0]), np.diag([1.0, 4.0])])
    s = spatial_distance(pos, means, covs)
    np.testing.assert_allclose(s, [[4.0, 1.0 + 0.25], [4.0, 0.25]])


def test_appearance_cost_is_min_distance_to_gallery() -> None:
    g1 = Gallery.from_descriptors(np.array([[0.0, 0.0], [3.0, 4.0]]), 10)
    g2 = Gallery.from_descriptors(np.array([[10.0, 0.0]]), 10)
    empty = Gallery(2, 10)
    c = appearance_cost(np.array([[3.0, 0.0], [np.nan, np.nan]]), [g1, g2, empty])
    np.testing.assert_allclose(c[0, :2], [3.0, 7.0], rtol=1e-6)
    assert np.isnan(c[0, 2]) and np.all(np.isnan(c[1]))


def test_position_gate_uses_chi_square_quantile() -> None:
    thr = chi2_gate(0.95, 2)
    assert thr == pytest.approx(5.991, abs=1e-3)
    out = gate_position(np.array([[1.0, 6.5]]), thr)
    assert out[0, 0] == 1.0 and out[0, 1] == 1e5


# ---------------------------------------------------------------- galleries
def test_gallery_prunes_older_of_the_closest_pair() -> None:
    a, b, c, d = np.array([0.0, 0.0]), np.array([0.1, 0.0]), np.array([5.0, 0.0]), np.array([0.0, 9.0])
    g = Gallery.from_descriptors(np.stack([a, b, c]), capacity=3)
    g.add(d)  # closest pair is (a, b): the older, a, goes
    np.testing.assert_allclose(g.descriptors, [b, c, d])
    e = np.array([5.05, 0.0])
    g.add(e)  # closest pair is now (e, c): c, the older, goes; the newest is kept
    np.testing.assert_allclose(g.descriptors, [b, d, e])
    assert len(g) == 3


def test_gallery_neighbour_bookkeeping_matches_brute_force() -> None:
    rng = np.random.default_rng(3)
    g = Gallery(8, capacity=20)
    for x in rng.normal(size=(200, 8)):
        g.add(x)
        n = len(g)
        if n < g.capacity:
            continue  # the bookkeeping starts once the gallery is full
        d2 = pairwise_sq_distances(g._data[:n], g._data[:n])
        np.fill_diagonal(d2, np.inf)
        np.testing.assert_allclose(g._nn_d[:n], d2.min(axis=1), rtol=1e-4, atol=1e-4)
    assert len(g) == 20


def test_gallery_nearest_policy_replaces_the_view_nearest_to_the_new_one() -> None:
    a, b, c = np.array([0.0, 0.0]), np.array([0.1, 0.0]), np.array([5.0, 0.0])
    g = Gallery.from_descriptors(np.stack([a, b, c]), capacity=3, prune="nearest")
    g.add(np.array([4.9, 0.0]))  # nearest stored view is c, though (a, b) is the closest pair
    np.testing.assert_allclose(g.descriptors, [a, b, [4.9, 0.0]])
    with pytest.raises(ValueError, match="prune"):
        Gallery(2, prune="oldest")


@pytest.mark.parametrize("prune", ["closest_pair", "nearest"])
def test_gallery_add_with_known_distances_equals_add(prune: str) -> None:
    rng = np.random.default_rng(4)
    xs = rng.normal(size=(60, 8)).astype(np.float32)
    plain, reused = Gallery(8, 10, prune), Gallery(8, 10, prune)
    for x in xs:
        plain.add(x)
        d2 = reused.sq_distances(x[None])[0] if len(reused) else None
        reused.add(x, d2)
        np.testing.assert_allclose(reused.min_distances(xs[:5]), plain.min_distances(xs[:5]), rtol=1e-5, atol=1e-5)
    np.testing.assert_allclose(reused.descriptors, plain.descriptors)


def test_gallery_copy_on_write() -> None:
    g = Gallery.from_descriptors(np.eye(3), capacity=3)
    snap = g.copy()
    g.add(np.array([0.0, 0.0, 5.0]))
    np.testing.assert_allclose(snap.descriptors, np.eye(3))
    assert not np.allclose(g.descriptors, np.eye(3))


def test_gallery_refuses_non_finite() -> None:
    with pytest.raises(ValueError):
        Gallery(2).add(np.array([np.nan, 0.0]))


# ---------------------------------------------------------------- ID memory
def test_assign_recovers_closest_id_below_t_recover() -> None:
    mem = IdentityMemory(capacity=10)
    assert mem.new_id() == 1 and mem.new_id() == 2
    mem.archive(1, np.array([[0.0, 0.0]]))
    mem.archive(2, np.array([[10.0, 0.0]]))
    assert mem.assign(np.array([0.5, 0.0]), live_ids=set(), t_recover=1.0) == (1, True)
    assert mem.assign(np.array([9.5, 0.0]), live_ids=set(), t_recover=1.0) == (2, True)
    # the same person while ID 1 is live: not recoverable, a fresh ID
    assert mem.assign(np.array([0.5, 0.0]), live_ids={1}, t_recover=1.0) == (3, False)
    # nobody close enough
    assert mem.assign(np.array([5.0, 0.0]), live_ids=set(), t_recover=1.0) == (4, False)
    assert mem.assign(None, live_ids=set(), t_recover=1.0) == (5, False)


def test_memory_is_bounded_per_id() -> None:
    mem = IdentityMemory(capacity=7)
    rng = np.random.default_rng(1)
    mem.archive(3, rng.normal(size=(5, 4)))
    mem.archive(3, rng.normal(size=(5, 4)))
    assert len(mem.entries[3]) == 7
    assert mem.next_id == 4


def test_memory_save_load_roundtrip(tmp_path: Path) -> None:
    rng = np.random.default_rng(2)
    mem = IdentityMemory(capacity=50)
    for _ in range(3):
        mem.new_id()
    mem.archive(1, rng.normal(size=(4, 6)))
    mem.archive(3, rng.normal(size=(2, 6)))
    live = rng.normal(size=(3, 6))
    path = tmp_path / "sub" / "memory.npz"
    save_memory(path, mem, model="colour", extra=[(2, live)])
    assert [p.name for p in path.parent.iterdir()] == ["memory.npz"]  # no temporary file left
    loaded, model = read_memory(path)
    assert model == "colour" and loaded.next_id == 4
    assert sorted(loaded.entries) == [1, 2, 3]
    np.testing.assert_allclose(loaded.entries[1].descriptors, mem.entries[1].descriptors)
    np.testing.assert_allclose(loaded.entries[2].descriptors, live.astype(np.float32))


def test_memory_load_rejects_garbage(tmp_path: Path) -> None:
    bad = tmp_path / "bad.npz"
    bad.write_bytes(b"not a zip file")
    with pytest.raises(ValueError, match="not a tracker ID memory file"):
        read_memory(bad)


def test_memory_file_layout_is_stable(tmp_path: Path) -> None:
    """A file of format 1 written field by field (as older versions did) still loads."""
    path = tmp_path / "v1.npz"
    np.savez(path, format_version=np.int64(1), model=np.str_("colour"), next_id=np.int64(9), capacity=np.int64(20),
             ids=np.array([3, 7, 3], np.int64), counts=np.array([1, 2, 1], np.int64),
             descriptors=np.arange(8, dtype=np.float32).reshape(4, 2))
    loaded, model = read_memory(path)
    assert model == "colour" and loaded.next_id == 9 and loaded.capacity == 20 and loaded.version == 0
    np.testing.assert_array_equal(loaded.entries[3].descriptors, [[0, 1], [6, 7]])
    np.testing.assert_array_equal(loaded.entries[7].descriptors, [[2, 3], [4, 5]])
    with np.load(path) as f:
        np.savez(tmp_path / "v2.npz", **{**dict(f), "format_version": np.int64(2)})
    with pytest.raises(ValueError, match="ID memory format 2"):
        read_memory(tmp_path / "v2.npz")


def test_memory_blocks_round_trip_without_files() -> None:
    rng = np.random.default_rng(4)
    mem = IdentityMemory(capacity=5, next_id=3)
    mem.archive(2, rng.normal(size=(3, 4)))
    ids, counts, data = mem.to_blocks(extra=[(8, rng.normal(size=(2, 4)))])
    assert ids.tolist() == [2, 8] and counts.tolist() == [3, 2] and data.dtype == np.float32
    back = IdentityMemory.from_blocks(5, mem.next_id, ids, counts, data)
    assert back.next_id == 9 and back.version == 0
    np.testing.assert_array_equal(back.entries[2].descriptors, mem.entries[2].descriptors)
    with pytest.raises(ValueError, match="inconsistent"):
        IdentityMemory.from_blocks(5, 1, ids, counts + 1, data)


def test_id_memory_keeps_at_most_max_ids_forgetting_the_longest_archived() -> None:
    mem = IdentityMemory(capacity=5, max_ids=2)
    for track_id in (1, 2):
        mem.archive(track_id, np.eye(3)[track_id : track_id + 1])
    mem.archive(1, np.eye(3)[1:2])  # 1 archived again: now the newest
    mem.archive(3, np.eye(3)[0:1])
    assert sorted(mem.entries) == [1, 3] and mem.evicted == 1
    assert mem.copy().max_ids == 2
