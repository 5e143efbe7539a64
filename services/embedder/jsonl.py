"""Reading the detection JSON lines of ``perception detect`` and cropping their boxes.

One line per image: ``{"image": path, "detections": [{"bbox_xyxy": [x0, y0, x1, y1],
"score": s, ...}, ...], ...}``. A relative image path is looked up from the current
directory first, then from the JSON file's directory.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any, Iterator

import cv2
import numpy as np

from common.runtime.cli_util import CliError
from common.runtime.detections_file import read_detection_lines
from services.embedder.core.backend import crop_boxes

__all__ = ["crops_of_line", "read_lines"]


def read_lines(path: str | Path) -> Iterator[tuple[int, dict[str, Any]]]:
    """(line number, object) of every non-empty line, each with an ``"image"``; CliError otherwise."""
    return read_detection_lines(path, require_image=True)


def _image(line: dict[str, Any], where: str, base: Path) -> np.ndarray:
    path = Path(line["image"])
    if not path.is_absolute() and not path.is_file():
        path = base / path
    img = cv2.imread(str(path), cv2.IMREAD_COLOR)
    if img is None:
        raise CliError(f"{where}: cannot read image {line['image']!r} (looked in . and {base})")
    return cv2.cvtColor(img, cv2.COLOR_BGR2RGB)


def crops_of_line(line: dict[str, Any], where: str, base: Path) -> tuple[list[np.ndarray], np.ndarray]:
    """Crops of a line's boxes (clamped, empty ones skipped) and the (K,) detection positions."""
    boxes = []
    for i, det in enumerate(line.get("detections", [])):
        box = det.get("bbox_xyxy") if isinstance(det, dict) else None
        if not isinstance(box, list) or len(box) != 4 or not all(isinstance(v, (int, float)) for v in box):
            raise CliError(f"{where}: detection {i} needs bbox_xyxy: [x0, y0, x1, y1], four numbers (got {box!r})")
        boxes.append(box)
    if not boxes:
        return [], np.zeros(0, np.int64)
    return crop_boxes(_image(line, where, base), np.asarray(boxes, np.float64))
