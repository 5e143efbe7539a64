"""The metrics core on small hand-made cases, one CLEAR MOT quantity at a time."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from tools.evaluation.distances import euclidean_distances, iou_distances
from tools.evaluation.evaluate import evaluate_tables
from tools.evaluation.metrics import ClearMot, ClearMotAccumulator, evaluate_frames, gate_distances, solve_assignment
from tools.evaluation.readers import TrackTable


def points_frame(gt: dict[int, float], hyp: dict[int, float]) -> tuple[list[int], list[int], np.ndarray]:
    """A frame of 1-D positions (metres along x): ids and their distance matrix."""
    g = np.array([[v, 0.0] for v in gt.values()]).reshape(-1, 2)
    h = np.array([[v, 0.0] for v in hyp.values()]).reshape(-1, 2)
    return list(gt), list(hyp), euclidean_distances(g, h)


def run(frames: list[tuple[dict[int, float], dict[int, float]]], threshold: float = 1.0) -> ClearMot:
    return evaluate_frames((points_frame(g, h) for g, h in frames), threshold, inclusive=False)


def test_perfect_tracking() -> None:
    r = run([({1: 0.0, 2: 5.0}, {7: 0.0, 8: 5.0})] * 4)
    assert (r.objects, r.matches, r.misses, r.false_positives, r.id_switches) == (8, 8, 0, 0, 0)
    assert r.mota == 1.0 and r.motp == 0.0 and r.idf1 == 1.0
    assert (r.mostly_tracked, r.partially_tracked, r.mostly_lost) == (2, 0, 0)
    assert r.consistency == 1.0


def test_miss_and_mota() -> None:
    r = run([({1: 0.0}, {7: 0.2}), ({1: 0.0}, {}), ({1: 0.0}, {7: 0.4})])
    assert (r.objects, r.matches, r.misses, r.false_positives) == (3, 2, 1, 0)
    assert r.mota == pytest.approx(1 - 1 / 3)
    assert r.motp == pytest.approx(0.3)


def test_hypothesis_beyond_threshold_is_fp_and_miss() -> None:
    r = run([({1: 0.0}, {7: 1.5})])
    assert (r.matches, r.misses, r.false_positives) == (0, 1, 1)
    assert r.mota == -1.0
    assert math.isnan(r.motp)


def test_threshold_is_strict_or_inclusive() -> None:
    frame = points_frame({1: 0.0}, {7: 1.0})
    assert evaluate_frames([frame], 1.0, inclusive=False).matches == 0
    assert evaluate_frames([frame], 1.0, inclusive=True).matches == 1


def test_id_switch_to_a_new_id_is_not_a_recall_error() -> None:
    r = run([({1: 0.0}, {7: 0.0}), ({1: 0.0}, {9: 0.0})])
    assert (r.matches, r.id_switches, r.recall_errors) == (1, 1, 0)
    assert r.mota == pytest.approx(0.5)
    assert r.detections == 2 and r.objects == r.matches + r.id_switches + r.misses


def test_recall_error_crafted_case() -> None:
    """Person 2 is tracked as 8, leaves; person 1 (tracked as 7) is then given ID 8."""
    frames = [({1: 0.0, 2: 5.0}, {7: 0.0, 8: 5.0})] * 3 + [({1: 0.0}, {7: 0.0})] + [({1: 0.0}, {8: 0.1})] * 2
    # Then person 1 switches again, to an ID nobody had: a switch, not a recall error.
    frames += [({1: 0.0}, {9: 0.0})]
    acc = ClearMotAccumulator(1.0, inclusive=False)
    events = [acc.update(*points_frame(g, h)) for g, h in frames]
    assert events[4].recall_errors == [(1, 8, pytest.approx(0.1))]
    assert events[5].switches == [] and events[5].matches == [(1, 8, pytest.approx(0.1))]
    assert events[6].switches == [(1, 9, 0.0)] and events[6].recall_errors == []
    r = acc.result()
    assert (r.id_switches, r.recall_errors) == (2, 1)


def test_switching_back_to_an_id_only_this_person_had_is_not_a_recall_error() -> None:
    r = run([({1: 0.0}, {7: 0.0}), ({1: 0.0}, {9: 0.0}), ({1: 0.0}, {7: 0.0})])
    assert (r.id_switches, r.recall_errors) == (2, 0)


def test_correspondence_kept_while_valid_even_if_another_is_closer() -> None:
    frames = [
        ({1: 0.0}, {7: 0.1, 8: 3.0}),  # 1 <-> 7
        ({1: 0.0}, {7: 0.9, 8: 0.0}),  # 7 still within 1 m: kept, although 8 is closer
        ({1: 0.0}, {7: 1.2, 8: 0.0}),  # 7 no longer valid: switch to 8
    ]
    acc = ClearMotAccumulator(1.0, inclusive=False)
    events = [acc.update(*points_frame(g, h)) for g, h in frames]
    assert events[1].matches == [(1, 7, pytest.approx(0.9))] and events[1].false_positives == [8]
    assert events[2].switches == [(1, 8, 0.0)] and events[2].false_positives == [7]
    r = acc.result()
    assert (r.matches, r.id_switches, r.false_positives) == (2, 1, 3)


def test_correspondence_survives_a_gap() -> None:
    """A person missed for a while and found again by the same ID is no switch."""
    r = run([({1: 0.0}, {7: 0.0}), ({1: 0.0}, {}), ({1: 0.0}, {7: 0.0})])
    assert (r.id_switches, r.misses, r.fragmentations) == (0, 1, 1)


def test_hungarian_minimises_total_distance() -> None:
    # Greedy would give 1<->7 (0.1) and leave 2 unmatched; Hungarian matches both.
    acc = ClearMotAccumulator(1.0, inclusive=False)
    ev = acc.update(*points_frame({1: 0.0, 2: -0.8}, {7: -0.1, 8: 0.5}))
    assert sorted(ev.matches) == [(1, 8, pytest.approx(0.5)), (2, 7, pytest.approx(0.7))]


def test_assignment_prefers_more_pairs_to_a_cheaper_single_pair() -> None:
    cost = np.array([[0.0, 0.4], [0.3, np.nan]])
    rows, cols = solve_assignment(cost)
    assert list(zip(rows.tolist(), cols.tolist())) == [(0, 1), (1, 0)]
    assert solve_assignment(np.full((2, 3), np.nan))[0].size == 0


def test_fragmentations_count_interruptions_inside_the_tracked_span() -> None:
    present = {1: 0.0}
    hit = ({**present}, {7: 0.0})
    miss = ({**present}, {})
    # tracked, missed, tracked, missed, missed, tracked, then missed at the end (outside the span)
    r = run([miss, hit, miss, hit, miss, miss, hit, miss])
    assert r.fragmentations == 2
    assert r.misses == 5


def test_mostly_tracked_partially_tracked_mostly_lost() -> None:
    frames = []
    for k in range(10):
        hyp = {}
        if k < 8:
            hyp[7] = 0.0  # person 1: 8/10 -> MT (>= 80 %)
        if k < 2:
            hyp[8] = 10.0  # person 2: 2/10 -> PT (>= 20 %)
        if k < 1:
            hyp[9] = 20.0  # person 3: 1/10 -> ML (< 20 %)
        frames.append(({1: 0.0, 2: 10.0, 3: 20.0}, hyp))
    r = run(frames)
    assert (r.mostly_tracked, r.partially_tracked, r.mostly_lost, r.gt_tracks) == (1, 1, 1, 3)


def test_consistency_histogram() -> None:
    frames = [({1: 0.0, 2: 10.0}, {7: 0.0, 9: 10.0})] * 4 + [({1: 0.0}, {7: 0.0})] * 2
    frames += [({1: 0.0}, {8: 0.0})] * 2  # person 1: 6 frames as 7, 2 as 8; person 2: 4 as 9
    r = run(frames)
    assert r.consistency_counts == (10, 2)
    assert r.consistency_histogram == pytest.approx([10 / 12, 2 / 12])
    assert r.consistency == pytest.approx(10 / 12)


def test_idf1_global_id_matching() -> None:
    # Person 1 is 7 for two frames, then 8 for two frames: only one of them can be its ID.
    r = run([({1: 0.0}, {7: 0.0})] * 2 + [({1: 0.0}, {8: 0.0})] * 2)
    assert (r.idtp, r.idfn, r.idfp) == (2, 2, 2)
    assert r.idf1 == pytest.approx(0.5) and r.idp == pytest.approx(0.5) and r.idr == pytest.approx(0.5)


def test_combine_sums_counts_and_pads_histograms() -> None:
    a = run([({1: 0.0}, {7: 0.0}), ({1: 0.0}, {8: 0.0})])
    b = run([({1: 0.0}, {7: 0.5})])
    total = ClearMot.combine([a, b])
    assert (total.objects, total.matches, total.id_switches, total.frames) == (3, 2, 1, 3)
    assert total.consistency_counts == (2, 1)
    assert total.motp == pytest.approx(0.5 / 3)
    assert total.to_dict()["mota"] == pytest.approx(1 - 1 / 3)


def test_empty_evaluation_is_nan_not_an_error() -> None:
    r = evaluate_frames([], 1.0)
    assert r.objects == 0 and math.isnan(r.mota) and r.to_dict()["mota"] is None


def test_duplicate_ids_in_a_frame_are_rejected() -> None:
    with pytest.raises(ValueError, match="unique"):
        ClearMotAccumulator(1.0).update([1, 1], [7], np.zeros((2, 1)))


def test_gate_distances() -> None:
    d = gate_distances([[0.5, 1.0, np.inf]], 1.0, inclusive=True)
    assert d[0, 0] == 0.5 and d[0, 1] == 1.0 and np.isnan(d[0, 2])
    assert np.isnan(gate_distances([[1.0]], 1.0, inclusive=False)[0, 0])


def test_iou_distances() -> None:
    gt = np.array([[0.0, 0.0, 2.0, 2.0]])
    hyp = np.array([[0.0, 0.0, 2.0, 2.0], [1.0, 0.0, 2.0, 2.0], [5.0, 5.0, 1.0, 1.0], [0.0, 0.0, 0.0, 0.0]])
    assert iou_distances(gt, hyp) == pytest.approx(np.array([[0.0, 1 - 2 / 6, 1.0, 1.0]]))


def test_euclidean_distances_shape_and_values() -> None:
    d = euclidean_distances(np.array([[0.0, 0.0, 0.0], [1.0, 1.0, 1.0]]), np.array([[3.0, 4.0, 0.0]]))
    assert d.shape == (2, 1) and d[0, 0] == pytest.approx(5.0)


@settings(max_examples=60, deadline=None)
@given(st.integers(0, 2**31 - 1))
def test_invariants_on_random_sequences(seed: int) -> None:
    """Every object is a match, a switch or a miss; every hypothesis a match, a switch or an FP."""
    rng = np.random.default_rng(seed)
    gt_rows, hyp_rows = [], []
    for frame in range(int(rng.integers(1, 15))):
        for i in rng.choice(6, size=int(rng.integers(0, 6)), replace=False):
            gt_rows.append((frame, i, *rng.uniform(0, 4, 2)))
        for h in rng.choice(8, size=int(rng.integers(0, 6)), replace=False):
            hyp_rows.append((frame, 100 + h, *rng.uniform(0, 4, 2)))
    gt = np.array(gt_rows, dtype=float).reshape(-1, 4)
    hyp = np.array(hyp_rows, dtype=float).reshape(-1, 4)
    r = evaluate_tables(TrackTable.from_arrays(gt[:, 0], gt[:, 1], gt[:, 2:]),
                        TrackTable.from_arrays(hyp[:, 0], hyp[:, 1], hyp[:, 2:]))
    assert r.objects == len(gt_rows) == r.matches + r.id_switches + r.misses
    assert r.predictions == len(hyp_rows) == r.detections + r.false_positives
    assert 0 <= r.recall_errors <= r.id_switches
    assert r.idtp <= min(r.objects, r.predictions)
    assert r.mostly_tracked + r.partially_tracked + r.mostly_lost == r.gt_tracks
    assert sum(r.consistency_counts) == r.detections
    if r.detections:
        assert 0.0 <= r.motp < 1.0
