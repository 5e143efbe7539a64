"""``perception doctor``: watch a live system (or read a recording) and print a checklist of
what is wrong, each failure with its one-line fix. Exit status 0, 1 or 2."""

from __future__ import annotations

import argparse
import json
import logging
import sys
from pathlib import Path

from common.runtime.cli_util import CliError, add_key_arguments, keys_from_args
from common.transport.zenoh_config import add_zenoh_arguments
from tools.doctor.collect import Observer
from tools.doctor.core.checks import exit_code, render, run_checks, to_dicts

log = logging.getLogger(__name__)

DESCRIPTION = """\
Watch the robot's perception system for a few seconds (or read a recording) and print
a checklist: each line is ✓ (fine), ! (a warning) or ✗ (a failure), with what was
measured and, when something is wrong, the one-line fix.

  Streams     is each key alive, at what rate, from which node; which nodes run, which
              failed (and why), which drop or refuse inputs, and for what reason
  Camera      camera info (K, size), depth registered to colour, the depth unit
              (uint16 mm or float m, and what the values look like), valid depth share
  Transforms  map ← odom ← base_link ← … ← camera complete at the frames' stamps; the
              missing or stale edge; static transforms republished
  Clocks      how far the frames' stamps are from this machine's clock
  Chain       frames → detections → localized → embeddings → tracks, and the counted
              reason at the first stage that loses them
  Config      camera names, the embedding model against the tracker's, the tracker's frame

Exit status: 0 when every check passes, 1 on a warning, 2 on a failure, so a start-up
script can gate on it. --json prints the same checklist for machines.

examples:
  perception doctor
  perception doctor --duration 10 --robot mbot --connect tcp/192.168.1.20:7447
  perception doctor --recording run.mcap --json"""


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--duration", type=float, default=5.0, metavar="S",
                        help="how long to watch a live system (default 5 s)")
    parser.add_argument("--json", action="store_true", help="print the checklist as JSON")
    parser.add_argument("--recording", type=Path, default=None, metavar="FILE",
                        help="judge a recording (MCAP of perception record, or a ROS bag) instead of a live system")
    add_key_arguments(parser)
    add_zenoh_arguments(parser)


def _live(args: argparse.Namespace, observer: Observer) -> tuple[float, str]:
    from common.transport.zenoh import open_transport_from_args
    from tools.doctor.live import watch

    if args.duration <= 0:
        raise CliError(f"--duration must be positive, got {args.duration}")
    keys = keys_from_args(args)
    transport = open_transport_from_args(args)
    with transport:
        print(f"perception doctor: watching robot {keys.robot!r} for {args.duration:g} s ...", file=sys.stderr, flush=True)
        watched = watch(transport, keys, args.duration, observer)
    return watched, f"robot {keys.robot!r}, watched live for {watched:.1f} s"


def _recorded(args: argparse.Namespace, observer: Observer) -> tuple[float, str, list[str]]:
    from tools.doctor.recording import read_recording
    from tools.replay.sources import SourceError

    try:
        span, notes = read_recording(args.recording, observer)
    except SourceError as exc:
        raise CliError(str(exc)) from exc
    return span, f"recording {args.recording} ({span:.1f} s)", notes


def main(args: argparse.Namespace) -> int:
    observer = Observer()
    notes: list[str] = []
    if args.recording is not None:
        duration, title, notes = _recorded(args, observer)
        obs = observer.observation(duration, source="recording", liveliness=False)
    else:
        duration, title = _live(args, observer)
        obs = observer.observation(duration)
    checks = run_checks(obs)
    code = exit_code(checks)
    if args.json:
        print(json.dumps({"source": title, "exit_code": code, "notes": notes, "checks": to_dicts(checks)}, indent=2,
                         ensure_ascii=False))
    else:
        print(render(checks, f"perception doctor: {title}"))
        for note in notes:
            print(f"note: {note}")
    return code
