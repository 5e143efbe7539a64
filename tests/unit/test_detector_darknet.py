"""darknet backend: cfg parsing, weight counting, YOLOv3 output decoding (not accuracy)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from services.detector.core.boxes import DetectorError
from services.detector.core.darknet import DarknetDetector, DarknetParams, expected_weight_count, parse_cfg
from tests.fixtures.detector_models import TINY_CFG, tiny_darknet

IMAGE = np.full((48, 64, 3), 100, np.uint8)


def sigmoid(x: float) -> float:
    return 1.0 / (1.0 + np.exp(-x))


def test_grid_of_known_boxes(tmp_path: Path) -> None:
    cfg, weights = tiny_darknet(tmp_path, class_logits=[4.0, -4.0], anchor=4)
    det = DarknetDetector(DarknetParams(cfg=cfg, weights=weights, conf_threshold=0.5))
    assert det.input_wh == (32, 32)
    boxes, scores = det.detect(IMAGE)
    # 4x4 grid over a 64x48 image: cells of 16x12 px, boxes of 4/32 of the image (8x6 px) at the cell centres.
    assert len(boxes) == 16
    np.testing.assert_allclose(scores, sigmoid(4.0) ** 2, atol=1e-4)
    centres = np.column_stack([(boxes[:, 0] + boxes[:, 2]) / 2, (boxes[:, 1] + boxes[:, 3]) / 2])
    expected = {(16 * i + 8.0, 12 * j + 6.0) for i in range(4) for j in range(4)}
    assert {(round(float(x), 3), round(float(y), 3)) for x, y in centres} == expected
    np.testing.assert_allclose(boxes[:, 2] - boxes[:, 0], 8.0, atol=1e-3)
    np.testing.assert_allclose(boxes[:, 3] - boxes[:, 1], 6.0, atol=1e-3)


def test_overlapping_boxes_are_suppressed(tmp_path: Path) -> None:
    cfg, weights = tiny_darknet(tmp_path, class_logits=[4.0, -4.0], anchor=64)  # every box covers the image
    boxes, scores = DarknetDetector(DarknetParams(cfg=cfg, weights=weights, conf_threshold=0.5)).detect(IMAGE)
    assert len(boxes) == 1
    np.testing.assert_allclose(boxes[0], [0, 0, 64, 48], atol=1e-3)


def test_class_filter(tmp_path: Path) -> None:
    cfg, weights = tiny_darknet(tmp_path, class_logits=[-1.0, 4.0])
    boxes, _ = DarknetDetector(DarknetParams(cfg=cfg, weights=weights, conf_threshold=0.1)).detect(IMAGE)
    assert len(boxes) == 0  # every cell is a "class 1" object
    boxes, _ = DarknetDetector(DarknetParams(cfg=cfg, weights=weights, person_class=1, conf_threshold=0.5)).detect(IMAGE)
    assert len(boxes) == 16


def test_input_size_override(tmp_path: Path) -> None:
    cfg, weights = tiny_darknet(tmp_path, class_logits=[4.0])
    det = DarknetDetector(DarknetParams(cfg=cfg, weights=weights, input_size=64))
    assert det.input_wh == (64, 64)
    boxes, _ = det.detect(IMAGE)
    assert len(boxes) == 64  # 8x8 grid


def test_weight_count_of_yolov3_style_cfg() -> None:
    text = """
[net]
channels=3
[convolutional]
batch_normalize=1
filters=8
size=3
[convolutional]
batch_normalize=1
filters=4
size=1
[shortcut]
from=-2
[route]
layers=-1,-3
[convolutional]
filters=18
size=1
[yolo]
classes=1
"""
    # conv1: 8*4 + 8*3*9; conv2: 4*4 + 4*8; route: 8+4... shortcut keeps conv2's 4 channels -> route = 4 + 8 = 12.
    expected = (8 * 4 + 8 * 3 * 9) + (4 * 4 + 4 * 8 * 1) + (18 + 18 * 12)
    assert expected_weight_count(parse_cfg(text)) == expected
    assert expected_weight_count(parse_cfg("[net]\n[mystery]\n")) is None


def test_truncated_weights_are_refused(tmp_path: Path) -> None:
    cfg, weights = tiny_darknet(tmp_path, class_logits=[4.0], truncate=True)
    with pytest.raises(DetectorError, match="truncated"):
        DarknetDetector(DarknetParams(cfg=cfg, weights=weights))


def test_missing_files(tmp_path: Path) -> None:
    cfg, weights = tiny_darknet(tmp_path, class_logits=[4.0])
    with pytest.raises(DetectorError, match="darknet weights .* does not exist"):
        DarknetDetector(DarknetParams(cfg=cfg, weights=tmp_path / "absent.weights"))
    with pytest.raises(DetectorError, match="darknet cfg .* does not exist"):
        DarknetDetector(DarknetParams(cfg=tmp_path / "absent.cfg", weights=weights))


def test_malformed_cfg(tmp_path: Path) -> None:
    _, weights = tiny_darknet(tmp_path, class_logits=[4.0])
    bad = tmp_path / "bad.cfg"
    bad.write_text("[convolutional]\nfilters=4\n")
    with pytest.raises(DetectorError, match=r"\[net\]"):
        DarknetDetector(DarknetParams(cfg=bad, weights=weights))
    assert "[yolo]" in TINY_CFG
