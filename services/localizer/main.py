"""``perception localizer``: run the localizer node on one camera."""

from __future__ import annotations

import argparse

from common.runtime.node import run_node
from services.localizer import flags
from services.localizer.config import LocalizerConfig
from services.localizer.service import LocalizerService

DESCRIPTION = """\
Place each detected person in the map frame: for every box of a Detections message,
take the 25th percentile of the valid depth pixels inside the box of the matching
depth frame, cast the ray through the box centre to that depth, and transform the
point (with its covariance) to --target-frame at the frame's time. A frame without a
depth image (an RGB-only camera) puts each person on the floor instead, from the box's
foot point: through the camera's pose in --target-frame, or through --floor-homography.

Subscribes to frames/{camera}, detections/{camera}, tf and tf_static; publishes
LocalizedDetections on localized/{camera}. With --stream NAME (a second detector on the
same camera) it reads detections/NAME and publishes localized/NAME, source NAME. Settings come from the defaults, then a
--service-config YAML/JSON file (its 'localizer' section, or the whole file), then
PERCEPTION_LOCALIZER__FIELD environment variables, then the flags below. See
services/localizer/README.md for every setting and the transforms it needs."""

add_arguments = flags.add_arguments


def main(args: argparse.Namespace) -> int:
    return run_node(args, "localizer", LocalizerConfig, flags.overrides(args), LocalizerService, prepare=flags.prepare)
