"""``perception legs``: the legs and people in a file's laser scans, one JSON line a scan."""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

from common.runtime.cli_util import CliError

DESCRIPTION = """\
Run the laser leg detector (the laser node's core, with the node's settings) over every laser scan
of FILE: a ROS 1 bag, a ROS 2 bag folder, or a recording of 'perception record'. Prints one JSON
line per scan read, in the file's order, positions in the scanner's frame (m):

  {"stamp_ns": ..., "frame": "laser", "topic": "/scan", "seq": 0,
   "legs": [{"x": ..., "y": ..., "score": ...}],
   "people": [{"x": ..., "y": ..., "score": ..., "legs": [0, 1], "cov": [[...], [...]]}]}

'score' is the calibrated probability that a leg is a leg (a person's: that at least one of
theirs is); 'people' lists those at or above --min-probability (default: the node's). A scan with
nothing in it gives empty lists. Without --json a summary per topic is printed instead."""


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("file", type=Path, metavar="FILE", help="a ROS 1 bag, a ROS 2 bag folder or a perception recording")
    p.add_argument("--topic", default=None, help="the scans' topic (default: every laser topic in the file)")
    p.add_argument("--json", action="store_true", help="one JSON line per scan (default: a summary)")
    p.add_argument("--model", type=Path, default=None, help="a leg classifier from 'perception train-legs'")
    p.add_argument("--service-config", type=Path, default=None, metavar="FILE",
                   help="the laser node's settings (its 'laser' section, or the whole file)")
    p.add_argument("--min-probability", type=float, default=None, help="a person's least probability to be listed")


def main(args: argparse.Namespace) -> int:
    import numpy as np

    from common.runtime.node import load_node_config
    from services.laser.config import LaserConfig
    from services.laser.core.legs import detect, pair
    from services.laser.core.scan import ScanGeometry
    from services.laser.files import ScanFileError, read_scans
    from services.laser.model_file import ModelFileError, load_model

    config = load_node_config(LaserConfig, "laser", args.service_config,
                              {"model": args.model, "min_probability": args.min_probability})
    try:
        model = load_model(config.model)[0]
    except ModelFileError as exc:
        raise CliError(str(exc)) from exc
    params = config.params()
    summary: dict[str, list[int]] = {}
    try:
        for topic, scan in read_scans(args.file, args.topic):
            g = ScanGeometry(scan.angle_min, scan.angle_increment, scan.range_min, scan.range_max)
            legs = detect(scan.ranges, g, model, params)
            people = pair(legs, params)
            keep = np.flatnonzero(people.probability >= config.min_probability)
            row = summary.setdefault(topic, [0, 0, 0])
            row[0] += 1
            row[1] += len(legs)
            row[2] += len(keep)
            if args.json:
                line = {"stamp_ns": scan.header.stamp_ns, "frame": scan.header.frame_id, "topic": topic,
                        "seq": scan.header.seq,
                        "legs": [{"x": round(float(x), 4), "y": round(float(y), 4), "score": round(float(s), 4)}
                                 for (x, y), s in zip(legs.xy, legs.probability)],
                        "people": [{"x": round(float(people.xy[k, 0]), 4), "y": round(float(people.xy[k, 1]), 4),
                                    "score": round(float(people.probability[k]), 4), "legs": list(people.legs[k]),
                                    "cov": np.round(people.cov[k], 5).tolist()} for k in keep]}
                sys.stdout.write(json.dumps(line) + "\n")
    except ScanFileError as exc:
        raise CliError(str(exc)) from exc
    except ValueError as exc:  # a scan that breaks LaserScan's rules
        raise CliError(f"{args.file}: a bad scan: {exc}") from exc
    except BrokenPipeError:  # `| head`
        return 0
    if not args.json:
        for topic, (n, n_legs, n_people) in summary.items():
            print(f"{topic}: {n} scans, {n_legs / max(n, 1):.2f} legs and {n_people / max(n, 1):.2f} people a scan")
    return 0
