"""The flags of ``perception localizer`` and the settings they override."""

from __future__ import annotations

import argparse
from pathlib import Path
from typing import Any

from common.runtime.node import add_node_arguments
from services.localizer.config import LocalizerConfig
from services.localizer.files import read_floor_homography

__all__ = ["add_arguments", "overrides", "prepare"]

#: flag -> (setting, type, metavar, help)
_FLAGS: dict[str, tuple[str, type, str | None, str]] = {
    "--camera": ("camera", str, None, "camera name in the keys"),
    "--stream": ("stream", str, "NAME", "a second detector's stream on this camera: detections/NAME in, "
                                        "localized/NAME out"),
    "--target-frame": ("target_frame", str, None, "frame to publish positions in"),
    "--camera-frame": ("camera_frame", str, None, "camera frame id when the frames carry none"),
    "--percentile": ("percentile", float, None, "depth percentile inside each box"),
    "--min-depth": ("min_depth_m", float, "M", "nearest valid depth"),
    "--max-depth": ("max_depth_m", float, "M", "farthest valid depth"),
    "--transform-wait": ("transform_wait_s", float, "S", "how long to wait for a transform before dropping"),
    "--floor-homography": ("floor_homography", Path, "FILE", 'frames without depth: place people on the floor through '
                           'this image-to-floor homography, JSON {"H": 3x3, "image_size": [w, h]} (a fixed camera; '
                           "default: through the camera's pose in the target frame)"),
    "--floor-homography-frame": ("floor_homography_frame", str, "FRAME",
                                 "frame of the homography's floor coordinates"),
    "--floor-z": ("floor_z_m", float, "M", "height of the floor plane"),
    "--max-floor-range": ("max_floor_range_m", float, "M",
                          "frames without depth: farthest person kept, on the floor from the camera"),
}


def add_arguments(parser: argparse.ArgumentParser) -> None:
    g = parser.add_argument_group("localizer")
    for flag, (dest, kind, metavar, help_text) in _FLAGS.items():
        g.add_argument(flag, dest=dest, type=kind, default=None, metavar=metavar, help=help_text)
    add_node_arguments(parser, "localizer", LocalizerConfig)


def overrides(args: argparse.Namespace) -> dict[str, Any]:
    return {dest: getattr(args, dest, None) for dest, *_ in _FLAGS.values()}


def prepare(config: LocalizerConfig) -> dict[str, Any]:
    """Read the floor homography before the transport opens, so a bad file stops the node at once."""
    if config.floor_homography is None:
        return {}
    return {"floor_homography": read_floor_homography(config.floor_homography)}
