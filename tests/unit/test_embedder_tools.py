"""Calibration maths and the offline tools: perception embed, perception calibrate-embedder."""

from __future__ import annotations

import json
from pathlib import Path

import cv2
import numpy as np
import pytest

from perception.cli import main as perception
from services.embedder.core.calibration import calibrate, pair_distances, suggest_thresholds
from tests.fixtures.embedder_synthetic import random_outfit, render_person


def test_pair_distances_split_by_label() -> None:
    v = np.array([[0.0, 0.0], [3.0, 4.0], [0.0, 1.0]])
    same, diff = pair_distances(v, np.array([1, 2, 1]))
    np.testing.assert_allclose(same, [1.0])
    np.testing.assert_allclose(sorted(diff), [np.sqrt(18), 5.0])
    same_c, _ = pair_distances(np.array([[1.0, 0.0], [0.0, 2.0]]), np.array([0, 0]), "cosine")
    np.testing.assert_allclose(same_c, [1.0])


def test_suggested_thresholds_overlap_and_gap() -> None:
    rng = np.random.default_rng(0)
    same, diff = rng.normal(0.4, 0.15, 5000), rng.normal(0.8, 0.15, 5000)
    lo, hi, rec = suggest_thresholds(same, diff)
    assert lo == pytest.approx(np.percentile(diff, 1)) and hi == pytest.approx(np.percentile(same, 99))
    assert lo < rec < hi and rec == pytest.approx(np.percentile(diff, 5))
    lo, hi, rec = suggest_thresholds(np.array([0.1, 0.2]), np.array([0.9, 1.0]))
    assert 0.1 < lo < hi < 1.0 and rec == pytest.approx((lo + hi) / 2)
    with pytest.raises(ValueError):
        suggest_thresholds(np.array([]), np.array([1.0]))


def test_calibrate_reports_auc_and_rank1() -> None:
    v = np.array([[0.0], [0.1], [5.0], [5.1]])
    cal = calibrate(v, np.array(["a", "a", "b", "b"]))
    assert cal.auc == 1.0 and cal.rank1 == 1.0


@pytest.fixture
def labelled(tmp_path: Path) -> Path:
    """Two images, four synthetic people each appearing in both, one unlabelled and one empty box."""
    rng = np.random.default_rng(3)
    outfits = [random_outfit(rng) for _ in range(4)]
    lines = []
    for k in range(2):
        img = np.full((140, 300, 3), 128, np.uint8)
        dets = []
        for i, o in enumerate(outfits):
            x = 10 + 70 * i
            img[5:133, x:x + 64] = render_person(o, rng)
            dets.append({"bbox_xyxy": [x, 5, x + 64, 133], "score": 0.9, "person_id": i, "extra": "kept"})
        dets.append({"bbox_xyxy": [0, 0, 0, 50], "score": 0.5})
        cv2.imwrite(str(tmp_path / f"img{k}.png"), cv2.cvtColor(img, cv2.COLOR_RGB2BGR))
        lines.append({"image": f"img{k}.png", "detections": dets, "frame": k})
    path = tmp_path / "dets.jsonl"
    path.write_text("\n".join(json.dumps(line) for line in lines) + "\n")
    return path


def test_embed_adds_embeddings_and_model(labelled: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.chdir(tmp_path.parent)  # image paths resolve from the JSON file's folder
    out = tmp_path / "out.jsonl"
    assert perception(["embed", str(labelled), "--output", str(out)]) == 0
    lines = [json.loads(x) for x in out.read_text().splitlines()]
    assert len(lines) == 2 and lines[0]["frame"] == 0
    assert lines[0]["model"]["name"] == "colour" and lines[0]["model"]["dim"] == 224
    assert set(lines[0]["model"]["thresholds"]) == {"t_lower", "t_upper", "t_recover"}
    dets = lines[0]["detections"]
    assert dets[0]["extra"] == "kept" and len(dets[0]["embedding"]) == 224
    assert dets[4]["embedding"] is None  # the empty box
    e = np.array([[d["embedding"] for d in line["detections"][:4]] for line in lines])
    d = np.linalg.norm(e[0][:, None] - e[1][None], axis=2)
    assert np.all(d.argmin(axis=1) == np.arange(4))


def test_calibrate_embedder_prints_thresholds(labelled: Path, capsys: pytest.CaptureFixture[str]) -> None:
    assert perception(["calibrate-embedder", "--detections", str(labelled), "--json"]) == 0
    result = json.loads(capsys.readouterr().out)
    assert result["crops"] == 8 and result["people"] == 4
    assert result["pairs"] == {"same": 4, "different": 24}
    t = result["thresholds"]
    assert 0 < t["t_lower"] < t["t_upper"] and t["t_lower"] <= t["t_recover"] <= t["t_upper"]
    assert perception(["calibrate-embedder", "--detections", str(labelled)]) == 0
    assert "suggested:" in capsys.readouterr().out


def test_tools_fail_clearly(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    assert perception(["embed", str(tmp_path / "missing.jsonl")]) == 2
    assert "no such file" in capsys.readouterr().err
    bad = tmp_path / "bad.jsonl"
    bad.write_text('{"image": "nope.png", "detections": [{"bbox_xyxy": [0, 0, 5, 5], "score": 1}]}\n')
    assert perception(["embed", str(bad)]) == 2
    assert "cannot read image" in capsys.readouterr().err
    bad.write_text("{not json\n")
    assert perception(["embed", str(bad)]) == 2
    assert "bad.jsonl:1" in capsys.readouterr().err
    assert perception(["embed", str(bad), "--backend", "onnx"]) == 2
    assert "onnx.path" in capsys.readouterr().err
    assert perception(["embed", str(bad), "--backend", "onnx", "--model", str(tmp_path / "x.onnx")]) == 2
    assert "not found" in capsys.readouterr().err
    unlabelled = tmp_path / "u.jsonl"
    unlabelled.write_text('{"image": "x.png", "detections": []}\n')
    assert perception(["calibrate-embedder", "--detections", str(unlabelled)]) == 2
    assert "person_id" in capsys.readouterr().err
