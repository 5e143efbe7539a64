"""``perception detector``: run the detector node on one camera's frames."""

from __future__ import annotations

import argparse

from common.runtime.node import run_node
from services.detector import flags
from services.detector.config import DetectorConfig
from services.detector.service import DetectorService

DESCRIPTION = """\
Detect people in the frames of one camera and publish Detections.

Subscribes to frames/{camera} latest-only (a slow model never builds a queue; the
overwritten frames are counted as dropped_stale) and publishes detections/{camera}
with the source frame's header. Backends: hog (default, no model file), depth
(Basso/Munaro's depth clusters; needs registered depth), yolo-onnx (--model FILE.onnx)
and darknet (--darknet-cfg/--darknet-weights). Inference time and drops appear in
'perception status'.

Two detectors on one camera (as in the TU Ilmenau framework: a fast one on every frame,
a slow one a few times a second): run the second with --stream NAME; it publishes
detections/NAME, and a localizer with --camera CAMERA --stream NAME turns them into
localized/NAME for the tracker, which fuses both streams (deploy/two-detectors.yaml)."""

add_arguments = flags.add_arguments


def main(args: argparse.Namespace) -> int:
    return run_node(args, "detector", DetectorConfig, flags.node_overrides(args), DetectorService,
                    prepare=flags.prepare)
