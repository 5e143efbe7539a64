"""Reading the offline tool's inputs: depth images, camera info and transform files.

Every function raises :class:`common.runtime.cli_util.CliError` with a message naming the file
and what is wrong with it. JSON/YAML files are read by :mod:`common.runtime.config`.
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import cv2
import numpy as np
import yaml

from common.runtime.cli_util import CliError, check_input_file
from common.runtime.config import ConfigError, key_line, read_config_file
from common.geometry.transforms import PinholeCamera, RigidTransform
from services.localizer.core import FloorHomography

__all__ = ["boxes_of_line", "parse_transform", "read_camera_info", "read_depth", "read_floor_homography",
           "read_transforms"]

_MODELS = ("plumb_bob", "rational_polynomial", "equidistant", "none")


def boxes_of_line(item: dict[str, Any], where: str) -> tuple[np.ndarray, list[float]]:
    """The (N, 4) xyxy boxes and the scores of a detection line (``perception detect``'s JSON);
    CliError naming ``where`` when a detection has no four-number ``bbox_xyxy``."""
    try:
        boxes = np.array([d["bbox_xyxy"] for d in item.get("detections", [])], dtype=np.float64).reshape(-1, 4)
        scores = [float(d.get("score", 1.0)) for d in item.get("detections", [])]
    except (KeyError, TypeError, ValueError) as exc:
        raise CliError(f"{where}: every detection needs 'bbox_xyxy': [x1, y1, x2, y2] ({exc})") from exc
    return boxes, scores


def read_depth(path: Path) -> np.ndarray:
    """(H, W) depth: uint16 (units, 0 invalid) from a 16-bit PNG/TIFF or .npy, float32 metres from float .npy/TIFF/EXR."""
    if not path.is_file():
        raise CliError(f"depth image {path} does not exist")
    if path.suffix == ".npy":
        try:
            depth = np.load(path, allow_pickle=False)
        except (OSError, ValueError) as exc:
            raise CliError(f"depth image {path} cannot be read as .npy: {exc}") from exc
    else:
        level = cv2.utils.logging.getLogLevel()
        cv2.utils.logging.setLogLevel(cv2.utils.logging.LOG_LEVEL_SILENT)  # our message says it once
        try:
            depth = cv2.imread(str(path), cv2.IMREAD_UNCHANGED | cv2.IMREAD_ANYDEPTH)
        finally:
            cv2.utils.logging.setLogLevel(level)
        if depth is None:
            raise CliError(f"depth image {path} cannot be decoded (use a 16-bit PNG in millimetres or a .npy array)")
    if depth.ndim != 2:
        raise CliError(f"depth image {path} has shape {depth.shape}; a depth image has one channel")
    if depth.dtype == np.uint8:
        raise CliError(f"depth image {path} is 8-bit; depth must be 16-bit (millimetres) or float (metres)")
    if np.issubdtype(depth.dtype, np.floating):
        return depth.astype(np.float32, copy=False)
    return depth.astype(np.uint16, copy=False) if depth.dtype != np.uint16 else depth


def _read_mapping(path: Path, what: str) -> dict[str, Any]:
    """The mapping a JSON (``.json``) or YAML file holds; a CliError naming ``what`` if it
    is missing, cannot be parsed or is not a mapping."""
    try:
        return read_config_file(path)
    except ConfigError as exc:
        raise CliError(f"{what}: {exc}") from exc


def _matrix(value: Any, rows: int, cols: int, what: str) -> np.ndarray:
    if isinstance(value, dict) and "data" in value:  # camera_calibration YAML: {rows, cols, data}
        value = value["data"]
    arr = np.asarray(value, dtype=np.float64)
    if arr.size != rows * cols:
        raise CliError(f"{what} has {arr.size} numbers, expected {rows * cols}")
    return arr.reshape(rows, cols)


def read_camera_info(path: Path) -> tuple[PinholeCamera, str]:
    """The camera model and frame id of a CameraInfo-like JSON/YAML file.

    Accepted keys: ``width``/``height`` (or ``image_width``/``image_height``), ``K``
    (3x3 or 9 numbers; also ``k`` or ``camera_matrix``), ``D`` (also ``d`` or
    ``distortion_coefficients``), ``distortion_model`` (default plumb_bob) and
    ``frame_id`` (or ``header.frame_id``, default ``camera``).
    """
    data = _read_mapping(path, "--camera-info")

    def pick(*names: str, default: Any = None) -> tuple[str, Any]:
        for n in names:
            if n in data:
                return n, data[n]
        if default is None:
            raise CliError(f"camera info {path} has no {names[0]!r}")
        return names[0], default

    def field(names: tuple[str, ...], convert: Any, default: Any = None) -> Any:
        name, value = pick(*names, default=default)
        try:
            return convert(value)
        except (TypeError, ValueError) as exc:
            line = key_line(path, [name])
            where = f"{path}:{line}" if line is not None else str(path)
            raise CliError(f"camera info {where}: {name}: {exc}") from exc

    width = field(("width", "image_width"), int)
    height = field(("height", "image_height"), int)
    K = field(("K", "k", "camera_matrix"), lambda v: _matrix(v, 3, 3, f"K in {path}"))
    D = field(("D", "d", "distortion_coefficients"),
              lambda v: np.asarray(_flat(v), dtype=np.float64).reshape(-1), default=[])
    model = str(pick("distortion_model", default="plumb_bob")[1])
    header: dict[str, Any] = data["header"] if isinstance(data.get("header"), dict) else {}
    frame_id = str(data.get("frame_id") or header.get("frame_id") or "camera")
    if model not in _MODELS:
        raise CliError(f"camera info {path}: distortion_model {model!r} is not one of {', '.join(_MODELS)}")
    try:
        return PinholeCamera(K, width, height, D, model), frame_id  # type: ignore[arg-type]
    except (TypeError, ValueError) as exc:
        raise CliError(f"camera info {path}: {exc}") from exc


def _flat(value: Any) -> Any:
    return value["data"] if isinstance(value, dict) and "data" in value else value


def _rigid(translation: Any, rotation: Any, what: str) -> RigidTransform:
    try:
        t = np.asarray(translation, dtype=np.float64).reshape(3)
        q = np.asarray(rotation, dtype=np.float64).reshape(4)
        return RigidTransform.from_quat(t, q)
    except (TypeError, ValueError) as exc:
        raise CliError(
            f"{what}: translation needs 3 numbers and rotation_xyzw 4 (a non-zero quaternion): {exc}"
        ) from exc


def parse_transform(spec: str) -> tuple[str, str, RigidTransform]:
    """``parent:child:x,y,z:qx,qy,qz,qw`` (the rotation may be left out for identity)."""
    parts = spec.split(":")
    if len(parts) not in (3, 4) or not parts[0] or not parts[1]:
        raise CliError(f"--transform {spec!r} is not PARENT:CHILD:X,Y,Z[:QX,QY,QZ,QW]")
    try:
        t = [float(v) for v in parts[2].split(",")]
        q = [float(v) for v in parts[3].split(",")] if len(parts) == 4 else [0.0, 0.0, 0.0, 1.0]
    except ValueError as exc:
        raise CliError(f"--transform {spec!r}: {exc}") from exc
    return parts[0], parts[1], _rigid(t, q, f"--transform {spec!r}")


def read_transforms(path: Path) -> list[tuple[str, str, RigidTransform]]:
    """Transforms of a JSON/YAML file: a list of ``{parent_frame, child_frame, translation, rotation_xyzw}``
    or an object with such a list under ``transforms`` (a TransformBatch as JSON)."""
    # common.runtime.config.read_config_file reads mappings only, and the list is this file's
    # documented form: only the mapping form ({"transforms": [...]}) could go through it.
    check_input_file(path, "expected a JSON/YAML list of transforms")
    try:
        data = json.loads(path.read_text()) if path.suffix == ".json" else yaml.safe_load(path.read_text())
    except (OSError, UnicodeDecodeError, json.JSONDecodeError, yaml.YAMLError) as exc:
        raise CliError(f"transforms file {path} cannot be parsed: {exc}") from exc
    items = data.get("transforms") if isinstance(data, dict) else data
    if not isinstance(items, list):
        raise CliError(f'transforms file {path} must hold a list of transforms (or {{"transforms": [...]}})')
    out = []
    for i, item in enumerate(items):
        if not isinstance(item, dict) or not item.get("parent_frame") or not item.get("child_frame"):
            raise CliError(
                f"transforms file {path}, entry {i}: needs parent_frame, child_frame, translation, rotation_xyzw"
            )
        out.append(
            (
                str(item["parent_frame"]),
                str(item["child_frame"]),
                _rigid(item.get("translation"), item.get("rotation_xyzw", [0, 0, 0, 1]), f"{path}, entry {i}"),
            )
        )
    return out


def read_floor_homography(path: Path) -> FloorHomography:
    """The floor homography of a JSON/YAML file ``{"H": 3x3 (or 9 numbers), "image_size": [width, height]}``
    (``image_size`` optional; other fields, such as a description, are ignored)."""
    data = _read_mapping(path, "floor homography")
    if "H" not in data:
        raise CliError(f'floor homography {path} has no "H" (a 3x3 matrix: foot pixel (u, v, 1) -> floor (x, y, w))')
    try:
        H = _matrix(data["H"], 3, 3, f"H in {path}")
        size = data.get("image_size")
        if size is not None and (not isinstance(size, (list, tuple)) or len(size) != 2):
            raise ValueError(f"image_size must be [width, height], got {size!r}")
        return FloorHomography(H, None if size is None else (int(size[0]), int(size[1])))
    except (TypeError, ValueError) as exc:
        raise CliError(f"floor homography {path}: {exc}") from exc
