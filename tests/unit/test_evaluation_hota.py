"""HOTA, DetA and AssA: hand-made cases, TrackEval's figures on the TUD files, and TrackEval itself when installed.

TrackEval is not a test dependency: every PyPI release (trackeval 1.0.0-1.3.0, packaged
from github.com/kovalp/TrackEval, a numpy-2 port of JonathonLuiten/TrackEval) requires
``opencv-python``, which today resolves to OpenCV 5 and would overwrite this project's
``cv2`` (opencv-python-headless < 5, which keeps the HOG detector). The reference figures
below were computed with trackeval 1.3.0 in a separate virtual environment (numpy 2.4.6,
scipy 1.17.1), through its own MOTChallenge pipeline: ``Evaluator`` +
``datasets.MotChallenge2DBox`` (BENCHMARK MOT15, SEQ_INFO = the last frame of each
sequence) + ``metrics.HOTA``; the reported figure is the mean over its 19 alphas. The
same run gave MOTA and IDF1 equal to py-motmetrics's (tests/unit/test_evaluation_cli.py).
The ``trackeval`` tests below rerun that comparison wherever the package is importable.
"""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import numpy as np
import pytest

from perception.cli import main
from tools.evaluation.distances import distance_similarity, euclidean_distances, iou_similarity
from tools.evaluation.evaluate import evaluate_sequences, evaluate_tables
from tools.evaluation.metrics import HOTA_ALPHAS, ClearMot, Hota, HotaAccumulator, evaluate_hota
from tools.evaluation.readers import TrackTable

# trackeval 1.3.0 on ../shared/data/motchallenge (gt.txt against test.txt), rounded to 6 decimals.
TRACKEVAL = {
    "TUD-Campus": dict(hota=0.391397, deta=0.418047, assa=0.369121, detre=0.441577, detpr=0.714083,
                       assre=0.383225, asspr=0.754050, loca=0.770052, tp_alpha_005=222),
    "TUD-Stadtmitte": dict(hota=0.397849, deta=0.392268, assa=0.408841, detre=0.413131, detpr=0.637622,
                           assre=0.449219, asspr=0.631203, loca=0.737521, tp_alpha_005=747),
    "overall": dict(hota=0.399957, deta=0.397683, assa=0.412450, detre=0.419871, detpr=0.655103,
                    assre=0.450665, asspr=0.692211, loca=0.732480, tp_alpha_005=969),
}
FIGURES = ("hota", "deta", "assa", "detre", "detpr", "assre", "asspr", "loca")
TUD = ("TUD-Campus", "TUD-Stadtmitte")


def tud_dirs(shared_data: Path, tmp_path: Path) -> tuple[Path, Path]:
    src = shared_data / "motchallenge"
    if not (src / "TUD-Campus" / "gt.txt").is_file():
        pytest.skip(f"MOTChallenge oracle files not found under {src}")
    gt, tracks = tmp_path / "gt", tmp_path / "tracks"
    gt.mkdir()
    tracks.mkdir()
    for seq in TUD:
        shutil.copy(src / seq / "gt.txt", gt / f"{seq}.txt")
        shutil.copy(src / seq / "test.txt", tracks / f"{seq}.txt")
    return gt, tracks


# ---- the pinned TrackEval figures ---------------------------------------------------------

def test_tud_equals_trackeval_pinned(shared_data: Path, tmp_path: Path) -> None:
    report = evaluate_sequences(*tud_dirs(shared_data, tmp_path), fmt="motchallenge")
    for name, result in [*report.sequences, ("overall", report.overall)]:
        expected = TRACKEVAL[name]
        h = result.hota_counts
        assert h is not None
        for figure in FIGURES:
            assert getattr(h, figure) == pytest.approx(expected[figure], abs=1e-3), (name, figure)
        assert h.tp[0] == expected["tp_alpha_005"], name
        assert (result.hota, result.deta, result.assa) == (h.hota, h.deta, h.assa)


def test_tud_hota_in_cli_json_and_table(shared_data: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    gt, tracks = tud_dirs(shared_data, tmp_path)
    assert main(["evaluate", "--format", "motchallenge", "--gt", str(gt), "--tracks", str(tracks), "--json"]) == 0
    out = json.loads(capsys.readouterr().out)
    assert out["hota_similarity"] == "IoU"
    for name in TUD:
        assert out["sequences"][name]["hota"] == pytest.approx(TRACKEVAL[name]["hota"], abs=1e-3)
    overall = out["overall"]
    for figure in ("hota", "deta", "assa"):
        assert overall[figure] == pytest.approx(TRACKEVAL["overall"][figure], abs=1e-3)
    curve = overall["hota_per_alpha"]
    assert len(curve["alpha"]) == 19 and curve["alpha"][0] == 0.05 and curve["alpha"][-1] == 0.95
    assert np.mean(curve["hota"]) == pytest.approx(overall["hota"])
    assert curve["tp"][0] == TRACKEVAL["overall"]["tp_alpha_005"]

    assert main(["evaluate", "--format", "motchallenge", "--gt", str(gt), "--tracks", str(tracks)]) == 0
    lines = capsys.readouterr().out.splitlines()
    assert "HOTA (mean over alpha = 0.05..0.95; similarity IoU)" in lines
    overall_rows = [ln.split() for ln in lines if ln.startswith("overall")]
    assert len(overall_rows) == 3
    assert overall_rows[2][1:4] == ["40.00", "39.77", "41.24"]  # HOTA%, DetA%, AssA%


# ---- hand-made cases ----------------------------------------------------------------------

def test_alphas_are_trackevals() -> None:
    assert HOTA_ALPHAS.size == 19
    assert HOTA_ALPHAS[0] == pytest.approx(0.05) and HOTA_ALPHAS[-1] == pytest.approx(0.95)


def test_perfect_tracking_is_one() -> None:
    h = evaluate_hota([([1, 2], [7, 8], np.eye(2))] * 5)
    assert (h.hota, h.deta, h.assa, h.loca) == (1.0, 1.0, 1.0, 1.0)


def test_id_switch_halves_association_not_detection() -> None:
    # One person, 4 frames, seen perfectly as 7 then as 8: every TP's A(c) = 2 / (2 + 2 + 0).
    h = evaluate_hota([([1], [7], [[1.0]])] * 2 + [([1], [8], [[1.0]])] * 2)
    assert h.deta == 1.0 and h.assa == pytest.approx(0.5) and h.hota == pytest.approx(np.sqrt(0.5))
    assert h.assre == pytest.approx(0.5) and h.asspr == pytest.approx(1.0)


def test_misses_and_false_positives_lower_detection() -> None:
    # Frame 1: matched; frame 2: missed; frame 3: a false positive alone.
    h = evaluate_hota([([1], [7], [[1.0]]), ([1], [], None), ([], [9], None)])
    assert h.tp[0] == 1 and h.fn[0] == 1 and h.fp[0] == 1
    assert h.deta == pytest.approx(1 / 3) and h.detre == pytest.approx(0.5) and h.detpr == pytest.approx(0.5)
    # A(c) of (1, 7) = TPA / (TPA + FNA + FPA) = 1 / (1 + 1 + 0): person 1 is missed once.
    assert h.assa == pytest.approx(0.5)


def test_similarity_below_alpha_is_no_match() -> None:
    # Similarity 0.5: a TP for the alphas 0.05..0.50 (10 of 19), a miss and an FP above.
    h = evaluate_hota([([1], [7], [[0.5]])])
    assert list(h.tp) == [1] * 10 + [0] * 9
    assert h.deta == pytest.approx(10 / 19) and h.assa == pytest.approx(10 / 19)
    assert h.loca == pytest.approx((10 * 0.5 + 9 * 1.0) / 19)  # LocA is 1 where nothing matched, as TrackEval


def test_global_alignment_picks_the_consistent_hypothesis() -> None:
    # Two hypotheses equally close to person 1 in frame 3; 7 has been person 1 all along.
    frames = [([1], [7], [[1.0]]), ([1], [7], [[1.0]]), ([1], [8, 7], [[1.0, 1.0]])]
    acc = HotaAccumulator()
    for f in frames:
        acc.update(*f)
    h = acc.result()
    assert h.assa == pytest.approx(1.0) and h.fp[0] == 1


def test_ground_plane_similarity_is_trackevals_point_convention() -> None:
    # One person 0.5 m from its track with the 1 m gate: similarity 1 - 0.5 / 2 = 0.75, a TP up to alpha 0.75.
    gt = TrackTable.from_arrays([0, 1], [1, 1], [[0.0, 0.0], [0.0, 0.0]])
    hyp = TrackTable.from_arrays([0, 1], [7, 7], [[0.5, 0.0], [0.5, 0.0]])
    r = evaluate_tables(gt, hyp)
    assert list(r.hota_counts.tp) == [2] * 15 + [0] * 4
    assert r.deta == pytest.approx(15 / 19) and r.hota == pytest.approx(15 / 19)
    assert distance_similarity(np.array([[0.0, 1.0, 2.0, 3.0]]), 2.0).tolist() == [[1.0, 0.5, 0.0, 0.0]]
    # With --threshold 0.5 the similarity reaches 0 at 1 m: 1 - 0.5 / 1 = 0.5, a TP up to alpha 0.5.
    assert evaluate_tables(gt, hyp, threshold=0.5).hota_counts.tp[9:11] == (2, 0)


def test_empty_and_one_sided_sequences() -> None:
    assert np.isnan(evaluate_hota([]).hota)
    only_gt = evaluate_hota([([1, 2], [], None)])
    assert (only_gt.hota, only_gt.deta, only_gt.fn[0]) == (0.0, 0.0, 2)
    only_hyp = evaluate_hota([([], [7], None)])
    assert (only_hyp.hota, only_hyp.fp[0]) == (0.0, 1)
    never_together = evaluate_hota([([1], [], None), ([], [7], None), ([2], [8], [[0.0]])])
    assert (never_together.hota, never_together.fn[0], never_together.fp[0]) == (0.0, 2, 2)
    assert ClearMot().to_dict()["hota"] is None


def test_combine_weights_assa_by_true_positives() -> None:
    a = evaluate_hota([([1], [7], [[1.0]])] * 2 + [([1], [8], [[1.0]])] * 2)  # AssA 0.5 over 4 TPs
    b = evaluate_hota([([1], [7], [[1.0]])] * 4)  # AssA 1 over 4 TPs
    total = Hota.combine([a, b])
    assert total.assa == pytest.approx(0.75) and total.deta == 1.0
    assert ClearMot.combine([ClearMot(hota_counts=a), ClearMot(hota_counts=b)]).assa == pytest.approx(0.75)
    assert ClearMot.combine([ClearMot(hota_counts=a), ClearMot()]).hota_counts is None


def test_similarity_must_be_in_unit_interval() -> None:
    with pytest.raises(ValueError, match=r"\[0, 1\]"):
        HotaAccumulator().update([1], [7], [[1.5]])
    with pytest.raises(ValueError, match="unique"):
        HotaAccumulator().update([1, 1], [7], [[1.0], [1.0]])


# ---- TrackEval itself, when installed -------------------------------------------------------

def test_tud_equals_trackeval_package(shared_data: Path, tmp_path: Path) -> None:
    trackeval = pytest.importorskip(
        "trackeval", reason="TrackEval is not installed (not a test dependency: it requires opencv-python, "
                            "which would replace this project's opencv-python-headless); the pinned test covers it")
    src = shared_data / "motchallenge"
    if not (src / "TUD-Campus" / "gt.txt").is_file():
        pytest.skip(f"MOTChallenge oracle files not found under {src}")
    root = tmp_path / "trackeval"
    lengths = {}
    for seq in TUD:
        last = max(int(np.loadtxt(src / seq / name, delimiter=",")[:, 0].max()) for name in ("gt.txt", "test.txt"))
        lengths[seq] = last
        gt_dir = root / "gt" / "MOT15-train" / seq / "gt"
        gt_dir.mkdir(parents=True)
        shutil.copy(src / seq / "gt.txt", gt_dir / "gt.txt")
        tracker_dir = root / "trackers" / "MOT15-train" / "oracle" / "data"
        tracker_dir.mkdir(parents=True, exist_ok=True)
        shutil.copy(src / seq / "test.txt", tracker_dir / f"{seq}.txt")
    evaluator = trackeval.Evaluator({"USE_PARALLEL": False, "PRINT_RESULTS": False, "PRINT_CONFIG": False,
                                     "OUTPUT_SUMMARY": False, "OUTPUT_DETAILED": False, "PLOT_CURVES": False,
                                     "TIME_PROGRESS": False})
    dataset = trackeval.datasets.MotChallenge2DBox({
        "GT_FOLDER": str(root / "gt"), "TRACKERS_FOLDER": str(root / "trackers"), "BENCHMARK": "MOT15",
        "SPLIT_TO_EVAL": "train", "TRACKERS_TO_EVAL": ["oracle"], "SEQ_INFO": lengths, "PRINT_CONFIG": False})
    results, _ = evaluator.evaluate([dataset], [trackeval.metrics.HOTA()])
    theirs = results["MotChallenge2DBox"]["oracle"]
    ours = evaluate_sequences(*tud_dirs(shared_data, tmp_path), fmt="motchallenge")
    names = {"TUD-Campus": "TUD-Campus", "TUD-Stadtmitte": "TUD-Stadtmitte", "overall": "COMBINED_SEQ"}
    for name, result in [*ours.sequences, ("overall", ours.overall)]:
        their = theirs[names[name]]["pedestrian"]["HOTA"]
        for figure, key in zip(FIGURES, ("HOTA", "DetA", "AssA", "DetRe", "DetPr", "AssRe", "AssPr", "LocA")):
            assert getattr(result.hota_counts, figure) == pytest.approx(float(np.mean(their[key])), abs=1e-3)
            # and the pinned constants are still TrackEval's
            assert TRACKEVAL[name][figure] == pytest.approx(float(np.mean(their[key])), abs=1e-6)


def test_ground_plane_equals_trackeval_point_similarity() -> None:
    """Random walks scored by TrackEval's HOTA with its point similarity (zero_distance 2 m) and by ours."""
    trackeval = pytest.importorskip(
        "trackeval", reason="TrackEval is not installed (not a test dependency, see the module docstring)")
    from trackeval.datasets._base_dataset import _BaseDataset

    rng = np.random.default_rng(3)
    gt_rows, hyp_rows = [], []
    people = rng.uniform(0, 6, (6, 2))
    for frame in range(60):
        people += rng.normal(0, 0.1, people.shape)
        for i, p in enumerate(people):
            if rng.random() < 0.9:
                gt_rows.append((frame, i, *p))
            if rng.random() < 0.85:
                tid = 100 + i + 10 * (frame // 25 if i % 2 else 0)  # some tracks change ID
                hyp_rows.append((frame, tid, *(p + rng.normal(0, 0.3, 2))))
        if rng.random() < 0.3:
            hyp_rows.append((frame, 900 + frame, *rng.uniform(0, 6, 2)))
    gt = np.array(gt_rows)
    hyp = np.array(hyp_rows)
    ours = evaluate_tables(TrackTable.from_arrays(gt[:, 0], gt[:, 1], gt[:, 2:]),
                           TrackTable.from_arrays(hyp[:, 0], hyp[:, 1], hyp[:, 2:]))

    gt_ids, hyp_ids = np.unique(gt[:, 1]), np.unique(hyp[:, 1])
    data: dict[str, object] = {"num_gt_ids": gt_ids.size, "num_tracker_ids": hyp_ids.size,
                               "num_gt_dets": len(gt), "num_tracker_dets": len(hyp),
                               "gt_ids": [], "tracker_ids": [], "similarity_scores": []}
    for frame in range(60):
        g, h = gt[gt[:, 0] == frame], hyp[hyp[:, 0] == frame]
        data["gt_ids"].append(np.searchsorted(gt_ids, g[:, 1]))
        data["tracker_ids"].append(np.searchsorted(hyp_ids, h[:, 1]))
        data["similarity_scores"].append(_BaseDataset._calculate_euclidean_similarity(g[:, 2:], h[:, 2:], 2.0))
    their = trackeval.metrics.HOTA().eval_sequence(data)
    for figure, key in zip(FIGURES, ("HOTA", "DetA", "AssA", "DetRe", "DetPr", "AssRe", "AssPr", "LocA")):
        assert getattr(ours.hota_counts, figure) == pytest.approx(float(np.mean(their[key])), abs=1e-9), figure
    # The similarity helpers are TrackEval's formulas.
    assert distance_similarity(euclidean_distances(gt[:5, 2:], hyp[:5, 2:]), 2.0) == pytest.approx(
        _BaseDataset._calculate_euclidean_similarity(gt[:5, 2:], hyp[:5, 2:], 2.0))
    boxes = rng.uniform(0, 50, (6, 4))
    assert iou_similarity(boxes[:3], boxes[3:]) == pytest.approx(
        _BaseDataset._calculate_box_ious(boxes[:3], boxes[3:], box_format="xywh"))
