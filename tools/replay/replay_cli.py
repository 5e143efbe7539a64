"""``perception replay FILE``: publish a recording or a ROS bag onto the perception keys."""

from __future__ import annotations

import argparse
import logging
import sys
from pathlib import Path

from common.runtime.cli_util import CliError, add_key_arguments, keys_from_args
from common.runtime.config import ConfigError
from common.runtime.service import ServiceRuntime, Shutdown
from common.transport.zenoh_config import add_zenoh_arguments
from tools.replay.bag_source import BagOptions
from tools.replay.config import load_topic_map
from tools.replay.core.mapping import parse_remap, parse_scan_topic
from tools.replay.core.timeline import TimeWindow
from tools.replay.engine import ReplayOptions, Replayer, ReplayStats
from tools.replay.progress import Progress
from tools.replay.sources import Source, SourceError, open_source

log = logging.getLogger(__name__)

DESCRIPTION = """Publish every stream of FILE on its key, in stamp order, keeping the recorded timing.

FILE is an MCAP recording from `perception record`, a ROS 1 .bag, or a ROS 2 bag folder
(sqlite3 or mcap storage). Bags are converted: colour + depth images are paired by stamp
into RGBDFrame on frames/CAMERA with the latest camera info; /tf, /tf_static and
/odom (as the transform odom -> base_link) go to the tf and tf_static keys; laser scans
(sensor_msgs/LaserScan) to scans/LASER: /scan as front, /rear_scan as rear...
(--scan-topic names them). Topics without a stream are listed and skipped. Timing
follows the message stamps.

examples:
  perception replay run.mcap --rate 0.5
  perception replay office.bag --camera head --max
  perception replay rosbag2_folder --topic-map topics.yaml --start 10 --end 40 --loop
  perception replay run.mcap --remap pp/robot=pp/sim
  perception replay robot.bag --scan-topic /left_scan=front --scan-topic /rear_scan=rear"""


def add_topic_arguments(parser: argparse.ArgumentParser) -> None:
    g = parser.add_argument_group("ROS bag topics (defaults: the usual openni/RealSense names)")
    g.add_argument("--topic-map", type=Path, default=None, metavar="YAML", help="topic map file (see the README)")
    g.add_argument("--camera", default="head", help="camera name of the frames key for the flags below (default head)")
    g.add_argument("--rgb-topic", default=None, metavar="TOPIC", help="colour sensor_msgs/Image or CompressedImage")
    g.add_argument("--depth-topic", default=None, metavar="TOPIC", help="registered depth image (16UC1 mm or 32FC1 m)")
    g.add_argument("--camera-info-topic", default=None, metavar="TOPIC", help="sensor_msgs/CameraInfo of the colour camera")
    g.add_argument("--tf-topic", action="append", default=None, metavar="TOPIC", help="tf2_msgs/TFMessage topic, repeatable")
    g.add_argument("--tf-static-topic", action="append", default=None, metavar="TOPIC", help="static TF topic, repeatable")
    g.add_argument("--odom-topic", action="append", default=None, metavar="TOPIC",
                   help="nav_msgs/Odometry topic, repeatable (published as the transform odom -> base_link on tf)")
    g.add_argument("--scan-topic", action="append", default=None, metavar="TOPIC[=NAME]",
                   help="sensor_msgs/LaserScan topic replayed on scans/NAME (default NAME: /scan -> front, "
                        "/rear_scan -> rear), repeatable; given, only these laser topics are replayed "
                        "(default: every one)")
    g.add_argument("--pair-tolerance-ms", type=float, default=None, metavar="MS",
                   help="largest stamp gap of paired colour and depth images (default 20)")
    add_key_arguments(parser)


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("file", type=Path, help="MCAP file, ROS 1 .bag file or ROS 2 bag folder")
    t = parser.add_argument_group("timing")
    speed = t.add_mutually_exclusive_group()
    speed.add_argument("--rate", "-r", type=float, default=1.0, metavar="X", help="speed factor (default 1: real time)")
    speed.add_argument("--max", action="store_true", help="as fast as the subscribers keep up (publishers block)")
    t.add_argument("--loop", action="store_true", help="start over at the end, until Ctrl-C")
    t.add_argument("--start", type=float, default=0.0, metavar="S", help="skip the first S seconds of the file")
    t.add_argument("--end", type=float, default=None, metavar="S", help="stop at S seconds from the file's start")
    t.add_argument("--wait-subscribers", type=float, default=2.0, metavar="S",
                   help="wait up to S seconds for subscribers on every stream before starting (default 2)")
    parser.add_argument("--remap", action="append", default=[], metavar="OLD=NEW",
                        help="publish keys starting with OLD under NEW instead, repeatable")
    parser.add_argument("--linger", type=float, default=0.5, metavar="S",
                        help="keep the session open S seconds after the last message, so that what is still "
                             "queued is delivered (default 0.5)")
    parser.add_argument("--no-progress", action="store_true", help="no progress display")
    add_topic_arguments(parser)
    add_zenoh_arguments(parser)


def bag_options_from_args(args: argparse.Namespace) -> BagOptions:
    try:
        scans = [parse_scan_topic(rule) for rule in args.scan_topic or []]
    except ValueError as exc:
        raise CliError(str(exc)) from exc
    flags = {"rgb": args.rgb_topic, "depth": args.depth_topic, "camera_info": args.camera_info_topic,
             "tf": args.tf_topic, "tf_static": args.tf_static_topic, "odom": args.odom_topic,
             "scan": scans, "pair_tolerance_ms": args.pair_tolerance_ms}
    try:
        cfg = load_topic_map(args.topic_map, args.camera, flags)
    except ConfigError as exc:
        raise CliError(f"topic map: {exc}") from exc
    return BagOptions(keys=keys_from_args(args), cameras=cfg.camera_dict(), lists=cfg.list_dict(),
                      lasers=cfg.lasers, default_camera=args.camera, pair_tolerance_ns=int(cfg.pair_tolerance_ms * 1e6))


def report(source: Source, stats: ReplayStats) -> None:
    """The per-stream counts on stdout, the conversion problems in the log."""
    rate = stats.total / stats.elapsed_s if stats.elapsed_s > 0 else 0.0
    print(f"replayed {stats.total} messages ({stats.bytes / 1e6:.1f} MB) in {stats.elapsed_s:.2f} s "
          f"({rate:.1f} msg/s, {stats.bytes / 1e6 / max(stats.elapsed_s, 1e-9):.1f} MB/s), {stats.passes} pass(es)")
    for key, n in sorted(stats.published.items()):
        print(f"  {key}: {n}")
    if stats.late:
        print(f"  {stats.late} messages came later than the reorder window and went out of stamp order")
    for topic, why in source.skipped.items():
        print(f"  skipped {topic}: {why}")
    for (stream, reason), n in source.problems.items():
        print(f"  {stream}: {n} x {reason}")


def main(args: argparse.Namespace) -> int:
    from common.transport.zenoh import open_transport_from_args

    remap = []
    for rule in args.remap:
        try:
            remap.append(parse_remap(rule))
        except ValueError as exc:
            raise CliError(str(exc)) from exc
    try:
        window = TimeWindow(args.start, args.end)
        options = ReplayOptions(rate=None if args.max else args.rate, loop=args.loop, window=window, remap=remap,
                                wait_subscribers_s=args.wait_subscribers)
        if args.rate is not None and not args.rate > 0:
            raise ValueError(f"--rate must be > 0, got {args.rate}")
    except ValueError as exc:
        raise CliError(str(exc)) from exc
    try:
        source = open_source(args.file, bag_options_from_args(args))
    except SourceError as exc:
        raise CliError(str(exc)) from exc
    with source:
        if not source.streams():
            reasons = "; ".join(f"{t}: {why}" for t, why in source.skipped.items()) or "no streams"
            raise CliError(f"{args.file}: nothing to replay ({reasons})")
        transport = open_transport_from_args(args)
        error: SourceError | None = None
        with Shutdown() as shutdown, transport, ServiceRuntime("replay", transport, keys_from_args(args)) as runtime:
            progress = Progress(source.duration_s(), sys.stderr, enabled=not args.no_progress)
            replayer = Replayer(transport, source, options, progress)
            runtime.watch(*replayer.publishers)
            try:
                stats = replayer.run(shutdown)
            except SourceError as exc:
                error, stats = exc, replayer.stats
            if stats.total and args.linger > 0:
                shutdown.wait(args.linger)  # Zenoh drops what is still queued when the session closes
        report(source, stats)
        if error is not None:
            raise CliError(str(error))
        if stats.total == 0:
            problems = "; ".join(f"{s}: {r}" for (s, r) in source.problems) or "no message in the selected time range"
            raise CliError(f"{args.file}: nothing was replayed ({problems})")
    return 0
