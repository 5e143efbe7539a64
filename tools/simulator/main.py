"""``perception simulate``: a simulated robot publishing RGB-D frames, transforms and ground truth."""

from __future__ import annotations

import argparse
import logging
from pathlib import Path

from common.runtime.cli_util import CliError, add_key_arguments, keys_from_args
from common.runtime.config import ConfigError, load_config
from common.runtime.progress import progress
from common.runtime.service import Counters, ServiceRuntime, Shutdown, package_version
from common.runtime.settings import add_settings_epilog, flag_help
from common.transport.zenoh_config import add_zenoh_arguments, options_from_args
from common.transport.zenoh import TransportError, open_transport
from tools.replay.recorder import McapRecorder
from tools.simulator.config import SimulatorConfig
from tools.simulator.core.laser_map import LASER_HEIGHT_M
from tools.simulator.core.scenarios import SCENARIOS
from tools.simulator.faults import FAULTS
from tools.simulator.groundtruth import GroundTruthCsv
from tools.simulator.service import SimulatorService
from tools.simulator.snapshot import write_snapshot
from tools.simulator.source import SimulatedStream
from tools.simulator.static_map import write_apartment_map

log = logging.getLogger(__name__)

DESCRIPTION = """\
Simulate the robot's head RGB-D camera and localization in an apartment with people:
RGB + registered depth (16UC1 mm) frames with camera info, transforms map->odom->base_link
->head_link->camera, and the people's true positions (map frame) with a visibility flag.
--back-camera NAME adds a second RGB-D camera fixed on the base looking backwards
(frames/NAME, base_link->NAME_link->NAME_optical on tf_static); --laser a 2-D laser on the base
(scans/front, base_link->base_laser on tf_static).

  perception simulate --list
  perception simulate --scenario moving-base                 # publish in real time
  perception simulate --scenario chairs --max                # as fast as the detector keeps up
  perception simulate --scenario still --output run.mcap --gt-csv gt.csv
  perception simulate --scenario still --snapshot still.png --snapshot-time 6
  perception simulate --scenario handover --back-camera back # two cameras, people walk from one to the other
  perception simulate --scenario still --laser               # and a 2-D laser on the base (scans/front)
  perception simulate --fault depth-float-mm                 # a setup mistake, for perception doctor"""


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--list", action="store_true", help="list the scenarios and exit")
    parser.add_argument("--scenario", default=None, help="scenario name")
    parser.add_argument("--seed", type=int, default=None, help="random seed: same seed, same run")
    parser.add_argument(
        "--duration",
        type=float,
        default=None,
        metavar="S",
        help=flag_help(SimulatorConfig, "duration_s", "simulated seconds"),
    )
    parser.add_argument("--fps", type=float, default=None, metavar="HZ", help="frames per simulated second")
    parser.add_argument("--width", type=int, default=None, metavar="PX", help="image width")
    parser.add_argument("--height", type=int, default=None, metavar="PX", help="image height")
    parser.add_argument("--camera", default=None, help="camera name in keys and headers")
    parser.add_argument(
        "--back-camera",
        default=None,
        metavar="NAME",
        help="also publish a camera fixed on the base looking backwards (0.95 m up, yaw 180 deg, the head "
             "camera's size and intrinsics) as frames/NAME, frame id NAME_optical, its mount "
             "base_link->NAME_link->NAME_optical on tf_static",
    )
    parser.add_argument(
        "--laser",
        nargs="?",
        const="front",
        default=None,
        metavar="NAME",
        help="also publish a 2-D laser on the base (360 degrees, 0.25-degree steps, 15 Hz by default: the settings "
             "laser_fov_deg, laser_step_deg, laser_rate_hz; 0.2 m above the floor, Hokuyo-like noise and dropouts) "
             "as scans/NAME (default front; with --ros2 on /scan), frame id base_laser on tf_static; the ground "
             "truth then says whom it could see (laser_seen)",
    )
    speed = parser.add_mutually_exclusive_group()
    speed.add_argument("--rate", type=float, default=None, metavar="X", help="speed relative to real time")
    speed.add_argument(
        "--max",
        dest="max_speed",
        action="store_true",
        default=None,
        help="publish each frame once the detector (each camera's, with --back-camera) has answered the previous one",
    )
    parser.add_argument("--alike", action="store_true", default=None, help="dress the first two people alike")
    parser.add_argument(
        "--min-visible",
        type=float,
        default=None,
        metavar="F",
        help="ground-truth rule: share of the body that must be seen",
    )
    parser.add_argument(
        "--no-depth-noise", dest="depth_noise", action="store_false", default=None, help="exact depth (for debugging)"
    )
    parser.add_argument("--start-ns", type=int, default=None, metavar="NS",
                        help="stamp of frame 0 in ns since the epoch")
    parser.add_argument("--head-control", action="store_true", default=None,
                        help="the head obeys HeadCommand (perception attention) instead of the scenario's motion")
    parser.add_argument("--fault", dest="faults", action="append", default=None, choices=sorted(FAULTS),
                        help="make a setup mistake on purpose, repeatable, to see what `perception doctor` "
                             "says: " + "; ".join(f"{k}: {v}" for k, v in FAULTS.items()))
    parser.add_argument(
        "--service-config",
        dest="config_file",
        default=None,
        metavar="FILE",
        help="YAML/JSON settings; its 'simulator' section if it has one, else the whole file "
             "(--config is the Zenoh config)",
    )
    parser.add_argument("--settings", dest="config_file", default=None, help=argparse.SUPPRESS)  # the old spelling
    parser.add_argument("--ros2", action="store_true", default=None,
                        help="be a ROS 2 robot: the head camera (rgb8, 16UC1 aligned depth, camera info on the "
                             "RealSense driver's topics) and /tf, /tf_static as ROS 2 topics over rmw_zenoh, for "
                             "perception ros2 to read; the ground truth stays on this project's key")
    out = parser.add_argument_group("files instead of (or besides) publishing")
    out.add_argument("--output", type=Path, default=None, help="write an MCAP recording instead of publishing")
    out.add_argument("--gt-csv", type=Path, default=None, help="write the ground truth as frame,id,x,y,z")
    out.add_argument("--write-map", type=Path, default=None, metavar="MAP.yaml",
                     help="write the apartment's static map as the robot's laser would have mapped it (a ROS map "
                          "YAML file and its PGM image, in the map frame) and exit: give it to "
                          "`perception tracker --static-map`")
    out.add_argument("--snapshot", type=Path, default=None, help="write one RGB + depth picture (PNG) and exit")
    out.add_argument("--snapshot-time", type=float, default=5.0, metavar="S", help="time of the snapshot (default 5)")
    add_key_arguments(parser)
    add_zenoh_arguments(parser)
    add_settings_epilog(parser, SimulatorConfig, "simulator")


def _config(args: argparse.Namespace) -> SimulatorConfig:
    overrides = {
        name: getattr(args, name)
        for name in (
            "scenario",
            "seed",
            "fps",
            "width",
            "height",
            "camera",
            "back_camera",
            "laser",
            "rate",
            "max_speed",
            "alike",
            "min_visible",
            "depth_noise",
            "start_ns",
            "head_control",
            "faults",
            "ros2",
        )
    }
    overrides["duration_s"] = args.duration
    try:
        return load_config(
            SimulatorConfig,
            args.config_file,
            env_prefix="PERCEPTION_SIMULATOR",
            overrides=overrides,
            section="simulator",
        )
    except ConfigError as exc:
        raise CliError(f"{exc} (see perception simulate --help and --list)") from exc


def list_scenarios() -> str:
    width = max(len(n) for n in SCENARIOS)
    return "\n".join(f"{s.name:<{width}}  {s.duration_s:5.1f} s  {s.description}" for s in SCENARIOS.values())


def _writable(path: Path | None) -> None:
    if path is not None and not path.parent.exists():
        raise CliError(f"{path}: the folder {path.parent} does not exist")


def _record(config: SimulatorConfig, args: argparse.Namespace, gt: GroundTruthCsv | None) -> int:
    keys = keys_from_args(args)
    stream = SimulatedStream(config, keys)
    if stream.frame_count is None:
        raise CliError("--duration 0 (until Ctrl-C) cannot be written to a file; give a duration in seconds")
    with McapRecorder(args.output, key_exprs=[keys.all()], writer_version=package_version()) as sink, Shutdown() as shutdown:
        for seq in progress(range(stream.frame_count), total=stream.frame_count, desc="simulate", unit="frame"):
            if shutdown.is_set():
                break
            _, pairs = stream.messages(seq)
            for key, msg in pairs:
                sink.write(key, msg, log_time_ns=msg.header.stamp_ns)
            if gt is not None:
                gt.add(SimulatedStream.groundtruth_of(pairs))
        counts = ", ".join(f"{k.rsplit('/', 1)[-1]}: {n}" for k, n in sink.counts.items())
    print(f"wrote {args.output} ({counts})")
    return 0


def main(args: argparse.Namespace) -> int:
    if args.list:
        print(list_scenarios())
        return 0
    config = _config(args)
    for path in (args.output, args.gt_csv, args.snapshot, args.write_map):
        _writable(path)
    if args.write_map is not None:
        image = write_apartment_map(args.write_map)
        print(f"wrote {args.write_map} and {image}: the apartment as a laser {LASER_HEIGHT_M:g} m above the floor "
              "maps it")
        return 0
    if args.snapshot is not None:
        stream = SimulatedStream(config, keys_from_args(args))
        fd, _ = stream.messages(round(args.snapshot_time * config.fps))
        write_snapshot(fd, args.snapshot)
        print(f"wrote {args.snapshot}")
        return 0
    gt = GroundTruthCsv(args.gt_csv) if args.gt_csv is not None else None
    try:
        if args.output is not None:
            return _record(config, args, gt)
        return _publish(config, args, gt)
    finally:
        if gt is not None:
            gt.close()
            print(f"wrote {args.gt_csv} ({gt.rows} rows)")


def _publish(config: SimulatorConfig, args: argparse.Namespace, gt: GroundTruthCsv | None) -> int:
    keys = keys_from_args(args)
    try:
        opts = options_from_args(args)
        if config.ros2:  # a ROS 2 robot's session: /map is transient local, a cached publisher
            opts = opts.model_copy(update={"timestamping": True})
        transport = open_transport(opts)
    except (TransportError, ValueError) as exc:
        raise CliError(str(exc)) from exc
    counters = Counters()
    try:
        service = SimulatorService(transport, keys, config, counters, gt_csv=gt)
        with Shutdown() as shutdown, ServiceRuntime("simulator", transport, keys, counters=counters) as runtime:
            runtime.watch(*service.publishers.values())
            log.info(
                "simulating %s at %gx%g, %g fps, %s",
                config.scenario,
                config.width,
                config.height,
                config.fps,
                "max speed" if config.max_speed else f"rate {config.rate:g}",
            )
            service.run(shutdown)
        service.close()
    finally:
        transport.close()
    return 0
