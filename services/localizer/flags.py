"""The flags of ``perception localizer`` and the settings they override."""

from __future__ import annotations

import argparse
from typing import Any

from common.runtime.node import add_node_arguments

__all__ = ["add_arguments", "overrides"]

#: flag -> (setting, type, metavar, help)
_FLAGS: dict[str, tuple[str, type, str | None, str]] = {
    "--camera": ("camera", str, None, "camera name in the keys (default head)"),
    "--stream": ("stream", str, "NAME", "a second detector's stream on this camera: detections/NAME in, "
                                        "localized/NAME out (default: the camera's name)"),
    "--target-frame": ("target_frame", str, None, "frame to publish positions in (default map)"),
    "--camera-frame": ("camera_frame", str, None, "camera frame id when the frames carry none"),
    "--percentile": ("percentile", float, None, "depth percentile inside each box (default 25)"),
    "--min-depth": ("min_depth_m", float, "M", "nearest valid depth (default 0.3)"),
    "--max-depth": ("max_depth_m", float, "M", "farthest valid depth (default 10)"),
    "--transform-wait": ("transform_wait_s", float, "S", "how long to wait for a transform before dropping (default 0.25)"),
}


def add_arguments(parser: argparse.ArgumentParser) -> None:
    g = parser.add_argument_group("localizer")
    for flag, (dest, kind, metavar, help_text) in _FLAGS.items():
        g.add_argument(flag, dest=dest, type=kind, default=None, metavar=metavar, help=help_text)
    add_node_arguments(parser, "localizer")


def overrides(args: argparse.Namespace) -> dict[str, Any]:
    return {dest: getattr(args, dest, None) for dest, *_ in _FLAGS.values()}
