"""Reading a calibration file: ROS ``camera_calibration`` YAML, or OpenCV ``FileStorage`` YAML/XML."""

from __future__ import annotations

from pathlib import Path

import cv2
import yaml

from services.camera.core.calibration import CalibrationError, from_mapping, from_opencv_nodes
from services.camera.core.sources import Intrinsics

__all__ = ["load_calibration"]


def load_calibration(path: str | Path) -> Intrinsics:
    """The intrinsics in a calibration file; :class:`CalibrationError` names the file and the fix."""
    p = Path(path).expanduser()
    if not p.is_file():
        raise CalibrationError(f"{p}: no such calibration file")
    text = p.read_text(errors="replace")
    if text.lstrip().startswith(("%YAML:1", "<?xml")) or "!!opencv-matrix" in text:
        fs = cv2.FileStorage(str(p), cv2.FILE_STORAGE_READ)
        try:
            if not fs.isOpened():
                raise CalibrationError(f"{p}: OpenCV cannot read it as a FileStorage YAML or XML")
            return from_opencv_nodes(str(p), fs.getNode("camera_matrix").mat(), fs.getNode("distortion_coefficients").mat(),
                                     int(fs.getNode("image_width").real()), int(fs.getNode("image_height").real()))
        finally:
            fs.release()
    try:
        doc = yaml.safe_load(text)
    except yaml.YAMLError as exc:
        raise CalibrationError(f"{p}: not YAML ({exc})") from exc
    return from_mapping(str(p), doc)
