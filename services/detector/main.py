"""``perception detector``: run the detector service on one camera's frames."""

from __future__ import annotations

import argparse


from common.cli_util import add_key_arguments, keys_from_args
from common.runtime import Counters, ServiceRuntime, Shutdown
from common.zenoh_config import add_zenoh_arguments
from common.zenoh_transport import open_transport_from_args
from services.detector.cli_args import add_backend_arguments, detector_from_args, load_service_config
from services.detector.service import DetectorService

DESCRIPTION = """\
Detect people in the frames of one camera and publish Detections.

Subscribes to frames/{camera} latest-only (a slow model never builds a queue; the
overwritten frames are counted as dropped_stale) and publishes detections/{camera}
with the source frame's header. Backends: hog (default, no model file), depth
(seed 002's depth clusters; needs registered depth), yolo-onnx (--model FILE.onnx)
and darknet (--darknet-cfg/--darknet-weights). Inference time and drops appear in
'perception status'."""


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--camera", default=None, help="camera name in the keys (default 'head')")
    parser.add_argument("--no-depth", action="store_true", help="the camera publishes no depth (refuses backend depth)")
    add_backend_arguments(parser)
    add_key_arguments(parser)
    add_zenoh_arguments(parser)


def main(args: argparse.Namespace) -> int:
    extra = {"camera": args.camera, "depth_available": False if args.no_depth else None}
    config = load_service_config(args, extra)
    detector = detector_from_args(config)
    keys = keys_from_args(args)
    transport = open_transport_from_args(args)
    counters = Counters()
    with transport:
        service = DetectorService(transport, keys, config, counters, detector=detector)
        with ServiceRuntime("detector", transport, keys, counters=counters) as runtime, Shutdown() as shutdown:
            runtime.watch(service.frames, service.publisher)
            service.run(shutdown)
        service.close()
    return 0
