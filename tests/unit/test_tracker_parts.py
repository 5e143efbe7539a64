"""The robust core's parts: the galleries in one array, the cues as pure functions, and a
tracker that keeps nothing of a frame but its state."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from services.tracker.core import cues, kalman
from services.tracker.core.gallery import Gallery
from services.tracker.core.robust import RobustParams, RobustTracker
from services.tracker.core.bank import GalleryBank
from services.tracker.core.types import AppearanceModel, FrameInput

RNG = np.random.default_rng(7)


def _unit(n: int, dim: int) -> np.ndarray:
    x = RNG.normal(size=(n, dim))
    return (x / np.linalg.norm(x, axis=1, keepdims=True)).astype(np.float32)


def test_a_bank_slot_keeps_what_a_nearest_pruning_gallery_keeps() -> None:
    bank, gallery = GalleryBank(capacity=6), Gallery(12, 6, prune="nearest")
    other = bank.allocate(12)
    slot = bank.allocate(12)
    for k, x in enumerate(_unit(40, 12)):
        if k % 2:  # through the batched path, with the distances of the association
            d2 = bank.pair_sq_distances(np.array([slot]), x[None])
            alone = gallery.sq_distances(x[None])[0]
            # the same distances to float32 rounding (the bank stores a gallery as columns, the
            # gallery as rows: the products add in another order), beyond them inf
            np.testing.assert_allclose(d2[0, : len(gallery)], alone, rtol=1e-6, atol=1e-6)
            assert np.all(np.isinf(d2[0, len(gallery):]))
            bank.add_many(np.array([slot]), x[None], d2)
            gallery.add(x, gallery.sq_distances(x[None])[0])
        else:
            bank.add(slot, x)
            gallery.add(x)
        assert np.array_equal(bank.descriptors(slot), gallery.descriptors)
    assert bank.size(other) == 0 and bank.sizes(np.array([other, slot, -1])).tolist() == [0, 6, 0]


def test_bank_copies_are_independent_and_freed_slots_are_reused() -> None:
    bank = GalleryBank(capacity=3)
    a, b = bank.allocate(4), bank.allocate(4)
    bank.add_many(np.array([a, b]), _unit(2, 4), None)
    snap = bank.copy()
    bank.add(a, _unit(1, 4)[0])
    bank.release(b)
    assert (bank.size(a), bank.size(b), snap.size(a), snap.size(b)) == (2, 0, 1, 1)
    assert bank.allocate(4) == b
    with pytest.raises(ValueError, match="dimension"):
        bank.allocate(5)


def test_pairs_compared_several_times_get_the_same_distances_as_alone() -> None:
    bank = GalleryBank(capacity=50)
    slots = [bank.allocate(16) for _ in range(3)]
    for s in slots:
        for x in _unit(50, 16):
            bank.add(s, x)
    x = _unit(4, 16)
    both = bank.pair_sq_distances(np.array([slots[0], slots[1], slots[1], slots[2]]), x)
    for k, s in enumerate([slots[0], slots[1], slots[1], slots[2]]):
        alone = bank.pair_sq_distances(np.array([s]), x[k : k + 1])[0]
        np.testing.assert_allclose(both[k], alone, rtol=1e-5, atol=1e-6)


def test_a_bank_too_large_for_the_cache_is_streamed_to_the_same_distances(monkeypatch: pytest.MonkeyPatch) -> None:
    from services.tracker.core import bank as bank_module

    bank = GalleryBank(capacity=40)
    slots = [bank.allocate(16) for _ in range(6)]
    for s in slots:
        for x in _unit(30, 16):  # partly filled: the slots past a gallery's descriptors stay inf
            bank.add(s, x)
    x = _unit(4, 16)
    for order in ([0, 1, 2, 3], [5, 2, 0, 4]):  # the bank's used part in order, and a gather
        picked = np.array([slots[k] for k in order])
        cached = bank.pair_sq_distances(picked, x)
        monkeypatch.setattr(bank_module, "_STREAM_BYTES", 0)
        streamed = bank.pair_sq_distances(picked, x)
        monkeypatch.undo()
        assert np.array_equal(np.isinf(streamed), np.isinf(cached)) and np.isinf(cached[:, 30:]).all()
        np.testing.assert_allclose(streamed[:, :30], cached[:, :30], rtol=1e-5, atol=1e-6)


def test_the_last_level_cache_is_read_as_linux_reports_it(tmp_path: Path) -> None:
    from services.tracker.core.bank import last_level_cache_bytes

    for index, size in (("index0", "32K"), ("index2", "1024K"), ("index3", "32768K"), ("index4", "junk")):
        (tmp_path / index).mkdir()
        (tmp_path / index / "size").write_text(size + "\n")
    assert last_level_cache_bytes(tmp_path) == 32 << 20
    assert last_level_cache_bytes(tmp_path / "absent") is None  # another system: the default threshold


def test_cues_return_what_they_computed() -> None:
    model = AppearanceModel(0.3, 0.7, 0.4)
    bank = GalleryBank(capacity=5)
    slot = bank.allocate(8)
    look = _unit(1, 8)[0]
    bank.add(slot, look)
    positions = np.array([[0.0, 0.0, 1.0], [5.0, 0.0, 1.0]])
    r, bad = cues.measurement_covariance(None, None, np.eye(3) * 0.04, 2)
    assert bad == 0 and r.shape == (2, 3, 3)
    total, d2 = cues.position_log_odds(positions, r, np.zeros((2, 2)), np.stack([np.eye(2)] * 2) * 0.1, 0.02)
    assert total.shape == d2.shape == (2, 2) and d2[0, 0] == 0.0 and d2[1, 0] > 13.8
    descriptors = np.stack([look, -look])
    odds, pairs = cues.appearance_log_odds(model, bank, np.array([slot, -1]), descriptors, np.ones((2, 2), bool))
    assert odds[0, 0] > 2 and odds[1, 0] < -2 and not odds[:, 1].any()  # no gallery: no information
    assert pairs.get(np.array([0]), np.array([0])) is not None and pairs.get(np.array([0]), np.array([1])) is None
    assert pairs.get(np.array([1]), np.array([0]))[0, 0] == pytest.approx(4.0, abs=1e-5)


def test_one_covariance_test_counts_and_replaces() -> None:
    good, asym = np.eye(3) * 0.01, np.eye(3) * 0.01
    asym[0, 1] = 0.005
    covs = np.stack([good, asym, -good, np.full((3, 3), np.nan)])
    usable = cues.usable_covariances(covs)
    assert usable.tolist() == [True, False, False, False]
    frame = FrameInput.of(np.zeros((4, 3)), measurement_cov=covs)
    assert frame.cov_usable is None  # not checked yet: the core checks it
    r, bad = cues.measurement_covariance(frame.measurement_cov, frame.cov_usable, np.eye(3), 4)
    assert bad == 3 and np.allclose(r[0], np.eye(3) + good) and np.allclose(r[1:], np.eye(3))
    told = cues.measurement_covariance(covs, np.array([True, False, False, False]), np.eye(3), 4)
    assert told[1] == 3 and np.array_equal(told[0], r)  # checked once (the service): not again


def test_the_process_noise_is_one_function() -> None:
    dt = 0.1
    assert np.array_equal(RobustTracker(RobustParams(q_accel=3.0, q_z=0.05))._q(dt),
                          kalman.white_acceleration(dt, 3.0, 0.05))


def test_nothing_of_a_frame_stays_on_the_tracker() -> None:
    trk = RobustTracker(RobustParams(appearance=AppearanceModel(0.3, 0.7, 0.4)))
    before = set(vars(trk))
    looks = _unit(2, 8)
    for k in range(6):
        trk.step(0.1 * k, FrameInput.of(np.array([[0.0, 0.0, 1.0], [2.0, 0.0, 1.0]]), looks))
    assert set(vars(trk)) == before
    assert len(trk.live_ids()) == 2 and all(len(t.gallery) for t in trk.tracks)  # type: ignore[arg-type]
