"""yolo-onnx backend: decoding of both layouts, letterbox inverse, class filter, NMS, providers, bad models."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

pytest.importorskip("onnx")

from services.detector.core.boxes import DetectorError  # noqa: E402
from services.detector.core.yolo_onnx import (  # noqa: E402
    Letterbox,
    YoloOnnxDetector,
    YoloParams,
    choose_providers,
    decode_yolo,
    letterbox,
)
from tests.fixtures.detector_models import constant_yolo_onnx  # noqa: E402

# Candidates in 640x640 network pixels: (cx, cy, w, h, objectness, class scores for person/car/dog).
CANDIDATES = np.array([
    [200, 300, 40, 100, 0.95, 0.90, 0.05, 0.05],  # person A
    [204, 302, 40, 100, 0.95, 0.80, 0.05, 0.05],  # duplicate of A, lower score: NMS removes it
    [400, 320, 50, 120, 0.90, 0.70, 0.10, 0.10],  # person B
    [300, 200, 80, 60, 0.95, 0.10, 0.90, 0.05],  # a car: class filter removes it
    [500, 400, 30, 90, 0.95, 0.20, 0.05, 0.05],  # person below the confidence threshold
    [100, 250, 30, 80, 0.10, 0.90, 0.05, 0.05],  # v5 only: low objectness
], dtype=np.float32)
# Real exports have thousands of candidates; pad with empty rows so the candidate axis is the longer one.
CANDIDATES = np.vstack([CANDIDATES, np.zeros((34, 8), np.float32)])

# A 320x240 image letterboxed into 640x640: scale 2, 80 px bands top and bottom.
IMAGE = np.zeros((240, 320, 3), np.uint8)


def expected_original(rows: np.ndarray) -> np.ndarray:
    cx, cy, w, h = rows[:, 0], rows[:, 1], rows[:, 2], rows[:, 3]
    boxes = np.column_stack([cx - w / 2, cy - h / 2, cx + w / 2, cy + h / 2])
    boxes[:, [0, 2]] /= 2.0
    boxes[:, [1, 3]] = (boxes[:, [1, 3]] - 80.0) / 2.0
    return boxes


def v8_output() -> np.ndarray:
    rows = np.delete(CANDIDATES, 4, axis=1)  # no objectness
    rows[5, 4] = 0.10  # the v5 "low objectness" row: a low person score here
    return rows.T[None]  # (1, 4+C, N)


def v5_output() -> np.ndarray:
    return CANDIDATES[None]  # (1, N, 5+C)


@pytest.mark.parametrize("layout", ["auto", "v8"])
def test_v8_layout_decoding(tmp_path: Path, layout: str) -> None:
    model = constant_yolo_onnx(tmp_path / "v8.onnx", v8_output())
    det = YoloOnnxDetector(YoloParams(model=model, layout=layout, conf_threshold=0.35))  # type: ignore[arg-type]
    boxes, scores = det.detect(IMAGE)
    np.testing.assert_allclose(scores, [0.90, 0.70], atol=1e-6)
    np.testing.assert_allclose(boxes, expected_original(CANDIDATES[[0, 2]]), atol=1e-3)
    assert boxes.dtype == np.float32 and scores.dtype == np.float32


@pytest.mark.parametrize("layout", ["auto", "v5"])
def test_v5_layout_decoding(tmp_path: Path, layout: str) -> None:
    model = constant_yolo_onnx(tmp_path / "v5.onnx", v5_output())
    det = YoloOnnxDetector(YoloParams(model=model, layout=layout, conf_threshold=0.35))  # type: ignore[arg-type]
    boxes, scores = det.detect(IMAGE)
    np.testing.assert_allclose(scores, [0.95 * 0.90, 0.90 * 0.70], atol=1e-6)
    np.testing.assert_allclose(boxes, expected_original(CANDIDATES[[0, 2]]), atol=1e-3)


def test_nms_threshold_controls_duplicates(tmp_path: Path) -> None:
    model = constant_yolo_onnx(tmp_path / "v8.onnx", v8_output())
    loose = YoloOnnxDetector(YoloParams(model=model, conf_threshold=0.35, nms_iou=0.95))
    boxes, scores = loose.detect(IMAGE)
    np.testing.assert_allclose(scores, [0.90, 0.80, 0.70], atol=1e-6)  # the duplicate survives a 0.95 IoU gate
    assert len(boxes) == 3


def test_person_class_selects_column(tmp_path: Path) -> None:
    model = constant_yolo_onnx(tmp_path / "v8.onnx", v8_output())
    det = YoloOnnxDetector(YoloParams(model=model, person_class=1, conf_threshold=0.35))
    boxes, scores = det.detect(IMAGE)
    np.testing.assert_allclose(scores, [0.90], atol=1e-6)
    np.testing.assert_allclose(boxes, expected_original(CANDIDATES[[3]]), atol=1e-3)


def test_num_classes_disambiguates_row_major_v8() -> None:
    rows = v8_output()[0].T  # (N, 4+C) rows, not transposed
    _, scores, layout = decode_yolo(rows[None], "auto", 0, 0.35, num_classes=3)
    assert layout == "v8"
    np.testing.assert_allclose(np.sort(scores)[::-1], [0.90, 0.80, 0.70], atol=1e-6)
    _, _, guessed = decode_yolo(rows[None], "auto", 0, 0.35)
    assert guessed == "v5"  # without the class count a row-major output reads as v5


def test_dynamic_input_uses_configured_size(tmp_path: Path) -> None:
    out = v8_output().copy()
    out[0, :4] *= 0.5  # the same candidates in a 320x320 network input
    model = constant_yolo_onnx(tmp_path / "dyn.onnx", out, input_hw=("height", "width"))
    det = YoloOnnxDetector(YoloParams(model=model, input_size=320, conf_threshold=0.35))
    assert det.input_hw == (320, 320)
    boxes, scores = det.detect(IMAGE)
    np.testing.assert_allclose(boxes, expected_original(CANDIDATES[[0, 2]]), atol=1e-3)


def test_letterbox_geometry_and_inverse() -> None:
    image = np.full((240, 320, 3), 7, np.uint8)
    padded, lb = letterbox(image, (640, 640))
    assert padded.shape == (640, 640, 3)
    assert (lb.scale, lb.pad_x, lb.pad_y) == (2.0, 0.0, 80.0)
    assert (padded[:80] == 114).all() and (padded[80:560] == 7).all() and (padded[560:] == 114).all()
    rng = np.random.default_rng(1)
    original = np.sort(rng.uniform(0, 240, size=(20, 2, 2)), axis=1).reshape(20, 4)[:, [0, 2, 1, 3]]
    net = original * lb.scale + [lb.pad_x, lb.pad_y, lb.pad_x, lb.pad_y]
    np.testing.assert_allclose(lb.to_original(net), original, atol=1e-9)
    tall = np.zeros((400, 100, 3), np.uint8)
    _, lb2 = letterbox(tall, (640, 640))
    assert lb2 == Letterbox(1.6, 240.0, 0.0)


def test_provider_choice() -> None:
    available = ["CUDAExecutionProvider", "CPUExecutionProvider"]
    assert choose_providers(None, available) == ["CUDAExecutionProvider", "CPUExecutionProvider"]
    trt = ["TensorrtExecutionProvider", "CUDAExecutionProvider", "CPUExecutionProvider"]
    assert choose_providers(None, trt) == trt
    assert choose_providers(None, ["AzureExecutionProvider", "CPUExecutionProvider"]) == ["CPUExecutionProvider"]
    assert choose_providers(["CPUExecutionProvider"], available) == ["CPUExecutionProvider"]
    with pytest.raises(DetectorError, match="TensorrtExecutionProvider"):
        choose_providers(["TensorrtExecutionProvider"], available)


def test_unavailable_provider_fails_at_construction(tmp_path: Path) -> None:
    model = constant_yolo_onnx(tmp_path / "v8.onnx", v8_output())
    with pytest.raises(DetectorError, match="not available"):
        YoloOnnxDetector(YoloParams(model=model, providers=("NoSuchExecutionProvider",)))


def test_missing_model(tmp_path: Path) -> None:
    with pytest.raises(DetectorError, match="does not exist"):
        YoloOnnxDetector(YoloParams(model=tmp_path / "absent.onnx"))


def test_truncated_model(tmp_path: Path) -> None:
    full = constant_yolo_onnx(tmp_path / "full.onnx", v8_output()).read_bytes()
    cut = tmp_path / "cut.onnx"
    cut.write_bytes(full[: len(full) // 2])
    with pytest.raises(DetectorError, match="truncated"):
        YoloOnnxDetector(YoloParams(model=cut))
    empty = tmp_path / "empty.onnx"
    empty.write_bytes(b"")
    with pytest.raises(DetectorError, match="empty"):
        YoloOnnxDetector(YoloParams(model=empty))


def test_bad_output_shape_is_reported() -> None:
    with pytest.raises(DetectorError, match="classes"):
        decode_yolo(np.zeros((1, 4, 100), np.float32), "v8", 0, 0.5)
    with pytest.raises(DetectorError, match="batch"):
        decode_yolo(np.zeros((2, 84, 100), np.float32), "auto", 0, 0.5)
