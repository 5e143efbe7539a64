"""Ignore regions (KITTI's rule): a track left unmatched within the gate of an ignored person is dropped."""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import numpy as np
import pytest

from perception.cli import main
from tools.evaluation.distances import euclidean_distances
from tools.evaluation.evaluate import evaluate_sequences, evaluate_tables, find_sequences
from tools.evaluation.metrics import ClearMotAccumulator
from tools.evaluation.readers import TrackTable


def table(rows: list[tuple[int, int, float, float]]) -> TrackTable:
    a = np.array(rows, dtype=float).reshape(-1, 4)
    return TrackTable.from_arrays(a[:, 0], a[:, 1], a[:, 2:])


def frame(gt: dict[int, float], hyp: dict[int, float], ignored: list[float]):
    """1-D positions along x: (gt ids, hyp ids, dist, ignore_dist)."""
    g = np.array([[x, 0.0] for x in gt.values()]).reshape(-1, 2)
    h = np.array([[x, 0.0] for x in hyp.values()]).reshape(-1, 2)
    i = np.array([[x, 0.0] for x in ignored]).reshape(-1, 2)
    return list(gt), list(hyp), euclidean_distances(g, h), euclidean_distances(h, i)


# ---- the core ----------------------------------------------------------------------------

def test_track_near_an_ignored_person_is_neither_fp_nor_match() -> None:
    acc = ClearMotAccumulator(1.0, inclusive=False)
    ev = acc.update(*frame({1: 0.0}, {7: 0.1, 8: 10.2}, ignored=[10.0]))
    assert ev.matches == [(1, 7, pytest.approx(0.1))]
    assert ev.false_positives == [] and ev.ignored == [8]
    r = acc.result()
    assert (r.matches, r.false_positives, r.ignored, r.predictions) == (1, 0, 1, 1)
    assert r.mota == 1.0 and r.idf1 == 1.0 and r.idp == 1.0


def test_track_near_a_gt_person_and_an_ignored_one_matches_the_gt_person() -> None:
    acc = ClearMotAccumulator(1.0, inclusive=False)
    ev = acc.update(*frame({1: 0.0}, {7: 0.3}, ignored=[0.5]))
    assert ev.matches == [(1, 7, pytest.approx(0.3))] and ev.ignored == [] and ev.false_positives == []


def test_the_gate_is_the_match_gate() -> None:
    # 1.0 m from the ignored person: outside the strict 1 m gate, so a false positive.
    acc = ClearMotAccumulator(1.0, inclusive=False)
    assert acc.update(*frame({}, {8: 11.0}, ignored=[10.0])).false_positives == [8]
    inclusive = ClearMotAccumulator(1.0, inclusive=True)
    assert inclusive.update(*frame({}, {8: 11.0}, ignored=[10.0])).ignored == [8]


def test_dropped_track_leaves_identity_measures() -> None:
    """Track 8 is within the gate of person 1 (matched to 7) and of an ignored person: dropped.

    Without the drop, 8 would be a false positive, count in IDP's denominator, and its
    co-occurrences with person 1 could let the ID matching give person 1 the ID 8.
    """
    frames = [frame({1: 0.0}, {7: 0.0, 8: 0.6}, ignored=[1.2])] * 3
    acc = ClearMotAccumulator(1.0, inclusive=False)
    for f in frames:
        acc.update(*f)
    r = acc.result()
    assert (r.matches, r.false_positives, r.ignored, r.predictions, r.idtp) == (3, 0, 3, 3, 3)
    assert r.idf1 == 1.0 and r.idp == 1.0
    assert (r.mostly_tracked, r.gt_tracks) == (1, 1)

    plain = ClearMotAccumulator(1.0, inclusive=False)
    for g, h, d, _ in frames:
        plain.update(g, h, d)
    p = plain.result()
    assert (p.false_positives, p.predictions) == (3, 6) and p.idf1 == pytest.approx(2 * 3 / (3 + 6))


def test_a_frame_without_ignored_people_changes_nothing() -> None:
    acc = ClearMotAccumulator(1.0, inclusive=False)
    g, h, d, _ = frame({1: 0.0}, {7: 5.0}, ignored=[])
    assert acc.update(g, h, d, np.zeros((1, 0))).false_positives == [7]
    assert acc.update(g, [], None, np.zeros((0, 1))).misses == [1]


def test_evaluate_tables_drops_before_hota_and_idf1() -> None:
    gt = table([(f, 1, 0.0, 0.0) for f in range(4)])
    ignore = table([(f, 50, 5.0, 0.0) for f in range(4)])
    hyp = table([(f, 7, 0.0, 0.0) for f in range(4)] + [(f, 9, 5.3, 0.0) for f in range(4)])
    with_ignore = evaluate_tables(gt, hyp, ignore=ignore)
    without = evaluate_tables(gt, hyp)
    assert (with_ignore.false_positives, with_ignore.ignored, with_ignore.mota) == (0, 4, 1.0)
    assert (without.false_positives, without.ignored) == (4, 0)
    assert with_ignore.idf1 == 1.0 and without.idf1 == pytest.approx(2 * 4 / (4 + 8))
    # HOTA sees only track 7, on person 1: every detection a TP at every alpha.
    assert with_ignore.hota_counts.fp == (0,) * 19 and with_ignore.deta == pytest.approx(1.0)
    assert without.hota_counts.fp[0] == 4 and without.deta < 1.0


def test_ignore_rows_in_other_frames_do_not_apply() -> None:
    gt = table([(0, 1, 0.0, 0.0)])
    hyp = table([(0, 7, 5.0, 0.0)])
    r = evaluate_tables(gt, hyp, ignore=table([(1, 50, 5.0, 0.0)]))
    assert (r.false_positives, r.ignored) == (1, 0)


# ---- files, directories and the CLI ----------------------------------------------------

GT = "frame,id,x,y,z\n1,1,0.0,0.0,1.0\n2,1,0.0,0.0,1.0\n"
IGNORE = "frame,id,x,y,z\n1,5,8.0,0.0,1.0\n2,5,8.0,0.0,1.0\n"
# Track 7 follows person 1; track 9 sits on the ignored person; track 11 is clutter in frame 2.
TRACKS = ("frame,stamp,id,x,y,z\n1,0.0,7,0.1,0.0,1.0\n1,0.0,9,8.3,0.1,1.0\n"
          "2,0.1,7,0.1,0.0,1.0\n2,0.1,9,8.3,0.1,1.0\n2,0.1,11,4.0,4.0,1.0\n")


def test_cli_file_inputs(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    (tmp_path / "gt.csv").write_text(GT)
    (tmp_path / "ignore.csv").write_text(IGNORE)
    (tmp_path / "tracks.csv").write_text(TRACKS)
    argv = ["evaluate", "--gt", str(tmp_path / "gt.csv"), "--tracks", str(tmp_path / "tracks.csv")]
    assert main([*argv, "--gt-ignore", str(tmp_path / "ignore.csv"), "--json"]) == 0
    out = json.loads(capsys.readouterr().out)
    assert out["ignore_regions"] is True and out["hota_similarity"] == "max(0, 1 - d / 2 m)"
    o = out["overall"]
    assert (o["matches"], o["false_positives"], o["ignored"], o["predictions"]) == (2, 1, 2, 3)
    assert o["mota"] == pytest.approx(0.5) and o["idp"] == pytest.approx(2 / 3)

    assert main(argv + ["--json"]) == 0
    plain = json.loads(capsys.readouterr().out)["overall"]
    assert (plain["false_positives"], plain["ignored"], plain["mota"]) == (3, 0, pytest.approx(-0.5))

    assert main([*argv, "--gt-ignore", str(tmp_path / "ignore.csv")]) == 0
    text = capsys.readouterr().out
    assert "ignored" in text.splitlines()[1].split() and "ignored person dropped" in text.splitlines()[0]


def test_kitti_layout_one_folder(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """gt_SEQ, gt_ignore_SEQ and dets_SEQ side by side; tracks as SEQ.csv or tracks_SEQ.csv elsewhere."""
    data, out = tmp_path / "kitti", tmp_path / "out"
    data.mkdir()
    out.mkdir()
    for seq in ("0000", "0002"):
        (data / f"gt_{seq}.csv").write_text(GT)
        (data / f"gt_ignore_{seq}.csv").write_text(IGNORE)
        (data / f"dets_{seq}.csv").write_text("frame,stamp,x,y,z,score\n1,0.0,0,0,1,3.0\n")
    (out / "0000.csv").write_text(TRACKS)
    (out / "tracks_0002.csv").write_text(TRACKS)
    seqs = find_sequences(data, out, data)
    assert [(s.name, s.gt.name, s.tracks.name, s.ignore.name) for s in seqs] == [
        ("0000", "gt_0000.csv", "0000.csv", "gt_ignore_0000.csv"),
        ("0002", "gt_0002.csv", "tracks_0002.csv", "gt_ignore_0002.csv")]
    assert main(["evaluate", "--gt", str(data), "--gt-ignore", str(data), "--tracks", str(out), "--json"]) == 0
    result = json.loads(capsys.readouterr().out)
    assert sorted(result["sequences"]) == ["0000", "0002"]
    assert (result["overall"]["ignored"], result["overall"]["false_positives"]) == (4, 2)
    # gt and tracks in one folder too; a single gt_SEQ file is sequence SEQ, its ignore file found in a folder.
    shutil.copy(out / "0000.csv", data / "tracks_0000.csv")
    shutil.copy(out / "tracks_0002.csv", data / "tracks_0002.csv")
    assert evaluate_sequences(data, data, ignore=data).overall.ignored == 4
    single = find_sequences(data / "gt_0000.csv", out / "0000.csv", data)
    assert [(s.name, s.ignore.name) for s in single] == [("0000", "gt_ignore_0000.csv")]


def test_ignore_errors(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    for d in ("gt", "tr", "ign"):
        (tmp_path / d).mkdir()
    (tmp_path / "gt" / "a.csv").write_text(GT)
    (tmp_path / "tr" / "a.csv").write_text(TRACKS)
    (tmp_path / "ign" / "gt_ignore_b.csv").write_text(IGNORE)

    def error(*argv: str) -> str:
        assert main(["evaluate", *argv]) == 2
        return capsys.readouterr().err

    gt, tr, ign = (str(tmp_path / d) for d in ("gt", "tr", "ign"))
    assert "no ignore file for any sequence" in error("--gt", gt, "--tracks", tr, "--gt-ignore", ign)
    assert "must be one too" in error("--gt", gt, "--tracks", tr, "--gt-ignore", str(tmp_path / "gt" / "a.csv"))
    assert "no ignore file for sequence 'a'" in error("--gt", str(tmp_path / "gt" / "a.csv"),
                                                      "--tracks", str(tmp_path / "tr" / "a.csv"), "--gt-ignore", ign)
    assert "nope: no such file" in error("--gt", gt, "--tracks", tr, "--gt-ignore", str(tmp_path / "nope"))
    assert "--gt-ignore applies to --format tracks" in error("--format", "motchallenge", "--gt", gt, "--tracks", tr,
                                                             "--gt-ignore", ign)
    (tmp_path / "ign" / "a.csv").write_text("frame,id,x,y,z\n1,5,abc,0,1\n")
    assert "a.csv:2: column 'x': 'abc' is not a number" in error("--gt", gt, "--tracks", tr, "--gt-ignore", ign)


def test_kitti_dev_set_ignored_people_as_tracks_are_all_dropped(shared_data: Path, tmp_path: Path) -> None:
    """On the real KITTI dev set: tracks = the GT people plus every ignored person -> no FP, all dropped."""
    src = shared_data / "kitti_ped_dev"
    if not (src / "gt_ignore_0000.csv").is_file():
        pytest.skip(f"KITTI pedestrian dev set not found under {src}")
    out = tmp_path / "out"
    out.mkdir()
    n_ignore = 0
    for gt_file in sorted(src.glob("gt_[0-9]*.csv")):
        seq = gt_file.stem[len("gt_"):]
        gt_lines = gt_file.read_text().splitlines()
        ign_lines = (src / f"gt_ignore_{seq}.csv").read_text().splitlines()[1:]
        n_ignore += len(ign_lines)
        shifted = [",".join([c[0], str(100000 + int(c[1])), *c[2:]]) for c in (ln.split(",") for ln in ign_lines)]
        (out / f"tracks_{seq}.csv").write_text("\n".join(gt_lines + shifted) + "\n")
    report = evaluate_sequences(src, out, ignore=src)
    o = report.overall
    assert len(report.sequences) == 7 and o.objects == 1309
    assert (o.false_positives, o.misses, o.id_switches, o.mota, o.idf1) == (0, 0, 0, 1.0, 1.0)
    assert o.ignored == n_ignore > 0 and o.predictions == o.objects
    assert o.hota == pytest.approx(1.0)
    plain = evaluate_sequences(src, out).overall
    assert plain.false_positives == n_ignore
