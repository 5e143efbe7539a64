"""The flags of ``perception tracker`` and the settings they override."""

from __future__ import annotations

import argparse
from pathlib import Path
from typing import Any

from common.runtime.cli_util import CliError
from common.runtime.node import add_node_arguments
from common.runtime.settings import flag_help
from services.tracker.config import PROFILES, TrackerConfig
from services.tracker.presets import PresetError, load_preset, preset_names

__all__ = ["add_arguments", "add_preset_argument", "adjust", "overrides", "preset"]


def add_preset_argument(parser: argparse.ArgumentParser | argparse._ArgumentGroup) -> None:
    """``--preset NAME``: a file of deploy/presets/ as a layer between the defaults and --service-config."""
    parser.add_argument("--preset", default=None, metavar="NAME",
                        help="tracker settings for a kind of site, deploy/presets/NAME.yaml, between the defaults and "
                             f"--service-config ({', '.join(preset_names()) or 'none shipped'})")


def preset(args: argparse.Namespace) -> dict[str, Any] | None:
    """The settings of ``--preset``, or None without one; CliError naming the known presets."""
    if args.preset is None:
        return None
    try:
        return load_preset(args.preset)
    except PresetError as exc:
        raise CliError(str(exc)) from exc


def add_arguments(parser: argparse.ArgumentParser) -> None:
    g = parser.add_argument_group("tracker")
    g.add_argument("--camera", default=None, help="camera whose streams to track, '*' for all")
    g.add_argument("--profile", choices=PROFILES, default=None)
    g.add_argument("--embedding-model", default=None, metavar="NAME",
                   help="only use descriptors of this model; none: the first model seen")
    g.add_argument("--time-step", choices=("time", "frame"), default=None,
                   help=flag_help(TrackerConfig, "thesis.time_step"))
    g.add_argument("--output-rate", type=float, default=None, metavar="HZ",
                   help=flag_help(TrackerConfig, "output_rate_hz"))
    g.add_argument("--no-embeddings", action="append", default=None, metavar="STREAM",
                   help="a stream no embedder reads (a second detector's, e.g. head-hog): tracked by position at "
                        "once; repeat for several (use with --camera '*')")
    g.add_argument("--laser", action="append", default=None, metavar="LASER", dest="lasers",
                   help="a 2-D laser whose people (localized/LASER, 'perception laser') are fused by position; "
                        "repeat for several (default: front and rear); --laser none: the camera alone")
    g.add_argument("--static-map", type=Path, default=None, metavar="MAP.yaml",
                   help=flag_help(TrackerConfig, "robust.static_map.path", "robust: the robot's static map (a ROS "
                                  "map_server / Nav2 map_saver YAML file, in the tracking frame): no track is born on "
                                  "its walls and furniture (a door jamb seen as a person)"))
    add_preset_argument(g)
    g.add_argument("--memory", type=Path, default=None, metavar="FILE", help=flag_help(TrackerConfig, "memory_path"))
    g.add_argument("--no-memory", action="store_true", help="do not load or save an ID memory")
    add_node_arguments(parser, "tracker", TrackerConfig)


def overrides(args: argparse.Namespace) -> dict[str, Any]:
    return {"camera": args.camera, "profile": args.profile, "embedding_model": args.embedding_model,
            "thesis": {"time_step": args.time_step}, "robust": {"static_map": {"path": args.static_map}},
            "memory_path": args.memory, "output_rate_hz": args.output_rate,
            "no_embeddings": args.no_embeddings,
            "lasers": None if args.lasers is None else [x for x in args.lasers if x != "none"]}


def adjust(args: argparse.Namespace) -> Any:
    """``--no-memory`` turns the memory off whatever the file or environment say."""

    def apply(config: TrackerConfig) -> TrackerConfig:
        return config.model_copy(update={"memory_path": None}) if args.no_memory else config

    return apply
