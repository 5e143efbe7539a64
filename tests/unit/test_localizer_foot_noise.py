"""The floor paths' foot-point noise, measured (services/localizer/core/foot_noise.py) and
``perception calibrate-localizer``: boxes with a known noise give it back."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from perception.cli import main as perception
from services.localizer.config import LocalizerConfig
from services.localizer.core import REJECT_FOOT_OUTSIDE_IMAGE, FloorParams, foot_points
from services.localizer.core.foot_noise import fit_foot_noise, match_boxes

#: the noise put on the synthetic detections: a pixel, shares of the height, a bias down
SIGMA_PX, SHARE_U, SHARE_V, BIAS_V = 1.5, 0.04, 0.025, 0.03


def _truth(n: int, rng: np.random.Generator) -> np.ndarray:
    """(n, 4) xyxy ground-truth boxes of people 30 to 200 px high."""
    h = rng.uniform(30.0, 200.0, n)
    w = 0.4 * h
    x, y = rng.uniform(0.0, 600.0, n), rng.uniform(0.0, 300.0, n)
    return np.column_stack([x, y, x + w, y + h])


def _detect(gt: np.ndarray, rng: np.random.Generator) -> np.ndarray:
    """The truth with the foot point moved by the model's noise (and the box's top alike)."""
    h = gt[:, 3] - gt[:, 1]
    du = rng.normal(0.0, np.sqrt(SIGMA_PX ** 2 + (SHARE_U * h) ** 2))
    dv = BIAS_V * h + rng.normal(0.0, np.sqrt(SIGMA_PX ** 2 + (SHARE_V * h) ** 2))
    out = gt.copy()
    out[:, [0, 2]] += du[:, None]
    out[:, 3] += dv
    out[:, 1] += rng.normal(0.0, 0.05, len(gt)) * h
    return out


def test_the_fit_gives_back_the_noise_it_was_made_with() -> None:
    rng = np.random.default_rng(3)
    gt = _truth(4000, rng)
    noise = fit_foot_noise(_detect(gt, rng), gt)
    assert noise.share_u == pytest.approx(SHARE_U, rel=0.1)
    assert noise.share_v == pytest.approx(SHARE_V, rel=0.1)
    assert noise.bias_v == pytest.approx(BIAS_V, abs=0.003) and abs(noise.bias_u) < 0.003
    assert 0.5 <= noise.sigma_u_px <= 3.0 and 0.5 <= noise.sigma_v_px <= 3.0
    assert noise.matched == 4000 - noise.dropped and noise.dropped < 40
    for b in noise.bins:  # the fit follows the measured spread at every height
        assert b.fit_u_px == pytest.approx(b.rms_u_px, rel=0.15) and b.fit_v_px == pytest.approx(b.rms_v_px, rel=0.15)


def test_mismatched_pairs_do_not_inflate_the_noise() -> None:
    rng = np.random.default_rng(4)
    gt = _truth(2000, rng)
    det = _detect(gt, rng)
    wrong = rng.choice(len(gt), 40, replace=False)  # 2 %: another person's box, far off
    det[wrong, :] += np.array([25.0, 0.0, 25.0, 30.0])
    noise = fit_foot_noise(det, gt)
    assert noise.dropped >= 40
    assert noise.share_u == pytest.approx(SHARE_U, rel=0.15) and noise.share_v == pytest.approx(SHARE_V, rel=0.15)


def test_too_few_pairs_is_an_error() -> None:
    gt = _truth(9, np.random.default_rng(5))
    with pytest.raises(ValueError, match="at least 10"):
        fit_foot_noise(gt, gt)
    with pytest.raises(ValueError, match="as many"):
        fit_foot_noise(gt, gt[:5])


def test_boxes_pair_one_to_one_within_their_frame() -> None:
    gt = np.array([[0, 0, 10, 30], [20, 0, 30, 30], [0, 0, 10, 30]], float)
    gt_frames = np.array([1, 1, 2])
    det = np.array([[21, 1, 31, 31], [1, 0, 11, 30], [0.5, 0, 10.5, 30], [100, 0, 110, 30], [0, 0, 10, 30]], float)
    det_frames = np.array([1, 1, 1, 1, 3])  # a second box on person 0, one on nobody, one in a frame without truth
    d, g = match_boxes(det_frames, det, gt_frames, gt)
    assert sorted(zip(d.tolist(), g.tolist())) == [(0, 1), (2, 0)]
    d, g = match_boxes(det_frames, det, gt_frames, gt, min_iou=0.99)
    assert len(d) == 0
    with pytest.raises(ValueError, match="min_iou"):
        match_boxes(det_frames, det, gt_frames, gt, min_iou=0.0)


def _files(tmp_path: Path, scale: float = 1.0) -> tuple[Path, Path, Path]:
    """Detections as JSON lines and as a det.txt, and a gt.txt (its boxes divided by ``scale``,
    with a don't-care row per frame that no detection matches)."""
    rng = np.random.default_rng(6)
    frames = np.repeat(np.arange(1, 201), 4)
    gt = _truth(len(frames), rng)
    det = _detect(gt, rng)
    lines, det_rows, gt_rows = [], [], []
    for f in np.unique(frames).tolist():
        m = frames == f
        lines.append(json.dumps({"image": f"frames/frame_{f:04d}.jpg", "width": 800, "height": 600,
                                 "detections": [{"bbox_xyxy": b.tolist(), "score": 0.9} for b in det[m]]}))
        det_rows += [f"{f},-1,{b[0]},{b[1]},{b[2] - b[0]},{b[3] - b[1]},0.9" for b in det[m]]
        gt_rows += [f"{f},{i},{b[0] / scale},{b[1] / scale},{(b[2] - b[0]) / scale},{(b[3] - b[1]) / scale},1,-1,-1,-1"
                    for i, b in enumerate(gt[m])]
        gt_rows.append(f"{f},99,{700 / scale},{500 / scale},{20 / scale},{50 / scale},0,-1,-1,-1")
    (jsonl := tmp_path / "dets.jsonl").write_text("\n".join(lines) + "\n")
    (txt := tmp_path / "det.txt").write_text("\n".join(det_rows) + "\n")
    (gtp := tmp_path / "gt.txt").write_text("\n".join(gt_rows) + "\n")
    return jsonl, txt, gtp


def test_calibrate_localizer_prints_the_settings(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    jsonl, txt, gt = _files(tmp_path, scale=0.5)
    for dets in (jsonl, txt):
        assert perception(["calibrate-localizer", "--detections", str(dets), "--ground-truth", str(gt),
                           "--gt-scale", "0.5", "--json"]) == 0
        result = json.loads(capsys.readouterr().out)
        assert 780 <= result["pairs"] <= 800 and result["ground_truth"] == 800  # the don't-care rows left out
        s = result["settings"]
        assert s["foot_sigma_share_u"] == pytest.approx(SHARE_U, rel=0.2)
        assert s["foot_sigma_share_v"] == pytest.approx(SHARE_V, rel=0.2)
        assert result["bias_share"]["v"] == pytest.approx(BIAS_V, abs=0.005)
        assert result["foot_bias"]["hog"]["v"] == pytest.approx(BIAS_V, abs=0.005)  # --detector's default
    assert perception(["calibrate-localizer", "--detections", str(jsonl), "--ground-truth", str(gt),
                       "--gt-scale", "0.5", "--detector", "yolo-onnx"]) == 0
    out = capsys.readouterr().out
    assert "localizer:\n  foot_sigma_u_px:" in out and "foot_sigma_share_v:" in out
    assert "  foot_bias:\n    yolo-onnx: {u: " in out and "foot bias of 'yolo-onnx': none" in out


def test_the_floor_paths_take_a_detectors_bias_off_the_foot_point() -> None:
    boxes = np.array([[10.0, 20.0, 30.0, 120.0], [0.0, 0.0, 10.0, 479.5]])
    plain, reasons = foot_points(boxes, 640, 480)
    moved, same = foot_points(boxes, 640, 480, bias=(0.01, 0.037))
    assert np.allclose(moved, plain - np.array([[1.0, 3.7], [4.795, 17.7415]]))
    assert same == reasons and reasons[1] == REJECT_FOOT_OUTSIDE_IMAGE  # cut off at the image's edge all the same
    with pytest.raises(ValueError, match="foot_bias"):
        FloorParams(foot_bias_v=0.5)
    config = LocalizerConfig()
    assert config.floor_params("hog").foot_bias_v == pytest.approx(0.037)
    assert config.floor_params("yolo-onnx").foot_bias_v == 0.0 and config.floor_params().foot_bias_u == 0.0
    with pytest.raises(ValueError):
        LocalizerConfig(foot_bias={"hog": {"v": 0.6}})


def test_calibrate_localizer_names_what_is_wrong(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    jsonl, _, gt = _files(tmp_path, scale=0.5)
    # the ground truth in other pixels: too few pairs, and the message points at --gt-scale
    assert perception(["calibrate-localizer", "--detections", str(jsonl), "--ground-truth", str(gt)]) == 2
    assert "--gt-scale" in capsys.readouterr().err
    other = tmp_path / "other.txt"
    other.write_text("5000,1,0,0,10,30,1\n")
    assert perception(["calibrate-localizer", "--detections", str(jsonl), "--ground-truth", str(other)]) == 2
    assert "frame numbers must agree" in capsys.readouterr().err
    unnumbered = tmp_path / "u.jsonl"
    unnumbered.write_text(json.dumps({"image": "frames/left.jpg", "detections": []}) + "\n")
    assert perception(["calibrate-localizer", "--detections", str(unnumbered), "--ground-truth", str(gt)]) == 2
    assert "no frame number" in capsys.readouterr().err
    for flag, value in (("--gt-scale", "0"), ("--min-iou", "1.5")):
        assert perception(["calibrate-localizer", "--detections", str(jsonl), "--ground-truth", str(gt),
                           flag, value]) == 2
        assert flag in capsys.readouterr().err
