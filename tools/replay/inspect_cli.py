"""``perception inspect FILE``: what a recording or bag holds."""

from __future__ import annotations

import argparse
import datetime as dt
from pathlib import Path

from common.runtime.cli_util import CliError
from tools.replay.sources import SourceError, Summary, open_source

DESCRIPTION = """Summarise an MCAP recording (from `perception record`), a ROS 1 .bag or a ROS 2 bag
folder: its streams or topics with message type, count and mean rate, its duration and
time range. For bags it also shows which perception stream each topic would feed
(the same topic map flags as `perception replay`)."""


def add_arguments(parser: argparse.ArgumentParser) -> None:
    from tools.replay.replay_cli import add_topic_arguments

    parser.add_argument("file", type=Path, help="MCAP file, ROS 1 .bag file or ROS 2 bag folder")
    add_topic_arguments(parser)


def _time(ns: int) -> str:
    return dt.datetime.fromtimestamp(ns / 1e9, tz=dt.timezone.utc).isoformat(timespec="milliseconds")


def format_summary(path: Path, s: Summary) -> str:
    lines = [f"{path}  ({s.format})",
             f"duration {s.duration_s:.3f} s, from {_time(s.start_ns)} to {_time(s.end_ns)}",
             f"{sum(st.count for st in s.streams)} messages in {len(s.streams)} streams", ""]
    width = max([len(st.name) for st in s.streams] + [6])
    twidth = max([len(st.type) for st in s.streams] + [4])
    lines.append(f"{'stream':<{width}}  {'type':<{twidth}}  {'count':>7}  {'rate Hz':>8}  note")
    for st in s.streams:
        rate = (st.count - 1) / s.duration_s if s.duration_s > 0 and st.count > 1 else 0.0
        lines.append(f"{st.name:<{width}}  {st.type:<{twidth}}  {st.count:>7}  {rate:>8.2f}  {st.note}".rstrip())
    lines.extend(s.extra)
    return "\n".join(lines)


def main(args: argparse.Namespace) -> int:
    from tools.replay.replay_cli import bag_options_from_args

    try:
        with open_source(args.file, bag_options_from_args(args)) as source:
            print(format_summary(args.file, source.summary()))
    except SourceError as exc:
        raise CliError(str(exc)) from exc
    return 0
