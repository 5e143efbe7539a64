"""A ROS 2 robot made of a third party's rmw_zenoh implementation: the simulator's head camera,
transforms and map published by zenoh-ros2-sdk (as a RealSense ROS 2 driver, tf and Nav2's map
server would), and the people read back by its subscriber. The ground truth goes on this project's key, for scoring.

    python -m tests.helpers.ros2_robot --connect tcp/127.0.0.1:PORT --robot NAME [--max] ...

At the end it prints one JSON line: frames sent, and the ``/humans/bodies/tracked`` messages and
bodies its subscriber received.
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import time
from typing import Any

os.environ.setdefault("GIT_PYTHON_REFRESH", "quiet")


def _fields(msg: Any) -> dict[str, Any]:
    return {f: getattr(msg, f) for f in msg.__dataclass_fields__}


def main(argv: list[str]) -> int:
    ap = argparse.ArgumentParser()
    ap.add_argument("--connect", required=True)
    ap.add_argument("--robot", required=True)
    ap.add_argument("--domain-id", type=int, default=0)
    ap.add_argument("--scenario", default="still")
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--duration", type=float, default=20.0)
    ap.add_argument("--fps", type=float, default=10.0)
    ap.add_argument("--width", type=int, default=320)
    ap.add_argument("--height", type=int, default=240)
    ap.add_argument("--max", action="store_true", help="each frame once the detector has answered the previous one")
    args = ap.parse_args(argv)

    import zenoh_ros2_sdk as sdk

    from common.messages.keys import RELIABLE, Keys
    from common.messages.schemas import Detections, PeopleGroundTruth, RGBDFrame, TransformBatch
    from common.transport.zenoh_config import ZenohOptions
    from common.transport.zenoh import open_transport
    from services.ros2.config import Ros2Config
    from services.ros2.convert import camera_info_message, image_message, tf_message
    from services.ros2.core.types import types_of
    from services.ros2.maps import occupancy_grid_message
    from tools.simulator.static_map import apartment_static_map
    from tools.simulator.config import SimulatorConfig
    from tools.simulator.source import SimulatedStream

    keys = Keys(robot=args.robot)
    types = types_of("jazzy")
    host, port = args.connect.removeprefix("tcp/").rsplit(":", 1)
    os.environ.setdefault("ZENOH_CONFIG_OVERRIDE", 'scouting/multicast/enabled=false;listen/endpoints=["tcp/127.0.0.1:0"]')
    topics = Ros2Config(domain_id=args.domain_id)

    def pub(topic: str, type_name: str) -> Any:
        return sdk.ROS2Publisher(topic, type_name, msg_definition=types.definition(type_name),
                                 type_hash=types.hash(type_name), domain_id=args.domain_id, router_ip=host,
                                 router_port=int(port), node_name="camera")

    info = pub(topics.camera_info_topic, "sensor_msgs/msg/CameraInfo")
    depth = pub(topics.depth_topic, "sensor_msgs/msg/Image")
    colour = pub(topics.colour_topic, "sensor_msgs/msg/Image")
    tf = pub(topics.tf_topic, "tf2_msgs/msg/TFMessage")
    tf_static = pub(topics.tf_static_topic, "tf2_msgs/msg/TFMessage")
    grid = pub(topics.map_topic, "nav_msgs/msg/OccupancyGrid")  # the robot's map server
    tracked: list[Any] = []
    sdk.ROS2Subscriber("/humans/bodies/tracked", "hri_msgs/msg/IdsList", tracked.append,
                       msg_definition=types.definition("hri_msgs/msg/IdsList"), type_hash=types.hash("hri_msgs/msg/IdsList"),
                       domain_id=args.domain_id, router_ip=host, router_port=int(port), node_name="hri_consumer")

    config = SimulatorConfig(scenario=args.scenario, seed=args.seed, fps=args.fps, width=args.width, height=args.height,
                             duration_s=args.duration)
    transport = open_transport(ZenohOptions(mode="client", connect=[args.connect], connect_timeout_s=30.0))
    gt_pub = transport.publisher(keys.groundtruth(), PeopleGroundTruth, RELIABLE)
    detections = transport.subscribe(keys.detections("head"), Detections, RELIABLE)
    stream = SimulatedStream(config, keys)
    total = stream.frame_count or 0
    t0 = time.monotonic()
    sent = 0
    for seq in range(total):
        if not args.max:
            delay = t0 + seq / args.fps - time.monotonic()
            if delay > 0:
                time.sleep(delay)
        _, pairs = stream.messages(seq)
        stamp = 0
        if seq % 50 == 0:  # the map, now and then (map_server sends it once, transient local)
            grid.publish(**_fields(occupancy_grid_message(
                types, apartment_static_map(stream.stamp_ns(seq), stream.world.apartment))))
        for key, msg in pairs:
            if isinstance(msg, RGBDFrame):
                stamp = msg.header.stamp_ns
                info.publish(**_fields(camera_info_message(types, msg)))
                depth.publish(**_fields(image_message(types, msg, depth=True)))
                colour.publish(**_fields(image_message(types, msg)))
                sent += 1
            elif isinstance(msg, TransformBatch):
                (tf_static if key == keys.tf_static() else tf).publish(**_fields(tf_message(types, msg)))
            elif isinstance(msg, PeopleGroundTruth):
                gt_pub.put(msg)
        if args.max:  # until the detector has answered this frame (1 s at most)
            deadline = time.monotonic() + 1.0
            while time.monotonic() < deadline:
                got = detections.recv(timeout=0.05)
                if got is not None and got.msg.header.stamp_ns >= stamp:
                    break
    time.sleep(2.0)  # the last tracks on their way back
    bodies: dict[str, int] = {}
    for m in tracked:
        for b in m.ids:
            bodies[b] = bodies.get(b, 0) + 1
    print(json.dumps({"frames_sent": sent, "tracked_messages": len(tracked), "bodies": bodies}), flush=True)
    transport.close()
    sdk.ZenohSession.get_instance(host, int(port)).session.close()
    return 0


if __name__ == "__main__":
    code = main(sys.argv[1:])
    sys.stdout.flush()
    # zenoh-ros2-sdk leaves threads of its own behind that keep the interpreter from exiting
    os._exit(code)
