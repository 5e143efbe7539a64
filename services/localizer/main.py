"""``perception localizer``: the localizer service on a Zenoh session."""

from __future__ import annotations

import argparse
import logging
from pathlib import Path


from common.cli_util import CliError, add_key_arguments, keys_from_args
from common.config import ConfigError, load_config, read_config_file
from common.runtime import Counters, ServiceRuntime, Shutdown
from common.zenoh_config import add_zenoh_arguments
from common.zenoh_transport import open_transport_from_args
from services.localizer.config import LocalizerConfig
from services.localizer.service import LocalizerService

log = logging.getLogger(__name__)

DESCRIPTION = """\
Place each detected person in the map frame: for every box of a Detections message,
take the 25th percentile of the valid depth pixels inside the box of the matching
depth frame, cast the ray through the box centre to that depth, and transform the
point (with its covariance) to --target-frame at the frame's time.

Subscribes to frames/{camera}, detections/{camera}, tf and tf_static; publishes
LocalizedDetections on localized/{camera}. Settings come from the defaults, then a
--service-config YAML/JSON file (its 'localizer' section, or the whole file), then
PERCEPTION_LOCALIZER__FIELD environment variables, then the flags below. See
services/localizer/README.md for every setting and the transforms it needs."""


def add_arguments(parser: argparse.ArgumentParser) -> None:
    g = parser.add_argument_group("localizer")
    g.add_argument(
        "--service-config",
        type=Path,
        default=None,
        metavar="FILE",
        help="YAML/JSON settings file (section 'localizer' if present)",
    )
    g.add_argument("--camera", default=None, help="camera name in the keys (default head)")
    g.add_argument("--target-frame", default=None, help="frame to publish positions in (default map)")
    g.add_argument("--camera-frame", default=None, help="camera frame id when the frames carry none")
    g.add_argument("--percentile", type=float, default=None, help="depth percentile inside each box (default 25)")
    g.add_argument(
        "--min-depth",
        dest="min_depth_m",
        type=float,
        default=None,
        metavar="M",
        help="nearest valid depth (default 0.3)",
    )
    g.add_argument(
        "--max-depth",
        dest="max_depth_m",
        type=float,
        default=None,
        metavar="M",
        help="farthest valid depth (default 10)",
    )
    g.add_argument(
        "--transform-wait",
        dest="transform_wait_s",
        type=float,
        default=None,
        metavar="S",
        help="how long to wait for a transform before dropping (default 0.25)",
    )
    add_key_arguments(parser)
    add_zenoh_arguments(parser)


def build_config(args: argparse.Namespace) -> LocalizerConfig:
    """Defaults -> file -> environment -> flags; CliError naming the bad value."""
    overrides = {
        name: getattr(args, name, None)
        for name in (
            "camera",
            "target_frame",
            "camera_frame",
            "percentile",
            "min_depth_m",
            "max_depth_m",
            "transform_wait_s",
        )
    }
    path = args.service_config
    try:
        section = "localizer" if path is not None and "localizer" in read_config_file(path) else None
        return load_config(
            LocalizerConfig, path, env_prefix="PERCEPTION_LOCALIZER", overrides=overrides, section=section
        )
    except ConfigError as exc:
        raise CliError(str(exc)) from exc


def main(args: argparse.Namespace) -> int:
    config = build_config(args)
    keys = keys_from_args(args)
    transport = open_transport_from_args(args)
    counters = Counters()
    with transport, Shutdown() as shutdown:
        # subscribe before the liveliness token appears, so 'alive' means 'listening'
        service = LocalizerService(transport, keys, config, counters)
        runtime = ServiceRuntime("localizer", transport, keys, counters=counters)
        runtime.watch(*service.subscriptions, service.pub)
        with runtime:
            service.run(shutdown)
    return 0
