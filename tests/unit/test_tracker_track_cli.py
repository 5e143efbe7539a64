"""``perception track``: the offline formats, position-only files, refusals."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from perception.cli import main
from services.tracker.offline import FormatError, frame_stamps, read_detections

DIM = 8


def write_detections(path: Path, embeddings: bool = True, skip: tuple[int, ...] = (30, 31), n: int = 60) -> None:
    """Two people walking apart in parallel (x = 1 + 0.02 k and 4 - 0.02 k) at 30 Hz."""
    rng = np.random.default_rng(0)
    looks = rng.normal(size=(2, DIM))
    looks /= np.linalg.norm(looks, axis=1, keepdims=True)
    header = "frame,stamp,x,y,z,score" + "".join(f",e{i}" for i in range(DIM)) * embeddings
    lines = [header]
    for k in range(n):
        if k in skip:
            continue
        for p, x in enumerate((1.0 + 0.02 * k, 4.0 - 0.02 * k)):
            row = [f"{k + 100}", f"{1000.0 + k / 30:.6f}", f"{x + rng.normal(scale=0.01):.4f}", f"{p * 2.0:.4f}", "1.0", "0.9"]
            if embeddings:
                e = looks[p] + rng.normal(scale=0.01, size=DIM)
                row += [f"{v:.5f}" for v in e / np.linalg.norm(e)]
            lines.append(",".join(row))
    path.write_text("\n".join(lines) + "\n")


def read_output(path: Path) -> tuple[str, np.ndarray]:
    text = path.read_text()
    header = text.splitlines()[0]
    return header, np.loadtxt(path, delimiter=",", skiprows=1, ndmin=2)


@pytest.mark.parametrize("embeddings", [True, False])
def test_thesis_profile_writes_confirmed_tracks_with_stable_ids(tmp_path: Path, embeddings: bool) -> None:
    dets, out = tmp_path / "dets.csv", tmp_path / "tracks.csv"
    write_detections(dets, embeddings)
    assert main(["track", "--detections", str(dets), "--output", str(out), "--profile", "thesis"]) == 0
    header, rows = read_output(out)
    assert header == "frame,stamp,id,x,y,z"
    frames = rows[:, 0].astype(int)
    assert frames.min() == 102  # confirmed on the third frame
    assert not set(frames) & {130, 131}  # a missed frame turns Confirmed tracks back to Tentative
    ids_by_lane = {lane: set(rows[rows[:, 4].round() == lane * 2.0][:, 2].astype(int)) for lane in (0, 1)}
    assert ids_by_lane == {0: {1}, 1: {2}}
    k = rows[:, 0] - 100
    np.testing.assert_allclose(rows[:, 1], 1000.0 + k / 30, atol=1e-5)
    assert np.all(np.bincount(frames)[[f for f in range(102, 160) if f not in (130, 131, 132, 133)]] == 2)


@pytest.mark.parametrize("embeddings", [True, False])
def test_robust_profile_coasts_through_a_short_miss_with_its_status(tmp_path: Path, embeddings: bool) -> None:
    dets, out = tmp_path / "dets.csv", tmp_path / "tracks.csv"
    write_detections(dets, embeddings)
    assert main(["track", "--detections", str(dets), "--output", str(out), "--status"]) == 0  # robust: the default
    text = out.read_text().splitlines()
    assert text[0] == "frame,stamp,id,x,y,z,status"
    rows = [line.split(",") for line in text[1:]]
    frames = np.array([int(r[0]) for r in rows])
    status = {(int(r[0]), int(r[2])): r[6] for r in rows}
    assert frames.min() == 102  # three confident hits confirm, as in the thesis
    # frames 130 and 131 have no detections: both people are reported, predicted, as coasting
    assert {status[(f, i)] for f in (130, 131) for i in (1, 2)} == {"coasting"}
    assert {v for (f, _), v in status.items() if f not in (130, 131)} == {"confirmed"}
    lanes = {int(r[2]): round(float(r[4]) / 2.0) for r in rows}
    assert lanes == {1: 0, 2: 1}  # the same two IDs throughout, and never swapped
    assert np.all(np.bincount(frames)[102:160] == 2)


def test_unknown_profile_is_refused_with_the_allowed_names(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    dets, cfg = tmp_path / "dets.csv", tmp_path / "tracker.yaml"
    write_detections(dets)
    cfg.write_text("profile: fast\n")
    code = main(["track", "--detections", str(dets), "--output", str(tmp_path / "o.csv"), "--service-config", str(cfg)])
    assert code == 2
    assert "'robust' or 'thesis'" in capsys.readouterr().err


def test_frame_stamps_are_interpolated_for_missing_frames(tmp_path: Path) -> None:
    dets = tmp_path / "dets.csv"
    dets.write_text("frame,stamp,x,y,z,score\n10,5.0,0,0,1,0.9\n10,5.0,1,0,1,0.9\n14,7.0,0,0,1,0.9\n")
    frames, stamps = frame_stamps(read_detections(dets))
    assert frames.tolist() == [10, 11, 12, 13, 14]
    np.testing.assert_allclose(stamps, [5.0, 5.5, 6.0, 6.5, 7.0])


def test_unknown_embedding_model_is_refused(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    dets = tmp_path / "dets.csv"
    write_detections(dets)
    code = main(["track", "--detections", str(dets), "--output", str(tmp_path / "o.csv"), "--embedding-model", "mynet"])
    assert code == 2
    err = capsys.readouterr().err
    assert "no appearance thresholds for embedding model 'mynet'" in err and "appearance.mynet" in err
    assert not (tmp_path / "o.csv").exists()


def test_config_file_can_add_a_model(tmp_path: Path) -> None:
    dets, cfg = tmp_path / "dets.csv", tmp_path / "tracker.yaml"
    write_detections(dets)
    cfg.write_text("appearance:\n  mynet: {t_lower: 0.25, t_upper: 0.6, t_recover: 0.35}\n")
    args = ["track", "--detections", str(dets), "--output", str(tmp_path / "o.csv"), "--service-config", str(cfg)]
    assert main(args + ["--embedding-model", "mynet"]) == 0
    assert main(args + ["--embedding-model", "trinet"]) == 0  # shipped models stay available


@pytest.mark.parametrize(
    ("content", "message"),
    [
        ("frame,x,y,z\n1,0,0,0\n", "header must start with"),
        ("frame,stamp,x,y,z,score,e1\n1,0,0,0,0,1,0\n", "e0,e1"),
        ("frame,stamp,x,y,z,score\n2,0,0,0,0,1\n1,0,0,0,0,1\n", "sorted by frame"),
        ("frame,stamp,x,y,z,score\n1,0,0,0,oops,1\n", "dets.csv"),
    ],
)
def test_malformed_files_are_refused(tmp_path: Path, content: str, message: str) -> None:
    dets = tmp_path / "dets.csv"
    dets.write_text(content)
    with pytest.raises(FormatError, match=message):
        read_detections(dets)


def test_bad_config_value_is_named(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    dets, cfg = tmp_path / "dets.csv", tmp_path / "bad.yaml"
    write_detections(dets)
    cfg.write_text("n_init: 0\n")
    assert main(["track", "--detections", str(dets), "--output", str(tmp_path / "o.csv"), "--service-config", str(cfg)]) == 2
    assert "n_init" in capsys.readouterr().err


def test_old_config_flag_points_to_service_config(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """``--config`` is the Zenoh config everywhere; the old spelling here says what to use."""
    dets, cfg = tmp_path / "dets.csv", tmp_path / "t.yaml"
    write_detections(dets)
    cfg.write_text("n_init: 3\n")
    assert main(["track", "--detections", str(dets), "--output", str(tmp_path / "o.csv"), "--config", str(cfg)]) == 2
    assert "--service-config" in capsys.readouterr().err


def test_tracker_node_has_profile_flag() -> None:
    import argparse

    from services.tracker import flags

    parser = argparse.ArgumentParser()
    flags.add_arguments(parser)
    assert flags.overrides(parser.parse_args(["--profile", "thesis"]))["profile"] == "thesis"
    assert flags.overrides(parser.parse_args([]))["profile"] is None


def test_empty_file_gives_header_only(tmp_path: Path) -> None:
    dets, out = tmp_path / "dets.csv", tmp_path / "o.csv"
    dets.write_text("frame,stamp,x,y,z,score\n")
    assert main(["track", "--detections", str(dets), "--output", str(out)]) == 0
    assert out.read_text() == "frame,stamp,id,x,y,z\n"


def test_a_floor_view_hides_a_coasting_person_outside_the_image(tmp_path: Path,
                                                                capsys: pytest.CaptureFixture[str]) -> None:
    dets, out, hom = tmp_path / "dets.csv", tmp_path / "tracks.csv", tmp_path / "floor.json"
    write_detections(dets)
    # the camera sees x in [-5, 5] m and y in [-1, 1] m: the lane at y = 0, not the one at y = 2
    hom.write_text('{"H": [[0.01, 0, -5], [0, 0.01, -1], [0, 0, 1]], "image_size": [1000, 200]}')
    assert main(["track", "--detections", str(dets), "--output", str(out), "--status", "--floor-view", str(hom)]) == 0
    rows = [line.split(",") for line in out.read_text().splitlines()[1:]]
    lanes = {int(r[2]): round(float(r[4]) / 2.0) for r in rows}
    coasting = {lanes[int(r[2])] for r in rows if int(r[0]) in (130, 131)}
    assert coasting == {0}  # frames 130 and 131 have no detections: only the person in view is reported
    hom.write_text('{"H": [[0.01, 0, -5], [0, 0.01, -1], [0, 0, 1]]}')
    assert main(["track", "--detections", str(dets), "--output", str(out), "--floor-view", str(hom)]) == 2
    assert "image_size" in capsys.readouterr().err
    hom.write_text('{"H": [[0, 0, 0], [0, 0, 0], [0, 0, 0]], "image_size": [1000, 200]}')
    assert main(["track", "--detections", str(dets), "--output", str(out), "--floor-view", str(hom)]) == 2
    assert "invertible" in capsys.readouterr().err
