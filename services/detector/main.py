"""``perception detector``: run the detector node on one camera's frames."""

from __future__ import annotations

import argparse
import ctypes

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

_M_TRIM_THRESHOLD, _M_MMAP_THRESHOLD = -1, -3  # glibc's mallopt parameters


def keep_freed_memory() -> bool:
    """Let glibc's malloc keep the memory a frame frees for the next frame, instead of handing it
    back to the kernel and faulting it in again.

    A detector allocates and frees several MB of temporaries per frame (the depth backend's
    images, points and cell tables). With glibc's defaults, blocks above its adaptive mmap
    threshold and a heap top past its trim threshold go back to the kernel: on the 2-vCPU VM the
    depth backend then took 300 to 1,100 page faults a frame, 0.5-3 ms of a 10 ms frame at
    640x480, none with these settings (mmap only from 32 MiB, trim from 256 MiB). Returns whether
    they applied (glibc only; elsewhere nothing changes)."""
    try:
        mallopt = ctypes.CDLL(None).mallopt
    except (OSError, AttributeError):
        return False
    return bool(mallopt(_M_MMAP_THRESHOLD, 32 << 20)) and bool(mallopt(_M_TRIM_THRESHOLD, 256 << 20))


def main(args: argparse.Namespace) -> int:
    keep_freed_memory()
    return run_node(args, "detector", DetectorConfig, flags.node_overrides(args), DetectorService,
                    prepare=flags.prepare)
