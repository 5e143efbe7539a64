"""``perception ros2``: run the ROS 2 node."""

from __future__ import annotations

import argparse

from common.runtime.node import run_node
from services.ros2 import flags
from services.ros2.config import Ros2Config
from services.ros2.service import Ros2Service

DESCRIPTION = """\
Be a ROS 2 node on the robot's own Zenoh router, through rmw_zenoh's wire format (no ROS
install, no bridge): read a ROS 2 camera (sensor_msgs/Image or CompressedImage, depth aligned
to colour, CameraInfo; paired by stamp) into frames/{camera}, read /tf and /tf_static into
tf and tf_static, and publish the tracker's people in ROS4HRI's conventions:
/humans/bodies/tracked (hri_msgs/IdsList), /humans/bodies/<id>/position, velocity and
posture, a body_<id> frame per person on /tf, and /humans/markers for RViz. It shows in
`ros2 node list` and `ros2 topic list`. ROS 2 Jazzy (rmw_zenoh >= 0.2.4), Kilted and Rolling.
Settings come from defaults <- --service-config FILE (section 'ros2' if present) <-
PERCEPTION_ROS2__FIELD environment variables <- flags; services/ros2/README.md has them all."""

add_arguments = flags.add_arguments


def main(args: argparse.Namespace) -> int:
    return run_node(args, "ros2", Ros2Config, flags.overrides(args), Ros2Service)
