"""The flags of ``perception laser`` and the settings they override."""

from __future__ import annotations

import argparse
from pathlib import Path
from typing import Any

from common.runtime.node import add_node_arguments
from services.laser.config import LaserConfig
from services.laser.model_file import load_model

__all__ = ["add_arguments", "overrides", "prepare"]

#: flag -> (setting, type, metavar, help)
_FLAGS: dict[str, tuple[str, type, str | None, str]] = {
    "--laser": ("laser", str, "NAME", "scanner name in the keys: scans/NAME in, localized/NAME out"),
    "--target-frame": ("target_frame", str, "FRAME", "frame to publish the people in"),
    "--laser-frame": ("laser_frame", str, "FRAME", "the scanner's frame id when its scans carry none"),
    "--model": ("model", Path, "FILE", "a leg classifier from 'perception train-legs' (default: the shipped one)"),
    "--min-probability": ("min_probability", float, "P", "a person's least probability to be published"),
    "--max-range": ("max_range_m", float, "M", "farthest leg kept"),
    "--map-clearance": ("map_clearance_m", float, "M", "leave out people this close to the static map's obstacles"),
    "--static-map": ("static_map", Path, "MAP.yaml", "the robot's static map (a ROS map_server / Nav2 map_saver YAML "
                     "file, in the target frame): legs on its walls and furniture (chair and table legs) are not "
                     "people; default: the static_map stream's (perception ros2's /map)"),
}


def add_arguments(parser: argparse.ArgumentParser) -> None:
    g = parser.add_argument_group("laser")
    for flag, (dest, kind, metavar, help_text) in _FLAGS.items():
        g.add_argument(flag, dest=dest, type=kind, default=None, metavar=metavar, help=help_text)
    add_node_arguments(parser, "laser", LaserConfig)


def overrides(args: argparse.Namespace) -> dict[str, Any]:
    return {dest: getattr(args, dest, None) for dest, *_ in _FLAGS.values()}


def prepare(config: LaserConfig) -> dict[str, Any]:
    """Read the leg classifier and the static map before the transport opens, so a bad file stops
    the node at once."""
    return {"model": load_model(config.model)[0], "obstacles": config.obstacles()}
