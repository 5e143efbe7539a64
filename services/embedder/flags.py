"""The flags of ``perception embedder`` (the backend ones shared with ``embed`` and
``calibrate-embedder``), the settings they override, and the start-up checks."""

from __future__ import annotations

import argparse
import logging
from typing import Any

from common.runtime.cli_util import CliError
from common.runtime.config import ConfigError
from common.runtime.node import add_node_arguments, load_node_config
from common.runtime.settings import flag_help
from services.embedder.config import EmbedderConfig, build_backend
from services.embedder.core.backend import Backend, EmbedderError
from services.embedder.core.orientation import OrientationClassifier

__all__ = ["add_arguments", "add_backend_arguments", "backend_from_config", "config_from_args", "overrides", "prepare"]

log = logging.getLogger(__name__)


def add_backend_arguments(parser: argparse.ArgumentParser, *, service_config: bool = True) -> None:
    """Flags that pick and configure a backend (shared with the offline tools)."""
    g = parser.add_argument_group("backend")
    g.add_argument("--backend", choices=["colour", "onnx"], default=None, help="descriptor backend")
    g.add_argument("--model", default=None, metavar="FILE.onnx", help=flag_help(EmbedderConfig, "onnx.path", "ONNX Re-ID model (backend onnx)"))
    g.add_argument("--input-size", type=int, nargs=2, default=None, metavar=("H", "W"),
                   help=flag_help(EmbedderConfig, "onnx.input_size", "model input size (else the model's .json)"))
    g.add_argument("--providers", default=None, metavar="P1,P2",
                   help=flag_help(EmbedderConfig, "onnx.providers", "onnxruntime execution providers in order, e.g. "
                                  "CUDAExecutionProvider,CPUExecutionProvider"))
    if service_config:
        g.add_argument("--service-config", default=None, metavar="FILE",
                       help="YAML/JSON settings; its 'embedder' section if it has one, else the whole file")


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Every flag of ``perception embedder``."""
    parser.add_argument("--camera", default=None, help="camera name in the keys")
    parser.add_argument("--orientation-model", default=None, metavar="FILE.onnx",
                        help=flag_help(EmbedderConfig, "orientation.path", "optional upper-body orientation classifier on each "
                                       "crop ((N, 3, H, W) -> (N, 8))"))
    add_backend_arguments(parser, service_config=False)
    add_node_arguments(parser, "embedder", EmbedderConfig)


def overrides(args: argparse.Namespace, extra: dict[str, Any] | None = None) -> dict[str, Any]:
    """The settings the flags set (None: not set)."""
    onnx: dict[str, Any] = {}
    if args.model:
        onnx["path"] = args.model
    if args.input_size:
        onnx["input_size"] = tuple(args.input_size)
    if args.providers:
        onnx["providers"] = [p.strip() for p in args.providers.split(",") if p.strip()]
    out: dict[str, Any] = {"backend": args.backend, "camera": getattr(args, "camera", None), **(extra or {})}
    if onnx:
        out["onnx"] = onnx
    if getattr(args, "orientation_model", None):
        out["orientation"] = {"path": args.orientation_model}
    return out


def config_from_args(args: argparse.Namespace, extra: dict[str, Any] | None = None) -> EmbedderConfig:
    return load_node_config(EmbedderConfig, "embedder", args.service_config, overrides(args, extra))


def backend_from_config(config: EmbedderConfig) -> Backend:
    try:
        return build_backend(config)
    except (EmbedderError, ConfigError) as exc:
        raise CliError(str(exc)) from exc


def prepare(config: EmbedderConfig) -> dict[str, Any]:
    """Load the models before the transport opens, so a missing file stops the node at once."""
    backend = backend_from_config(config)
    params = config.orientation.params()
    orientation = None
    if params is not None:
        try:
            orientation = OrientationClassifier(params)
        except EmbedderError as exc:
            raise CliError(f"orientation model: {exc}") from exc
    card = backend.card
    log.info("backend %s: %d-D %s, thresholds %s", card.name, card.dim, card.metric, card.thresholds)
    if card.thresholds is None:
        log.warning("model %s has no recommended tracker thresholds; run 'perception calibrate-embedder' "
                    "and set embedder.thresholds", card.name)
    return {"backend": backend, "orientation": orientation}
