"""A camera's intrinsics: from a calibration (read by ``services.camera.calibration_file``), or,
roughly, from a horizontal field of view.

Calibrations: the YAML of ROS's ``camera_calibration`` (``image_width``, ``camera_matrix``
``{rows, cols, data}``, ``distortion_model``, ``distortion_coefficients``: the usual output of a
calibration, and what ``camera_info_manager`` reads) and OpenCV's ``FileStorage`` YAML or XML
(``cv2.calibrateCamera``'s matrices saved as ``camera_matrix`` and ``distortion_coefficients``,
with ``image_width`` and ``image_height``). A calibration of another size with the same aspect
ratio is scaled to the image.
"""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any

import numpy as np

from services.camera.core.sources import Intrinsics

__all__ = ["CalibrationError", "checked", "from_fov", "from_mapping", "from_opencv_nodes", "scaled"]

_MODELS = {"plumb_bob": (4, 5, 8, 12, 14), "rational_polynomial": (8, 12, 14), "equidistant": (4,)}


class CalibrationError(ValueError):
    """The calibration file cannot be used; the message names the file, the field and the fix."""


def _matrix(path: Path, node: Any, name: str) -> np.ndarray:
    if isinstance(node, dict) and "data" in node:
        data = node["data"]
    else:
        data = node
    try:
        arr = np.asarray(data, dtype=np.float64).ravel()
    except (TypeError, ValueError) as exc:
        raise CalibrationError(f"{path}: {name} is not a list of numbers") from exc
    if not np.all(np.isfinite(arr)):
        raise CalibrationError(f"{path}: {name} holds a value that is not finite")
    return arr


def from_mapping(where: str, doc: Any) -> Intrinsics:
    """The intrinsics in a ROS ``camera_calibration`` document (already parsed); ``where`` names it."""
    path = Path(where)
    if not isinstance(doc, dict) or "camera_matrix" not in doc:
        raise CalibrationError(f"{where}: no camera_matrix; give the YAML that ROS's camera_calibration (or "
                               "OpenCV's FileStorage) writes")
    K = _matrix(path, doc["camera_matrix"], "camera_matrix")
    if K.size != 9:
        raise CalibrationError(f"{where}: camera_matrix has {K.size} values, not 9")
    D = _matrix(path, doc.get("distortion_coefficients", {"data": []}), "distortion_coefficients")
    model = str(doc.get("distortion_model", "plumb_bob"))
    try:
        width, height = int(doc["image_width"]), int(doc["image_height"])
    except (KeyError, TypeError, ValueError) as exc:
        raise CalibrationError(f"{where}: image_width and image_height are needed (the calibrated size)") from exc
    return checked(path, width, height, K.reshape(3, 3), D, model)


def from_opencv_nodes(where: str, K: Any, D: Any, width: int, height: int) -> Intrinsics:
    """The intrinsics of OpenCV's calibration matrices (``cv2.FileStorage`` nodes read)."""
    if K is None:
        raise CalibrationError(f"{where}: no camera_matrix node")
    if width <= 0 or height <= 0:
        raise CalibrationError(f"{where}: image_width and image_height are needed (the calibrated size)")
    D = np.zeros(0) if D is None else np.asarray(D, dtype=np.float64).ravel()
    return checked(Path(where), width, height, np.asarray(K, dtype=np.float64), D, "plumb_bob")


def checked(path: Path, width: int, height: int, K: np.ndarray, D: np.ndarray, model: str) -> Intrinsics:
    if width <= 0 or height <= 0:
        raise CalibrationError(f"{path}: image size {width}x{height}")
    if not (K[0, 0] > 0 and K[1, 1] > 0) or abs(K[2, 2] - 1.0) > 1e-9:
        raise CalibrationError(f"{path}: camera_matrix has no positive focal lengths or a last row other than 0 0 1")
    if model not in _MODELS and model != "none":
        raise CalibrationError(f"{path}: distortion model {model!r} is not plumb_bob, rational_polynomial or "
                               "equidistant")
    if model == "none" or not np.any(D):
        return Intrinsics(width, height, K, np.zeros(0), "none")
    if D.size not in _MODELS[model]:
        raise CalibrationError(f"{path}: {model} with {D.size} coefficients")
    if model == "plumb_bob" and D.size != 5:
        # OpenCV's 8/12/14-coefficient model is the rational one; 4 coefficients lack k3
        model = "rational_polynomial" if D.size > 5 else model
        D = np.concatenate([D, np.zeros(5 - D.size)]) if D.size < 5 else D[:8]
    if model == "rational_polynomial":
        D = D[:8]
    return Intrinsics(width, height, K, D, model)


def scaled(intr: Intrinsics, width: int, height: int) -> Intrinsics:
    """``intr`` for an image of ``width`` x ``height`` (the same camera at another resolution)."""
    if (width, height) == (intr.width, intr.height):
        return intr
    sx, sy = width / intr.width, height / intr.height
    if abs(sx - sy) > 0.01:
        raise CalibrationError(f"the calibration is for {intr.width}x{intr.height}, the images are {width}x{height}: "
                               "another aspect ratio, so another crop; calibrate at this resolution")
    K = intr.K.copy()
    K[0] *= sx
    K[1] *= sy
    return Intrinsics(width, height, K, intr.D, intr.distortion_model, intr.rough)


def from_fov(width: int, height: int, hfov_deg: float) -> Intrinsics:
    """A rough pinhole model from the horizontal field of view: square pixels, the principal
    point at the centre, no distortion. Positions from it are rough: calibrate the camera."""
    if not 1.0 < hfov_deg < 179.0:
        raise CalibrationError(f"horizontal field of view {hfov_deg} degrees: give one between 1 and 179")
    f = (width / 2.0) / math.tan(math.radians(hfov_deg) / 2.0)
    K = np.array([[f, 0.0, width / 2.0], [0.0, f, height / 2.0], [0.0, 0.0, 1.0]])
    return Intrinsics(width, height, K, np.zeros(0), "none", rough=True)
