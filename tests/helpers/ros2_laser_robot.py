"""A ROS 2 robot with a camera and a base laser, made of a third party's rmw_zenoh implementation
(zenoh-ros2-sdk): the simulator's head camera, transforms and map as in
:mod:`tests.helpers.ros2_robot`, and ``/scan`` (``sensor_msgs/msg/LaserScan``, frame
``base_laser``; ``base_link -> base_laser`` on ``/tf_static``) as a laser driver would publish it.

The scene (:func:`world`): the robot stands in the living room facing east. Person 1 walks in
front of the head camera, then round to its left, out of the image but 2.4-2.7 m from the laser,
for about 7 s, and back into the image. Person 2 paces behind the robot, where only the laser
sees them. The scan shows the legs alone of the people the simulator's laser could see (two
circles 0.12 m wide, 0.2 m apart, swinging as they walk: the simulator's ``legs_of`` and ``cast``),
no walls or furniture and no noise, so that the legs are all the leg detector can find. The
people stay 1.9-2.7 m from the scanner: at its 0.25-degree steps the shipped leg model finds clean
legs there nearly every scan, and seldom closer than 1.5 m.

Its subscribers read the people back as ROS4HRI topics: ``/humans/bodies/tracked`` and each
body's ``/humans/bodies/<id>/position``.

    python -m tests.helpers.ros2_laser_robot --connect tcp/127.0.0.1:PORT --robot NAME --record FILE [--max] ...

``--record`` gets one JSON object: per frame the ground truth (who the camera counts, who the laser
sees, where), every ``tracked`` and ``position`` message received, with the frame its stamp is of,
and the people the laser node found (``localized/front``, read on this project's key, to show what
the laser gave the tracker). The ground truth also goes on this project's key, for scoring. At the
end it prints one JSON line: frames and scans sent, messages received.
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import threading
import time
from pathlib import Path
from typing import Any

import numpy as np

os.environ.setdefault("GIT_PYTHON_REFRESH", "quiet")


def _fields(msg: Any) -> dict[str, Any]:
    return {f: getattr(msg, f) for f in msg.__dataclass_fields__}


#: The robot's pose in the map (x, y, yaw): mid-way along the living room's south wall, facing east.
POSE = (2.6, 1.2, 0.0)


def world(name: str = "", seed: int = 0, alike: bool = False, apartment: Any = None) -> Any:
    """The scene, in place of a scenario's world (``build_world``'s signature; the name is unused).

    Person 1 starts 2.6 m ahead of the camera and walks in its view, then round to the robot's
    left (out of the image from about 2.6 s to 10.3 s, 2.4-2.7 m from the laser) and back in front
    of it; person 2 paces 1.9-2.5 m behind the robot, out of the camera's view. The head is level
    (as in the handover scenario): the partition 3.4 m ahead then shows taller than a person
    instead of as a person-sized slice to the depth detector."""
    from tools.simulator.core.apartment import default_apartment
    from tools.simulator.core.motion import Action, Walker
    from tools.simulator.core.robot import HeadMotion, Odometry, Robot, static_trajectory
    from tools.simulator.core.scenarios import World
    from tools.simulator.core.wardrobe import draw_outfits

    apt = apartment or default_apartment()
    outfits = draw_outfits(np.random.default_rng(seed), 2, 1, alike)
    tour = [(5.4, 1.8), (4.6, 2.8), (3.6, 3.6), (2.6, 3.7), (3.6, 3.6), (4.6, 2.8), (5.4, 0.8), (5.4, 1.8)]
    guest = Walker(apt, (5.4, 0.8), 2.0, 1.75, outfits[0], [Action("goto", p) for p in tour] +
                   [Action("wait", seconds=600.0)], np.random.default_rng(seed + 1), speed=0.7)
    pacer = Walker(apt, (0.75, 2.6), 0.0, 1.7, outfits[1], [Action("goto", (0.75, 1.9)), Action("goto", (0.75, 2.6))] *
                   20 + [Action("wait", seconds=600.0)], np.random.default_rng(seed + 2), speed=0.5)
    base = static_trajectory(*POSE)
    return World(apt, [guest, pacer], [1, 2], Robot(base, HeadMotion(tilt0=0.0), Odometry(base)), False, 60.0)


def legs_ranges(map_laser: np.ndarray, angles: np.ndarray, max_range: float, people: list[Any], t: float) -> np.ndarray:
    """The ranges (float32, inf: no return) a scanner at ``map_laser`` (4, 4) measures at time
    ``t`` along ``angles`` when nothing but the legs of ``people`` (``PersonGroundTruth``) is round it."""
    from tools.simulator.core.laser_scan import cast, legs_of

    xy = np.array([p.position[:2] for p in people], np.float64).reshape(-1, 2)
    vel = np.array([p.velocity[:2] for p in people], np.float64).reshape(-1, 2)
    heading = np.array([p.facing_rad if p.facing_rad is not None else float(np.arctan2(v[1], v[0]))
                        for p, v in zip(people, vel)])
    legs = legs_of(xy, heading, np.hypot(vel[:, 0], vel[:, 1]), t,
                   np.array([p.posture == "sitting" for p in people], bool))
    yaw = float(np.arctan2(map_laser[1, 0], map_laser[0, 0]))
    return cast(map_laser[:2, 3], yaw, angles, np.zeros((0, 4)), legs, max_range).astype(np.float32)


def main(argv: list[str]) -> int:
    ap = argparse.ArgumentParser()
    ap.add_argument("--connect", required=True)
    ap.add_argument("--robot", required=True)
    ap.add_argument("--record", required=True, type=Path)
    ap.add_argument("--domain-id", type=int, default=0)
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--duration", type=float, default=15.0)
    ap.add_argument("--fps", type=float, default=10.0)
    ap.add_argument("--width", type=int, default=320)
    ap.add_argument("--height", type=int, default=240)
    ap.add_argument("--max", action="store_true", help="each frame once the detector has answered the previous one")
    args = ap.parse_args(argv)

    import zenoh_ros2_sdk as sdk

    from common.messages.keys import RELIABLE, Keys
    from common.messages.schemas import (Detections, LaserScan, LocalizedDetections, PeopleGroundTruth, RGBDFrame,
                                         TransformBatch)
    from common.transport.zenoh import open_transport
    from common.transport.zenoh_config import ZenohOptions
    from services.ros2.config import Ros2Config
    from services.ros2.convert import camera_info_message, image_message, tf_message
    from services.ros2.core.types import types_of
    import tools.simulator.source as source
    from services.ros2.maps import occupancy_grid_message
    from tools.simulator.config import SimulatorConfig
    from tools.simulator.source import SimulatedStream
    from tools.simulator.static_map import apartment_static_map

    keys = Keys(robot=args.robot)
    types = types_of("jazzy")
    host, port = args.connect.removeprefix("tcp/").rsplit(":", 1)
    os.environ.setdefault("ZENOH_CONFIG_OVERRIDE", 'scouting/multicast/enabled=false;listen/endpoints=["tcp/127.0.0.1:0"]')
    topics = Ros2Config(domain_id=args.domain_id)
    ros = {"domain_id": args.domain_id, "router_ip": host, "router_port": int(port)}

    def pub(topic: str, type_name: str, node: str = "camera") -> Any:
        return sdk.ROS2Publisher(topic, type_name, msg_definition=types.definition(type_name),
                                 type_hash=types.hash(type_name), node_name=node, **ros)

    def sub(topic: str, type_name: str, callback: Any) -> Any:
        return sdk.ROS2Subscriber(topic, type_name, callback, msg_definition=types.definition(type_name),
                                  type_hash=types.hash(type_name), node_name="hri_consumer", **ros)

    info = pub(topics.camera_info_topic, "sensor_msgs/msg/CameraInfo")
    depth = pub(topics.depth_topic, "sensor_msgs/msg/Image")
    colour = pub(topics.colour_topic, "sensor_msgs/msg/Image")
    tf = pub(topics.tf_topic, "tf2_msgs/msg/TFMessage")
    tf_static = pub(topics.tf_static_topic, "tf2_msgs/msg/TFMessage")
    scan = pub("/scan", "sensor_msgs/msg/LaserScan", node="laser_driver")
    grid = pub(topics.map_topic, "nav_msgs/msg/OccupancyGrid", node="map_server")

    source.build_world = world  # this scene instead of the scenario's
    config = SimulatorConfig(scenario="still", seed=args.seed, fps=args.fps, width=args.width,
                             height=args.height, duration_s=args.duration, laser="front")
    stream = SimulatedStream(config, keys)

    def frame_of(stamp: Any) -> int:
        ns = int(stamp.sec) * 1_000_000_000 + int(stamp.nanosec)
        return round((ns - stream.start_ns) * args.fps / 1e9)

    lock = threading.Lock()
    tracked: list[tuple[int, list[str]]] = []
    positions: list[tuple[str, int, float, float]] = []

    def on_tracked(m: Any) -> None:
        with lock:
            tracked.append((frame_of(m.header.stamp), list(m.ids)))

    def on_position(body: str) -> Any:
        def got(m: Any) -> None:
            with lock:
                positions.append((body, frame_of(m.header.stamp), float(m.point.x), float(m.point.y)))
        return got

    subs = [sub("/humans/bodies/tracked", "hri_msgs/msg/IdsList", on_tracked)]
    followed: set[str] = set()

    transport = open_transport(ZenohOptions(mode="client", connect=[args.connect], connect_timeout_s=30.0))
    gt_pub = transport.publisher(keys.groundtruth(), PeopleGroundTruth, RELIABLE)
    detections = transport.subscribe(keys.detections("head"), Detections, RELIABLE)
    laser_people = transport.subscribe(keys.localized("front"), LocalizedDetections, RELIABLE)
    found: list[tuple[int, list[list[float]]]] = []
    truth: list[dict[str, Any]] = []
    total = stream.frame_count or 0
    t0 = time.monotonic()
    sent = scans = 0

    def follow_new_bodies() -> None:  # each body's position topic, once its id is on /humans/bodies/tracked
        with lock:
            new = {b for _, ids in tracked for b in ids} - followed
        for body in sorted(new):
            subs.append(sub(f"/humans/bodies/{body}/position", "geometry_msgs/msg/PointStamped", on_position(body)))
            followed.add(body)

    def read_laser_people() -> None:
        while (got := laser_people.try_recv()) is not None:
            found.append((round((got.msg.header.stamp_ns - stream.start_ns) * args.fps / 1e9),
                          [[float(d.position[0]), float(d.position[1])] for d in got.msg.detections]))

    for seq in range(total):
        if not args.max:
            delay = t0 + seq / args.fps - time.monotonic()
            if delay > 0:
                time.sleep(delay)
        fd, pairs = stream.messages(seq)
        gt = SimulatedStream.groundtruth_of(pairs)
        truth.append({"seq": seq, "people": [{"id": p.id, "x": float(p.position[0]), "y": float(p.position[1]),
                                              "camera": p.counted, "laser": bool(p.laser_seen)} for p in gt.people]})
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
            elif isinstance(msg, LaserScan) and fd.scan is not None:  # the legs alone, as a ROS 2 driver sends them
                spec = fd.scan.laser.spec
                seen = [p for p in gt.people if p.laser_seen]
                ranges = legs_ranges(fd.scan.map_laser, spec.angles(), spec.range_max, seen, seq / args.fps)
                scan.publish(**_fields(types.cls("sensor_msgs/msg/LaserScan")(
                    header=types.header(msg.header.stamp_ns, msg.header.frame_id), angle_min=msg.angle_min,
                    angle_max=msg.angle_max, angle_increment=msg.angle_increment, time_increment=msg.time_increment,
                    scan_time=msg.scan_time, range_min=msg.range_min, range_max=msg.range_max, ranges=ranges,
                    intensities=np.zeros(0, np.float32))))
                scans += 1
        follow_new_bodies()
        read_laser_people()
        if args.max:  # until the detector has answered this frame (1 s at most)
            deadline = time.monotonic() + 1.0
            while time.monotonic() < deadline:
                answer = detections.recv(timeout=0.05)
                if answer is not None and answer.msg.header.stamp_ns >= stamp:
                    break
    time.sleep(2.0)  # the last tracks on their way back
    read_laser_people()
    with lock:
        record = {"fps": args.fps, "truth": truth, "tracked": list(tracked), "positions": list(positions),
                  "laser_people": found}
    args.record.write_text(json.dumps(record))
    print(json.dumps({"frames_sent": sent, "scans_sent": scans, "tracked_messages": len(record["tracked"]),
                      "position_messages": len(record["positions"]), "bodies": sorted(followed)}), flush=True)
    for s in subs:
        s.close()
    transport.close()
    sdk.ZenohSession.get_instance(host, int(port)).session.close()
    return 0


if __name__ == "__main__":
    code = main(sys.argv[1:])
    sys.stdout.flush()
    # zenoh-ros2-sdk leaves threads of its own behind that keep the interpreter from exiting
    os._exit(code)
