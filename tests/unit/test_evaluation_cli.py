"""``perception evaluate`` end to end: the py-motmetrics oracle, tracking CSVs and input errors."""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import pytest

from perception.cli import main
from tools.evaluation.evaluate import evaluate_sequences, format_table

# py-motmetrics 1.4.0 on its own TUD files (../shared/data/motchallenge/README.md).
ORACLE = {
    "TUD-Campus": dict(frames=71, objects=359, matches=202, false_positives=13, misses=150, id_switches=7,
                       fragmentations=7, mota=0.526462, motp=0.277201, idf1=0.557659, idp=0.729730,
                       idr=0.451253, mostly_tracked=1, partially_tracked=6, mostly_lost=1),
    "TUD-Stadtmitte": dict(frames=179, objects=1156, matches=697, false_positives=45, misses=452, id_switches=7,
                           fragmentations=6, mota=0.564014, motp=0.345904, idf1=0.644619, idp=0.819760,
                           idr=0.531142, mostly_tracked=5, partially_tracked=4, mostly_lost=1),
    "overall": dict(frames=250, objects=1515, matches=899, false_positives=58, misses=602, id_switches=14,
                    fragmentations=13, mota=0.555116, motp=0.330177, idf1=0.624296, idp=0.799176,
                    idr=0.512211, mostly_tracked=6, partially_tracked=10, mostly_lost=2),
}


def evaluate_json(capsys: pytest.CaptureFixture[str], *argv: str) -> dict:
    assert main(["evaluate", *argv, "--json"]) == 0
    return json.loads(capsys.readouterr().out)


def expect_error(capsys: pytest.CaptureFixture[str], *argv: str) -> str:
    assert main(["evaluate", *argv]) == 2
    err = capsys.readouterr().err
    assert err.startswith("perception: error: ") and "Traceback" not in err
    return err


def check_oracle(result: dict, expected: dict) -> None:
    for name, value in expected.items():
        if isinstance(value, int):
            assert result[name] == value, name
        else:
            assert result[name] == pytest.approx(value, abs=1e-3), name


@pytest.fixture
def tud(shared_data: Path, tmp_path: Path) -> tuple[Path, Path]:
    """GT and tracks directories of same-named files, built from the shared TUD files."""
    src = shared_data / "motchallenge"
    if not (src / "TUD-Campus" / "gt.txt").is_file():
        pytest.skip(f"MOTChallenge oracle files not found under {src}")
    gt, tracks = tmp_path / "gt", tmp_path / "tracks"
    gt.mkdir()
    tracks.mkdir()
    for seq in ("TUD-Campus", "TUD-Stadtmitte"):
        shutil.copy(src / seq / "gt.txt", gt / f"{seq}.txt")
        shutil.copy(src / seq / "test.txt", tracks / f"{seq}.txt")
    return gt, tracks


@pytest.mark.parametrize("seq", ["TUD-Campus", "TUD-Stadtmitte"])
def test_oracle_per_sequence_file(shared_data: Path, capsys: pytest.CaptureFixture[str], seq: str) -> None:
    src = shared_data / "motchallenge" / seq
    if not (src / "gt.txt").is_file():
        pytest.skip(f"MOTChallenge oracle files not found under {src}")
    out = evaluate_json(capsys, "--format", "motchallenge", "--gt", str(src / "gt.txt"),
                        "--tracks", str(src / "test.txt"))
    assert list(out["sequences"]) == [seq]
    check_oracle(out["sequences"][seq], ORACLE[seq])
    check_oracle(out["overall"], ORACLE[seq])


def test_oracle_directories_and_overall(tud: tuple[Path, Path], capsys: pytest.CaptureFixture[str]) -> None:
    gt, tracks = tud
    out = evaluate_json(capsys, "--format", "motchallenge", "--gt", str(gt), "--tracks", str(tracks))
    assert out["match_rule"] == "1 - IoU <= 0.5"
    for seq in ("TUD-Campus", "TUD-Stadtmitte"):
        check_oracle(out["sequences"][seq], ORACLE[seq])
    check_oracle(out["overall"], ORACLE["overall"])


def test_oracle_table_output(tud: tuple[Path, Path], capsys: pytest.CaptureFixture[str]) -> None:
    gt, tracks = tud
    assert main(["evaluate", "--format", "motchallenge", "--gt", str(gt), "--tracks", str(tracks)]) == 0
    lines = capsys.readouterr().out.splitlines()
    overall = [ln.split() for ln in lines if ln.startswith("overall")]
    assert overall[0][:4] == ["overall", "1515", "899", "602"] and overall[0][-1] == "55.51"
    assert overall[1][1] == "62.43"


def test_motchallenge_layout_gt_directory(tud: tuple[Path, Path], tmp_path: Path,
                                          capsys: pytest.CaptureFixture[str]) -> None:
    gt, tracks = tud
    layout = tmp_path / "mot"
    for f in gt.iterdir():
        (layout / f.stem / "gt").mkdir(parents=True)
        shutil.copy(f, layout / f.stem / "gt" / "gt.txt")
    out = evaluate_json(capsys, "--format", "motchallenge", "--gt", str(layout), "--tracks", str(tracks))
    check_oracle(out["overall"], ORACLE["overall"])


# ---- tracking CSVs (metres) -------------------------------------------------------------

def write(path: Path, text: str) -> Path:
    path.write_text(text)
    return path


GT_CSV = """frame,id,x,y,z
1,1,0.0,0.0,1.0
1,2,5.0,0.0,1.0
2,1,0.0,0.0,1.0
2,2,5.0,0.0,1.0
3,1,0.0,0.0,1.0
4,1,0.0,0.0,1.0
5,1,0.0,0.0,1.0
"""

# Person 2 (track 8) leaves after frame 2; in frame 4 person 1 is given ID 8: a recall error.
TRACKS_CSV = """frame,stamp,id,x,y,z,extra
1,0.0,7,0.1,0.0,1.0,a
1,0.0,8,5.0,0.2,1.0,a
2,0.1,7,0.1,0.0,1.0,a
2,0.1,8,5.0,0.2,1.0,a
3,0.2,7,0.1,0.0,1.0,a
4,0.3,8,0.3,0.0,2.5,a
5,0.4,8,0.3,0.0,2.5,a
"""


def test_recall_error_counted_from_the_cli(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    gt = write(tmp_path / "gt.csv", GT_CSV)
    tracks = write(tmp_path / "tracks.csv", TRACKS_CSV)
    r = evaluate_json(capsys, "--gt", str(gt), "--tracks", str(tracks))["overall"]
    assert (r["objects"], r["matches"], r["id_switches"], r["recall_errors"], r["misses"]) == (7, 6, 1, 1, 0)
    assert r["motp"] == pytest.approx((0.1 * 3 + 0.2 * 2 + 0.3 * 2) / 7)
    assert r["mota"] == pytest.approx(1 - 1 / 7)
    assert r["id_switches_pct"] == pytest.approx(100 / 7)


def test_dims_3_uses_height(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    gt = write(tmp_path / "gt.csv", GT_CSV)
    tracks = write(tmp_path / "tracks.csv", TRACKS_CSV)
    r = evaluate_json(capsys, "--gt", str(gt), "--tracks", str(tracks), "--dims", "3")
    assert r["match_rule"] == "3-D (x, y, z) distance < 1 m"
    # In 3-D, frames 4 and 5 are 1.53 m off: misses and false positives instead of matches.
    o = r["overall"]
    assert (o["matches"], o["misses"], o["false_positives"], o["recall_errors"]) == (5, 2, 2, 0)


def test_threshold_flag(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    gt = write(tmp_path / "gt.csv", GT_CSV)
    tracks = write(tmp_path / "tracks.csv", TRACKS_CSV)
    o = evaluate_json(capsys, "--gt", str(gt), "--tracks", str(tracks), "--threshold", "0.25")["overall"]
    assert (o["matches"], o["misses"]) == (5, 2)


def test_ground_truth_against_itself_in_directories(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    for d in ("gt", "tr"):
        (tmp_path / d).mkdir()
        write(tmp_path / d / "still.csv", GT_CSV)
        write(tmp_path / d / "moving.csv", GT_CSV.replace("0.0,0.0", "1.0,2.0"))
    write(tmp_path / "tr" / "unrelated.csv", GT_CSV)  # no ground truth: ignored with a warning
    out = evaluate_json(capsys, "--gt", str(tmp_path / "gt"), "--tracks", str(tmp_path / "tr"))
    assert sorted(out["sequences"]) == ["moving", "still"]
    assert out["overall"]["objects"] == 14 and out["overall"]["mota"] == 1.0 and out["overall"]["idf1"] == 1.0
    report = evaluate_sequences(tmp_path / "gt", tmp_path / "tr")
    table = format_table(report)
    assert "overall" in table and "recall err" in table and "consistency%" in table


# ---- errors --------------------------------------------------------------------------------

@pytest.mark.parametrize(
    ("tracks_text", "fragment"),
    [
        ("frame,stamp,id,x,y\n1,0,7,0,0\n", "header lacks column(s) z"),
        ("frame,stamp,id,x,y,z\n1,0,7,0,abc,1\n", "tracks.csv:2: column 'y': 'abc' is not a number"),
        ("frame,stamp,id,x,y,z\n1,0,7.5,0,0,1\n", "tracks.csv:2: column 'id': '7.5' is not an integer"),
        ("frame,stamp,id,x,y,z\n1,0,7,nan,0,1\n", "column 'x': 'nan' is not a finite number"),
        ("frame,stamp,id,x,y,z\n1,0,7,0,0\n", "tracks.csv:2: 5 columns, the header has 6"),
        ("frame,stamp,id,x,y,z\n1,0,7,0,0,1\n2,0,7,0,0,1\n1,0,7,1,1,1\n", "tracks.csv:4: ID 7 appears twice in frame 1 (first on line 2)"),
        ("", "tracks.csv: empty file"),
    ],
)
def test_csv_errors_name_file_line_and_column(tmp_path: Path, capsys: pytest.CaptureFixture[str],
                                              tracks_text: str, fragment: str) -> None:
    gt = write(tmp_path / "gt.csv", GT_CSV)
    tracks = write(tmp_path / "tracks.csv", tracks_text)
    assert fragment in expect_error(capsys, "--gt", str(gt), "--tracks", str(tracks))


def test_motchallenge_short_row(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    gt = write(tmp_path / "gt.txt", "1,1,0,0,10,10,1\n1,2,0,0\n")
    err = expect_error(capsys, "--format", "motchallenge", "--gt", str(gt), "--tracks", str(gt))
    assert "gt.txt:2: 4 columns" in err


def test_motchallenge_gt_drops_rows_below_confidence_1(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    gt = write(tmp_path / "gt.txt", "1,1,0,0,10,10,1,-1,-1,-1\n1,2,50,50,10,10,0,-1,-1,-1\n")
    hyp = write(tmp_path / "hyp.txt", "1,5,1,0,10,10,-1,-1,-1,-1\n")
    o = evaluate_json(capsys, "--format", "motchallenge", "--gt", str(gt), "--tracks", str(hyp))["overall"]
    assert (o["objects"], o["matches"], o["false_positives"]) == (1, 1, 0)
    assert o["motp"] == pytest.approx(1 - 90 / 110)


def test_path_errors(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    gt_dir, tr_dir = tmp_path / "gt", tmp_path / "tr"
    gt_dir.mkdir()
    tr_dir.mkdir()
    gt = write(gt_dir / "seq1.csv", GT_CSV)
    assert "no tracks file for sequence(s) seq1" in expect_error(capsys, "--gt", str(gt_dir), "--tracks", str(tr_dir))
    assert "missing.csv: no such file" in expect_error(capsys, "--gt", str(gt), "--tracks", str(tmp_path / "missing.csv"))
    assert "two files or two directories" in expect_error(capsys, "--gt", str(gt), "--tracks", str(tr_dir))
    assert "--dims applies to --format tracks" in expect_error(
        capsys, "--format", "motchallenge", "--dims", "3", "--gt", str(gt), "--tracks", str(gt))
    assert "--threshold must be a positive" in expect_error(
        capsys, "--threshold", "-1", "--gt", str(gt), "--tracks", str(gt))


def test_header_only_tracks_file_means_all_misses(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    gt = write(tmp_path / "gt.csv", GT_CSV)
    tracks = write(tmp_path / "tracks.csv", "frame,stamp,id,x,y,z\n")
    o = evaluate_json(capsys, "--gt", str(gt), "--tracks", str(tracks))["overall"]
    assert (o["objects"], o["misses"], o["mota"], o["motp"], o["consistency"]) == (7, 7, 0.0, None, None)
