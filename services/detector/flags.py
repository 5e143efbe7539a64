"""Flags shared by ``perception detector`` and ``perception detect``, and config loading from them."""

from __future__ import annotations

import argparse
from typing import Any

from common.runtime.cli_util import CliError
from common.runtime.node import add_node_arguments, load_node_config
from common.runtime.settings import flag_help
from services.detector.config import BACKENDS, DetectorConfig, build_detector
from services.detector.core import Detector
from services.detector.core.boxes import DetectorError
from services.detector.memory import keep_freed_memory

__all__ = ["add_arguments", "add_backend_arguments", "detector_from_args", "load_service_config", "node_overrides",
           "overrides", "prepare"]


def add_backend_arguments(parser: argparse.ArgumentParser) -> None:
    """The backend flags (``perception detector`` and ``perception detect``)."""
    g = parser.add_argument_group("detector")
    g.add_argument("--backend", choices=BACKENDS, default=None, help=flag_help(DetectorConfig, "backend"))
    g.add_argument("--model", default=None, metavar="ONNX", help=flag_help(DetectorConfig, "yolo.model", "yolo-onnx: path of the .onnx model"))
    g.add_argument("--providers", default=None, metavar="P1,P2",
                   help=flag_help(DetectorConfig, "yolo.providers", "yolo-onnx: onnxruntime providers in order, "
                                  "comma-separated, e.g. CUDAExecutionProvider,CPUExecutionProvider"))
    g.add_argument("--darknet-cfg", default=None, metavar="CFG", help=flag_help(DetectorConfig, "darknet.cfg", "darknet: the .cfg file"))
    g.add_argument("--darknet-weights", default=None, metavar="WEIGHTS",
                   help=flag_help(DetectorConfig, "darknet.weights", "darknet: the .weights file"))
    g.add_argument("--upsample", type=float, default=None,
                   help=flag_help(DetectorConfig, "hog.upsample", "hog: image scale before detection, about 1.1 x 96 "
                                  "/ the smallest person's height in px: 2.25 for ~50 px people (PETS-like "
                                  "480x360), 1.0 when everyone is taller than ~105 px (a 640x480 RGB-D camera, "
                                  "people within ~8 m); cost grows with its square"))
    g.add_argument("--conf", type=float, default=None, metavar="P",
                   help=flag_help(DetectorConfig, "yolo.conf_threshold", "yolo-onnx/darknet: confidence threshold "
                                  "(sets darknet.conf_threshold too)"))


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Every flag of ``perception detector``."""
    parser.add_argument("--camera", default=None, help=flag_help(DetectorConfig, "camera"))
    parser.add_argument("--stream", default=None, metavar="NAME",
                        help=flag_help(DetectorConfig, "stream", "publish detections/NAME instead of "
                                       "detections/{camera}: a second detector on the same camera (e.g. a slow hog "
                                       "or yolo-onnx next to depth; its localizer takes --stream NAME too)"))
    parser.add_argument("--max-rate", type=float, default=None, metavar="HZ",
                        help=flag_help(DetectorConfig, "max_rate_hz", "process at most HZ frames per second of "
                                       "sensor time, skipping the others (a slow second detector: e.g. --max-rate 3)"))
    parser.add_argument("--no-depth", action="store_true",
                        help=flag_help(DetectorConfig, "depth_available", "the camera publishes no depth (refuses "
                                       "backend depth); sets it false"))
    parser.add_argument("--floor-frame", default=None, metavar="FRAME", help=flag_help(DetectorConfig, "floor_frame"))
    add_backend_arguments(parser)
    add_node_arguments(parser, "detector", DetectorConfig)


def node_overrides(args: argparse.Namespace) -> dict[str, Any]:
    """The node's settings from its flags."""
    return overrides(args, {"camera": args.camera, "stream": args.stream, "max_rate_hz": args.max_rate,
                            "depth_available": False if args.no_depth else None, "floor_frame": args.floor_frame})


def prepare(config: DetectorConfig) -> dict[str, Any]:
    """Build the detector before the transport opens, so a missing model stops the node at once;
    the process keeps the memory a frame frees for the next (:func:`keep_freed_memory`)."""
    keep_freed_memory()
    return {"detector": detector_from_args(config)}


def overrides(args: argparse.Namespace, extra: dict[str, Any] | None = None) -> dict[str, Any]:
    """The settings the flags set (None: not set, left to the file or the defaults)."""
    providers = [p.strip() for p in args.providers.split(",") if p.strip()] if args.providers else None
    return {
        **(extra or {}),
        "backend": args.backend,
        "hog": {"upsample": args.upsample},
        "yolo": {"model": args.model, "providers": providers, "conf_threshold": args.conf},
        "darknet": {"cfg": args.darknet_cfg, "weights": args.darknet_weights, "conf_threshold": args.conf},
    }


def load_service_config(args: argparse.Namespace, extra: dict[str, Any] | None = None) -> DetectorConfig:
    """Defaults -> --service-config file (section ``detector``) -> environment -> flags; CliError if invalid."""
    return load_node_config(DetectorConfig, "detector", args.service_config, overrides(args, extra))


def detector_from_args(config: DetectorConfig) -> Detector:
    """Build the configured detector; a missing or broken model becomes a CliError."""
    try:
        return build_detector(config)
    except DetectorError as exc:
        raise CliError(str(exc)) from exc
