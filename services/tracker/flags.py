"""The flags of ``perception tracker`` and the settings they override."""

from __future__ import annotations

import argparse
from pathlib import Path
from typing import Any

from common.runtime.node import add_node_arguments
from services.tracker.config import PROFILES, TrackerConfig

__all__ = ["add_arguments", "adjust", "overrides"]


def add_arguments(parser: argparse.ArgumentParser) -> None:
    g = parser.add_argument_group("tracker")
    g.add_argument("--camera", default=None, help="camera whose streams to track, '*' for all (default head)")
    g.add_argument("--profile", choices=PROFILES, default=None,
                   help="'robust' (default): cue fusion, staged association, life cycle in seconds; "
                        "'thesis': Pinto's thesis exactly")
    g.add_argument("--embedding-model", default=None, metavar="NAME",
                   help="only use descriptors of this model (default: the first model seen)")
    g.add_argument("--time-step", choices=("time", "frame"), default=None,
                   help="thesis profile: 'time': dt from stamps (default); 'frame': dt = 1 per frame, as the thesis")
    g.add_argument("--output-rate", type=float, default=None, metavar="HZ",
                   help="publish Tracks at this rate, predicted to the publish time (default 10); 0: once per frame")
    g.add_argument("--no-embeddings", action="append", default=None, metavar="STREAM",
                   help="a stream no embedder reads (a second detector's, e.g. head-hog): tracked by position at "
                        "once; repeat for several (use with --camera '*')")
    g.add_argument("--static-map", type=Path, default=None, metavar="MAP.yaml",
                   help="robust: the robot's static map (a ROS map_server / Nav2 map_saver YAML file, in the tracking "
                        "frame): no track is born on its walls and furniture (a door jamb seen as a person)")
    g.add_argument("--memory", type=Path, default=None, metavar="FILE", help="ID memory file")
    g.add_argument("--no-memory", action="store_true", help="do not load or save an ID memory")
    add_node_arguments(parser, "tracker")


def overrides(args: argparse.Namespace) -> dict[str, Any]:
    return {"camera": args.camera, "profile": args.profile, "embedding_model": args.embedding_model,
            "thesis": {"time_step": args.time_step}, "robust": {"static_map": {"path": args.static_map}},
            "memory_path": args.memory, "output_rate_hz": args.output_rate,
            "no_embeddings": args.no_embeddings}


def adjust(args: argparse.Namespace) -> Any:
    """``--no-memory`` turns the memory off whatever the file or environment say."""

    def apply(config: TrackerConfig) -> TrackerConfig:
        return config.model_copy(update={"memory_path": None}) if args.no_memory else config

    return apply
