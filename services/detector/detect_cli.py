"""``perception detect IMAGE...``: people boxes of image files as JSON lines.

One line per image, in the order given:
``{"image": path, "width": W, "height": H, "detections": [{"bbox_xyxy": [x1, y1, x2, y2], "score": s}]}``.
``perception embed`` and ``perception localize`` read this format.
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path
from typing import Any, TextIO

import cv2
import numpy as np

from common.runtime.cli_util import CliError, check_input_file
from common.runtime.progress import progress
from services.detector.core import Detector
from services.detector.core.boxes import DetectorError
from services.detector.flags import add_backend_arguments, detector_from_args, load_service_config

DESCRIPTION = """\
Detect people in image files (PNG, JPEG, ...) and write one JSON line per image:
  {"image": PATH, "width": W, "height": H,
   "detections": [{"bbox_xyxy": [x1, y1, x2, y2], "score": S}, ...]}
to --output (default: standard output). Backends as for 'perception detector',
except depth, which needs depth images."""


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("images", nargs="+", metavar="IMAGE", help="image files")
    parser.add_argument("--output", "-o", default=None, metavar="FILE", help="JSON-lines file to write (default stdout)")
    parser.add_argument("--service-config", type=Path, default=None, metavar="FILE",
                        help="YAML/JSON settings; its 'detector' section if it has one, else the whole file")
    add_backend_arguments(parser)


def read_rgb(path: Path) -> np.ndarray:
    """(H, W, 3) uint8 RGB pixels of an image file; CliError if it cannot be read."""
    expected = "expected an image file: PNG, JPEG or another format OpenCV reads"
    check_input_file(path, expected)
    if path.stat().st_size == 0:
        raise CliError(f"image {path} is empty ({expected})")
    level = cv2.utils.logging.getLogLevel()
    cv2.utils.logging.setLogLevel(cv2.utils.logging.LOG_LEVEL_SILENT)  # our message says it once
    try:
        bgr = cv2.imread(str(path), cv2.IMREAD_COLOR)
    finally:
        cv2.utils.logging.setLogLevel(level)
    if bgr is None:
        raise CliError(f"image {path} cannot be decoded ({expected})")
    return cv2.cvtColor(bgr, cv2.COLOR_BGR2RGB)


def detect_file(detector: Detector, path: Path) -> dict[str, Any]:
    """The JSON record of one image."""
    rgb = read_rgb(path)
    try:
        boxes, scores = detector.detect(rgb)
    except DetectorError as exc:
        raise CliError(f"{path}: {exc}") from exc
    return {
        "image": str(path),
        "width": int(rgb.shape[1]),
        "height": int(rgb.shape[0]),
        "detections": [{"bbox_xyxy": [round(float(v), 2) for v in b], "score": round(float(s), 4)}
                       for b, s in zip(boxes, scores)],
    }


def write_records(detector: Detector, images: list[Path], out: TextIO) -> int:
    """Detect in every image and write its line; the number of detections."""
    total = 0
    for path in progress(images, total=len(images), desc="detect", unit="image"):
        record = detect_file(detector, path)
        total += len(record["detections"])
        out.write(json.dumps(record) + "\n")
        out.flush()
    return total


def main(args: argparse.Namespace) -> int:
    config = load_service_config(args)
    if config.backend == "depth":
        raise CliError("the depth backend needs depth images and intrinsics; use --backend hog, yolo-onnx or darknet")
    detector = detector_from_args(config)
    images = [Path(p) for p in args.images]
    if args.output is None:
        write_records(detector, images, sys.stdout)
        return 0
    try:
        with open(args.output, "w") as out:
            write_records(detector, images, out)
    except OSError as exc:
        raise CliError(f"cannot write {args.output}: {exc}") from exc
    return 0
