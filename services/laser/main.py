"""``perception laser``: run the laser leg detector on one scanner."""

from __future__ import annotations

import argparse

from common.runtime.node import run_node
from services.laser import flags
from services.laser.config import LaserConfig
from services.laser.service import LaserService

DESCRIPTION = """\
Find the people around the robot in a 2-D laser's scans: cut each scan into segments, tell the
legs from the rest by their shape (boosted trees trained on Leigh et al.'s labelled scans, the
model shipped in the package or --model), pair legs into people, and publish them in
--target-frame through the scanner's transform at each scan's stamp, at a prior height (a 2-D
scan does not measure it). The tracker fuses them like a camera's people, by position alone.

Subscribes to scans/{laser}, tf, tf_static and static_map, or reads --static-map (legs on its
walls and furniture are dropped before they are paired); publishes LocalizedDetections on
localized/{laser} (detector 'laser-legs', the scan as their view). The tracker never confirms a
person from legs alone: the camera confirms them, the laser keeps them all round the robot.

  perception laser --static-map map.yaml     # perception ros2 passes the robot's /scan on as scans/front
  perception demo --laser --scenario guided-tour --duration 48   # try it on the simulated apartment

A robot with a front and a rear scanner runs one node for each (--laser front, --laser rear). Settings come from
the defaults, then a --service-config YAML/JSON file (its 'laser' section, or the whole file),
then PERCEPTION_LASER__FIELD environment variables, then the flags below. See
services/laser/README.md."""

add_arguments = flags.add_arguments


def main(args: argparse.Namespace) -> int:
    return run_node(args, "laser", LaserConfig, flags.overrides(args), LaserService, prepare=flags.prepare)
