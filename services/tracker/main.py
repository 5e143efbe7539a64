"""``perception tracker``: flags -> TrackerConfig -> Zenoh transport -> TrackerService."""

from __future__ import annotations

import argparse
import logging
from pathlib import Path

from pydantic import ValidationError

from common.cli_util import CliError, add_key_arguments, keys_from_args
from common.config import ConfigError, load_config
from common.runtime import Counters, ServiceRuntime, Shutdown
from common.zenoh_config import add_zenoh_arguments, options_from_args
from common.zenoh_transport import TransportError, open_transport
from services.tracker.config import TrackerConfig
from services.tracker.service import TrackerService

log = logging.getLogger(__name__)

DESCRIPTION = """\
Track people in 3-D with the thesis's Re-ID tracker (seed 000): Kalman filters,
appearance association gated by position (Algorithm 1), an ID memory that gives a
returning person their old ID (Algorithm 2). Subscribes to the localizer's
LocalizedDetections and the embedder's Embeddings, publishes the Confirmed tracks
after every frame, and answers `?id=K` queries on the track query key.

Settings come from defaults (the paper's values) <- --service-config FILE (section
'tracker' if present) <- PERCEPTION_TRACKER__FIELD environment variables <- flags.
The ID memory is kept in --memory (default under ~/.local/state) so a restarted
tracker keeps identities; --no-memory turns that off."""


def add_arguments(parser: argparse.ArgumentParser) -> None:
    g = parser.add_argument_group("tracker")
    g.add_argument("--service-config", type=Path, default=None, metavar="FILE",
                   help="YAML/JSON TrackerConfig (or a deploy file with a 'tracker' section)")
    g.add_argument("--camera", default=None, help="camera whose streams to track, '*' for all (default head)")
    g.add_argument("--embedding-model", default=None, metavar="NAME",
                   help="only use descriptors of this model (default: the first model seen)")
    g.add_argument("--time-step", choices=("time", "frame"), default=None,
                   help="'time': dt from stamps (default); 'frame': dt = 1 per frame, as the thesis")
    g.add_argument("--memory", type=Path, default=None, metavar="FILE", help="ID memory file")
    g.add_argument("--no-memory", action="store_true", help="do not load or save an ID memory")
    add_key_arguments(parser)
    add_zenoh_arguments(parser)


def config_from_args(args: argparse.Namespace) -> TrackerConfig:
    overrides: dict[str, object] = {"camera": args.camera, "embedding_model": args.embedding_model,
                                    "time_step": args.time_step, "memory_path": args.memory}
    path = args.service_config
    section = None
    if path is not None:
        from common.config import read_config_file

        section = "tracker" if "tracker" in read_config_file(path) else None
    try:
        config = load_config(TrackerConfig, path, env_prefix="PERCEPTION_TRACKER", overrides=overrides, section=section)
    except ConfigError as exc:
        raise CliError(str(exc)) from exc
    if args.no_memory:
        config = config.model_copy(update={"memory_path": None})
    return config


def main(args: argparse.Namespace) -> int:
    config = config_from_args(args)
    keys = keys_from_args(args)
    try:
        opts = options_from_args(args)
    except ValidationError as exc:
        raise CliError(str(exc.errors(include_url=False)[0]["msg"])) from exc
    with Shutdown() as shutdown:
        try:
            transport = open_transport(opts)
        except TransportError as exc:
            raise CliError(str(exc)) from exc
        with transport:
            counters = Counters()
            try:
                service = TrackerService(transport, keys, config, counters)
            except ValueError as exc:
                raise CliError(f"cannot start the tracker: {exc}") from exc
            with ServiceRuntime("tracker", transport, keys, counters=counters) as runtime:
                runtime.watch(service.loc_sub, service.emb_sub, service.publisher)
                log.info("tracking camera %r in frame %r, memory %s", config.camera, config.frame_id,
                         config.memory_path or "off")
                service.run(shutdown)
    return 0
