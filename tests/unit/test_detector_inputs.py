"""Bad inputs to the detectors and the command-line tools: clear errors, never a crash or a silent result."""

from __future__ import annotations

import json
from pathlib import Path

import cv2
import numpy as np
import pytest

from perception.cli import main as cli_main
from services.detector.core.boxes import DetectorError, as_rgb
from services.detector.core.hog import HogDetector
from tests.fixtures.detector_models import constant_yolo_onnx, tiny_darknet


@pytest.mark.parametrize("image", [np.zeros((0, 0, 3), np.uint8), np.zeros((10, 0, 3), np.uint8), np.zeros(5, np.uint8)])
def test_empty_or_shapeless_image(image: np.ndarray) -> None:
    with pytest.raises(DetectorError, match="non-empty"):
        HogDetector().detect(image)


def test_wrong_dtype_or_channels() -> None:
    with pytest.raises(DetectorError, match="uint8"):
        as_rgb(np.zeros((48, 64), np.uint16))  # a depth image handed in as colour
    with pytest.raises(DetectorError, match="channels"):
        as_rgb(np.zeros((48, 64, 2), np.uint8))
    assert as_rgb(np.zeros((48, 64), np.uint8)).shape == (48, 64, 3)  # grey is fine
    assert as_rgb(np.zeros((48, 64, 4), np.uint8)).shape == (48, 64, 3)  # so is RGBA


def write_image(path: Path, rgb: np.ndarray) -> Path:
    assert cv2.imwrite(str(path), cv2.cvtColor(rgb, cv2.COLOR_RGB2BGR))
    return path


def test_detect_cli_writes_one_json_line_per_image(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    images = [write_image(tmp_path / f"{i}.png", np.full((60 + i, 80, 3), 100, np.uint8)) for i in range(2)]
    out = tmp_path / "dets.jsonl"
    assert cli_main(["detect", *map(str, images), "--output", str(out)]) == 0
    lines = [json.loads(line) for line in out.read_text().splitlines()]
    assert lines == [
        {"image": str(images[0]), "width": 80, "height": 60, "detections": []},
        {"image": str(images[1]), "width": 80, "height": 61, "detections": []},
    ]


def test_detect_cli_with_yolo_onnx(tmp_path: Path) -> None:
    pytest.importorskip("onnx")
    rows = np.zeros((5, 50), np.float32)  # v8 layout (4 + 1 class, 50 candidates)
    rows[:, 0] = [320, 320, 80, 100, 0.8]  # one person in the middle of a 640x640 input
    model = constant_yolo_onnx(tmp_path / "m.onnx", rows[None])
    image = write_image(tmp_path / "square.png", np.zeros((320, 320, 3), np.uint8))
    out = tmp_path / "dets.jsonl"
    assert cli_main(["detect", str(image), "--backend", "yolo-onnx", "--model", str(model), "--output", str(out)]) == 0
    (record,) = [json.loads(line) for line in out.read_text().splitlines()]
    assert record["width"] == 320 and record["height"] == 320
    (det,) = record["detections"]
    assert det["bbox_xyxy"] == [140.0, 135.0, 180.0, 185.0] and det["score"] == pytest.approx(0.8)


def test_detect_cli_on_pets09(shared_data: Path, capsys: pytest.CaptureFixture[str]) -> None:
    frame = shared_data / "pets09" / "frame_0040.png"
    if not frame.is_file():
        pytest.skip(f"{frame} not found")
    assert cli_main(["detect", str(frame), "--upsample", "2.25"]) == 0
    record = json.loads(capsys.readouterr().out)
    assert record["width"] == 480 and record["height"] == 360 and len(record["detections"]) >= 3


@pytest.mark.parametrize("argv, message", [
    (["detect", "{tmp}/absent.png"], "absent.png: no such file"),
    (["detect", "{tmp}/junk.png"], "cannot be decoded"),
    (["detect", "{tmp}/ok.png", "--backend", "yolo-onnx"], "needs yolo.model"),
    (["detect", "{tmp}/ok.png", "--backend", "yolo-onnx", "--model", "{tmp}/absent.onnx"], "absent.onnx does not exist"),
    (["detect", "{tmp}/ok.png", "--backend", "yolo-onnx", "--model", "{tmp}/cut.onnx"], "truncated"),
    (["detect", "{tmp}/ok.png", "--backend", "darknet", "--darknet-cfg", "{tmp}/tiny.cfg",
      "--darknet-weights", "{tmp}/tiny.weights"], "truncated"),
    (["detect", "{tmp}/ok.png", "--backend", "depth"], "needs depth"),
    (["detect", "{tmp}/ok.png", "--upsample", "50"], "hog.upsample"),
    (["detector", "--backend", "depth", "--no-depth"], "depth_available"),
    (["detector", "--backend", "yolo-onnx", "--model", "{tmp}/absent.onnx"], "absent.onnx does not exist"),
])
def test_cli_errors_name_the_problem(tmp_path: Path, capsys: pytest.CaptureFixture[str], argv: list[str], message: str) -> None:
    pytest.importorskip("onnx")
    write_image(tmp_path / "ok.png", np.zeros((60, 80, 3), np.uint8))
    (tmp_path / "junk.png").write_bytes(b"this is not a png")
    full = constant_yolo_onnx(tmp_path / "full.onnx", np.zeros((1, 5, 50), np.float32)).read_bytes()
    (tmp_path / "cut.onnx").write_bytes(full[: len(full) // 2])
    tiny_darknet(tmp_path, class_logits=[1.0], truncate=True)
    code = cli_main([a.format(tmp=tmp_path) for a in argv])
    err = capsys.readouterr().err
    assert code == 2
    assert message in err and "Traceback" not in err


def test_service_config_file_section(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    config = tmp_path / "robot.yaml"
    config.write_text("detector:\n  backend: depth\n  depth_available: false\n")
    assert cli_main(["detector", "--service-config", str(config)]) == 2
    assert "depth_available" in capsys.readouterr().err
