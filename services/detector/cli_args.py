"""Flags shared by ``perception detector`` and ``perception detect``, and config loading from them."""

from __future__ import annotations

import argparse
from typing import Any

from common.cli_util import CliError
from common.config import ConfigError, load_config
from services.detector.config import BACKENDS, DetectorConfig, build_detector
from services.detector.core import Detector
from services.detector.core.boxes import DetectorError

__all__ = ["add_backend_arguments", "detector_from_args", "load_service_config"]

ENV_PREFIX = "PERCEPTION_DETECTOR"


def add_backend_arguments(parser: argparse.ArgumentParser) -> None:
    g = parser.add_argument_group("detector")
    g.add_argument("--service-config", dest="service_config", default=None, metavar="FILE",
                   help="YAML/JSON config; its 'detector' section is read if present (env PERCEPTION_DETECTOR__FIELD overrides)")
    g.add_argument("--backend", choices=BACKENDS, default=None, help="detector backend (default hog)")
    g.add_argument("--model", default=None, metavar="ONNX", help="yolo-onnx: path of the .onnx model (yolo.model)")
    g.add_argument("--providers", default=None, metavar="P1,P2",
                   help="yolo-onnx: onnxruntime providers in order, e.g. CUDAExecutionProvider,CPUExecutionProvider")
    g.add_argument("--darknet-cfg", default=None, metavar="CFG", help="darknet: the .cfg file")
    g.add_argument("--darknet-weights", default=None, metavar="WEIGHTS", help="darknet: the .weights file")
    g.add_argument("--upsample", type=float, default=None, help="hog: image scale before detection (2-2.5 for ~50 px people)")
    g.add_argument("--conf", type=float, default=None, help="yolo-onnx/darknet: confidence threshold")


def _prune(tree: dict[str, Any]) -> dict[str, Any]:
    """``tree`` without None leaves and empty sub-mappings (unset flags override nothing)."""
    out: dict[str, Any] = {}
    for k, v in tree.items():
        if isinstance(v, dict):
            v = _prune(v)
            if v:
                out[k] = v
        elif v is not None:
            out[k] = v
    return out


def load_service_config(args: argparse.Namespace, extra: dict[str, Any] | None = None) -> DetectorConfig:
    """Defaults -> --config file (section ``detector``) -> environment -> flags; CliError if invalid."""
    providers = [p.strip() for p in args.providers.split(",") if p.strip()] if args.providers else None
    overrides = _prune({
        **(extra or {}),
        "backend": args.backend,
        "hog": {"upsample": args.upsample},
        "yolo": {"model": args.model, "providers": providers, "conf_threshold": args.conf},
        "darknet": {"cfg": args.darknet_cfg, "weights": args.darknet_weights, "conf_threshold": args.conf},
    })
    section = None
    if args.service_config is not None:
        from common.config import read_config_file

        try:
            section = "detector" if "detector" in read_config_file(args.service_config) else None
        except ConfigError as exc:
            raise CliError(str(exc)) from exc
    try:
        return load_config(DetectorConfig, args.service_config, env_prefix=ENV_PREFIX, overrides=overrides, section=section)
    except ConfigError as exc:
        raise CliError(f"{exc}\n(fix it in {args.service_config or 'the flags'} or the PERCEPTION_DETECTOR__* environment)") from exc


def detector_from_args(config: DetectorConfig) -> Detector:
    """Build the configured detector; a missing or broken model becomes a CliError."""
    try:
        return build_detector(config)
    except DetectorError as exc:
        raise CliError(str(exc)) from exc
