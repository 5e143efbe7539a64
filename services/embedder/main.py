"""``perception embedder``: run the embedder service on one camera."""

from __future__ import annotations

import argparse
import logging
from typing import Any


from common.cli_util import CliError, add_key_arguments, keys_from_args
from common.config import ConfigError, load_config
from common.runtime import Counters, ServiceRuntime, Shutdown
from common.zenoh_config import add_zenoh_arguments
from common.zenoh_transport import open_transport_from_args
from services.embedder.config import EmbedderConfig, build_backend
from services.embedder.core.backend import Backend, EmbedderError
from services.embedder.service import EmbedderService

log = logging.getLogger(__name__)

DESCRIPTION = """\
Describe the appearance of every detected person: pair each Detections message with
its RGB frame, crop the boxes and publish one descriptor per detection on
embeddings/{camera}, with a model card (name, dimension, metric, recommended tracker
thresholds).

Backends: 'colour' (default, no model: striped colour histograms, 128-D) and 'onnx'
(any Re-ID model: --model FILE.onnx; GPU via onnxruntime-gpu, providers TensorRT,
CUDA, CPU in that order unless --providers says otherwise).

Settings layer as defaults -> --service-config FILE (section 'embedder') ->
PERCEPTION_EMBEDDER__FIELD environment variables -> flags."""


def add_backend_arguments(parser: argparse.ArgumentParser) -> None:
    """Flags that pick and configure a backend (shared with the offline tools)."""
    g = parser.add_argument_group("backend")
    g.add_argument("--backend", choices=["colour", "onnx"], default=None, help="descriptor backend (default colour)")
    g.add_argument("--model", default=None, metavar="FILE.onnx", help="ONNX Re-ID model (backend onnx)")
    g.add_argument("--input-size", type=int, nargs=2, default=None, metavar=("H", "W"),
                   help="model input size (default 256 128, or the model's .json)")
    g.add_argument("--providers", default=None, metavar="P1,P2",
                   help="onnxruntime execution providers in order, e.g. CUDAExecutionProvider,CPUExecutionProvider")
    g.add_argument("--service-config", default=None, metavar="FILE", help="YAML/JSON settings (section 'embedder')")


def config_from_args(args: argparse.Namespace, extra: dict[str, Any] | None = None) -> EmbedderConfig:
    onnx: dict[str, Any] = {}
    if args.model:
        onnx["path"] = args.model
    if args.input_size:
        onnx["input_size"] = tuple(args.input_size)
    if args.providers:
        onnx["providers"] = [p.strip() for p in args.providers.split(",") if p.strip()]
    overrides: dict[str, Any] = {"backend": args.backend, **(extra or {})}
    if onnx:
        overrides["onnx"] = onnx
    try:
        return load_config(EmbedderConfig, args.service_config, env_prefix="PERCEPTION_EMBEDDER",
                           overrides=overrides, section="embedder")
    except ConfigError as exc:
        raise CliError(str(exc)) from exc


def backend_from_config(config: EmbedderConfig) -> Backend:
    try:
        return build_backend(config)
    except (EmbedderError, ConfigError) as exc:
        raise CliError(str(exc)) from exc


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--camera", default=None, help="camera name in the keys (default head)")
    add_backend_arguments(parser)
    add_key_arguments(parser)
    add_zenoh_arguments(parser)


def main(args: argparse.Namespace) -> int:
    config = config_from_args(args, {"camera": args.camera})
    keys = keys_from_args(args)
    backend = backend_from_config(config)
    card = backend.card
    log.info("backend %s: %d-D %s, thresholds %s", card.name, card.dim, card.metric, card.thresholds)
    if card.thresholds is None:
        log.warning("model %s has no recommended tracker thresholds; run 'perception calibrate-embedder' "
                    "and set embedder.thresholds", card.name)
    transport = open_transport_from_args(args)
    counters = Counters()
    with transport, Shutdown() as shutdown:
        service = EmbedderService(transport, keys, config, backend, counters)
        with ServiceRuntime("embedder", transport, keys, counters=counters) as runtime:
            runtime.watch(service.frames_sub, service.dets_sub, service.pub)
            service.run(shutdown)
    return 0
