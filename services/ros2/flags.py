"""The flags of ``perception ros2`` and the settings they override."""

from __future__ import annotations

import argparse
from typing import Any

from common.runtime.node import add_node_arguments
from services.ros2.config import Ros2Config

__all__ = ["add_arguments", "overrides"]


def add_arguments(parser: argparse.ArgumentParser) -> None:
    g = parser.add_argument_group("ROS 2")
    g.add_argument("--domain-id", dest="domain_id", type=int, default=None, metavar="N",
                   help="ROS_DOMAIN_ID of the robot")
    g.add_argument("--distro", choices=("jazzy", "kilted", "rolling"), default=None,
                   help="the robot's ROS 2 distribution (the three share every hash used here)")
    g.add_argument("--node-name", dest="node_name", default=None, help="name in the ROS 2 graph")
    g.add_argument("--camera", default=None, help="this project's camera name: frames/CAMERA")
    g.add_argument("--colour-topic", dest="colour_topic", default=None, metavar="TOPIC",
                   help="colour images")
    g.add_argument("--compressed", dest="colour_compressed", action="store_const", const=True, default=None,
                   help="the colour topic is a sensor_msgs/CompressedImage one (jpeg or png)")
    g.add_argument("--depth-topic", dest="depth_topic", default=None, metavar="TOPIC",
                   help="depth aligned to colour; '' for none")
    g.add_argument("--camera-info-topic", dest="camera_info_topic", default=None, metavar="TOPIC",
                   help="the colour camera's CameraInfo")
    g.add_argument("--no-camera", dest="camera_in", action="store_const", const=False, default=None,
                   help="do not read a ROS 2 camera (the frames come from elsewhere)")
    g.add_argument("--no-tf", dest="tf_in", action="store_const", const=False, default=None,
                   help="do not read /tf and /tf_static")
    g.add_argument("--map-topic", dest="map_topic", default=None, metavar="TOPIC",
                   help="the robot's map, nav_msgs/OccupancyGrid, passed to the tracker (default /map, Nav2's "
                        "map_server's and slam_toolbox's); '' for none")
    g.add_argument("--scan", dest="scans", action="append", default=None, metavar="TOPIC[:NAME]",
                   help="read sensor_msgs/LaserScan on TOPIC and publish it on scans/NAME (a bare TOPIC is laser "
                        "front); repeat for several lasers; replaces the default /scan:front")
    g.add_argument("--no-scan", dest="scans", action="store_const", const=[], default=None,
                   help="do not read a laser scan topic")
    g.add_argument("--no-people", dest="people_out", action="store_const", const=False, default=None,
                   help="do not publish the people as ROS 2 topics")
    add_node_arguments(parser, "ros2", Ros2Config)


def overrides(args: argparse.Namespace) -> dict[str, Any]:
    names = ("domain_id", "distro", "node_name", "camera", "colour_topic", "colour_compressed", "depth_topic",
             "camera_info_topic", "map_topic", "scans", "camera_in", "tf_in", "people_out")
    out = {n: getattr(args, n) for n in names}
    if args.depth_topic == "":
        out["require_depth"] = False
    return out
