"""The flags of ``perception camera`` and the settings they override."""

from __future__ import annotations

import argparse
from pathlib import Path
from typing import Any

from common.runtime.node import add_node_arguments
from services.camera.config import CameraConfig

__all__ = ["add_arguments", "overrides", "prepare"]


def add_arguments(parser: argparse.ArgumentParser) -> None:
    g = parser.add_argument_group("camera")
    g.add_argument("source", nargs="?", default=None,
                   help="opencv: a device index (0) or path (/dev/video0), a video file, a folder of images or an "
                        "rtsp:// or http:// URL; realsense: a recording (.bag, .db3), or nothing for the camera")
    g.add_argument("--backend", choices=("opencv", "realsense"), default=None, help="")
    g.add_argument("--serial", default=None, help="realsense: the camera's serial number")
    g.add_argument("--camera", default=None, help="this project's camera name: frames/CAMERA")
    g.add_argument("--frame-id", dest="frame_id", default=None, help="the optical frame's name")
    g.add_argument("--width", type=int, default=None, metavar="PX", help="the width asked of a device")
    g.add_argument("--height", type=int, default=None, metavar="PX", help="the height asked of a device")
    g.add_argument("--fps", type=float, default=None, metavar="HZ", help="the rate asked of a device, and a folder's")
    g.add_argument("--camera-info", dest="camera_info", type=Path, default=None, metavar="FILE.yaml",
                   help="the calibration: ROS camera_calibration YAML or OpenCV FileStorage YAML/XML")
    g.add_argument("--hfov", dest="hfov_deg", type=float, default=None, metavar="DEG",
                   help="without a calibration: the horizontal field of view (rough intrinsics, with a warning)")
    pace = g.add_mutually_exclusive_group()
    pace.add_argument("--rate", type=float, default=None, metavar="X", help="a file's speed relative to real time")
    pace.add_argument("--max", dest="pace", action="store_const", const="max", default=None,
                      help="a file: each frame once the detector has answered the previous one")
    g.add_argument("--no-passthrough", dest="passthrough", action="store_const", const=False, default=None,
                   help="decode JPEG files and MJPG videos here and send raw pixels")
    g.add_argument("--loop", action="store_const", const=True, default=None, help="a file starts again at its end")
    g.add_argument("--start-ns", dest="start_ns", type=int, default=None, metavar="NS",
                   help="a file's first stamp in ns since the epoch; frame k is start + (k - 1) / fps")
    add_node_arguments(parser, "camera", CameraConfig)


def overrides(args: argparse.Namespace) -> dict[str, Any]:
    names = ("source", "backend", "serial", "camera", "frame_id", "width", "height", "fps", "camera_info", "hfov_deg",
             "rate", "pace", "loop", "start_ns", "passthrough")
    return {n: getattr(args, n) for n in names}


def prepare(config: CameraConfig) -> dict[str, Any]:
    """Open the source before connecting: a device that does not open, a file that is not a
    video, a calibration file that cannot be read stop the node at start-up (exit status 2)."""
    from services.camera.calibration_file import load_calibration
    from services.camera.core.calibration import CalibrationError
    from services.camera.core.sources import SourceError
    from services.camera.service import open_source

    if config.camera_info is not None:
        try:
            load_calibration(config.camera_info)
        except CalibrationError as exc:
            raise ValueError(str(exc)) from exc
    try:
        return {"source": open_source(config)}
    except SourceError as exc:
        raise ValueError(str(exc)) from exc
