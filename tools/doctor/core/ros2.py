"""ROS 2: what the doctor sees of the ROS 2 graph on the router (rmw_zenoh's liveliness tokens),
and the silent failures between a ROS 2 robot and the ``ros2`` node.

rmw_zenoh subscribes to the exact key of a topic, type hash included: a camera of another ROS 2
distribution, or a compressed topic read as raw, is never delivered and never an error. The
publishers' tokens name each topic's type and hash, so the doctor can say which it is; what the
node did receive and could not read (an image encoding, a step that does not match the width)
comes from its counters.
"""

from __future__ import annotations

from dataclasses import dataclass

from services.ros2.core.types import known_hashes
from services.ros2.core.wire import GraphEntity
from tools.doctor.core.facts import Check, NodeFacts, Observation
from tools.doctor.core.laser import ros2_scan_topics

__all__ = ["SECTION", "input_topics", "ros2_checks"]

SECTION = "ROS 2"
#: The ros2 node's counters of unreadable ROS input, and what to do about each.
_INPUT_FIXES = {
    "invalid_unknown_encoding": "publish rgb8, bgr8 or mono8 colour and 16UC1 (mm) or 32FC1 (m) depth, or jpeg/png "
                                "on a CompressedImage topic (set colour_compressed)",
    "invalid_not_depth": "the depth topic carries colour: point depth_topic at the depth aligned to colour",
    "invalid_not_colour": "the colour topic carries depth: point colour_topic at the colour image",
    "invalid_bad_step": "the driver's step does not match width x bytes per pixel: check its encoding setting",
    "invalid_bad_size": "the images' data does not match height x step: the driver sends truncated images",
    "invalid_size": "colour, depth and camera info differ in size: read the depth aligned to colour "
                    "(aligned_depth_to_color) and the colour camera's camera_info",
    "invalid_corrupt": "the compressed images do not decode: check the driver's image_transport",
    "invalid_bad_camera_info": "the camera info has no focal length: calibrate the camera, or publish its intrinsics",
    "invalid_cdr": "payloads are not CDR of the expected type: the publisher is not an rmw_zenoh of a supported "
                   "distribution",
    "invalid_attachment": "samples without rmw_zenoh's attachment: the robot runs rmw_zenoh before Jazzy 0.2.4, or "
                          "zenoh-bridge-ros2dds; use rmw_zenoh >= 0.2.4 (Jazzy), Kilted or Rolling",
    "invalid_type_hash": "the robot's ROS 2 distribution is not the node's: set distro (jazzy, kilted, rolling); Humble "
                         "is not supported",
    "invalid_wrong_type": "a topic carries another type than the node reads there: see the topic lines",
    "invalid_scan_length": "the laser's ranges do not fit its angle_min, angle_max and angle_increment: check the "
                           "driver's angle settings (a cropped scan must crop both)",
    "invalid_scan_increment": "the laser's scans have angle_increment 0: the driver does not fill in its geometry",
    "invalid_scan_not_finite": "the laser's scans carry NaN or inf in their angles, increments or range limits (NaN "
                               "and inf ranges are fine): check the driver",
    "invalid_scan_range_limits": "the laser's range_min is not below its range_max: check the driver's range settings",
    "invalid_scan_intensities": "the laser sends intensities but not one per range: turn its intensities off or fix "
                                "the driver",
    "invalid_scan_empty": "the laser's scans have no ranges: the scanner is not measuring (see its driver's log)",
    "invalid_scan": "the laser's scans are refused (see the ros2 node's log, which names the field)",
}


@dataclass(frozen=True)
class _Input:
    setting: str
    topic: str
    type_name: str
    required: bool = True
    #: without a publisher the node still works, and nothing is wrong: said, not warned about
    optional: str = ""


def input_topics(node: NodeFacts, lasers_read: frozenset[str] = frozenset()) -> list[_Input]:
    """The ROS topics a ``ros2`` node reads, from its status's settings; ``lasers_read``: the
    lasers a laser node reads (their topic without a publisher warns)."""
    s = node.settings
    out = []
    if s.get("camera_in", "true") == "true":
        colour = "sensor_msgs/msg/CompressedImage" if s.get("colour_compressed") == "true" else "sensor_msgs/msg/Image"
        out.append(_Input("colour_topic", s.get("colour_topic", ""), colour))
        if s.get("depth_topic"):
            depth = "sensor_msgs/msg/CompressedImage" if s.get("depth_compressed") == "true" else "sensor_msgs/msg/Image"
            out.append(_Input("depth_topic", s["depth_topic"], depth))
        out.append(_Input("camera_info_topic", s.get("camera_info_topic", ""), "sensor_msgs/msg/CameraInfo"))
    if s.get("tf_in", "true") == "true":
        out.append(_Input("tf_topic", s.get("tf_topic", "/tf"), "tf2_msgs/msg/TFMessage", required=False))
        out.append(_Input("tf_static_topic", s.get("tf_static_topic", "/tf_static"), "tf2_msgs/msg/TFMessage",
                          required=False))
    out.append(_Input("map_topic", s.get("map_topic", "/map"), "nav_msgs/msg/OccupancyGrid", required=False,
                      optional="no map: the tracker runs without one unless given a file (a door jamb seen as a "
                               "person may start a track); Nav2's map_server or slam_toolbox publish it"))
    for laser, topic in ros2_scan_topics(node).items():
        out.append(_Input(f"scans (TOPIC:NAME, here {topic}:{laser})", topic, "sensor_msgs/msg/LaserScan",
                          required=False, optional="" if laser in
                          lasers_read else f"no laser: scans/{laser} stays empty (no perception laser reads it)"))
    return [i for i in out if i.topic]


def _name(e: GraphEntity) -> str:
    ns = e.namespace.rstrip("/")
    return f"{ns}/{e.node_name}"


def _topic_check(inp: _Input, graph: list[GraphEntity], mine: set[str], distro: str) -> Check:
    pubs = [e for e in graph if e.kind == "MP" and e.topic == inp.topic and e.zid not in mine]
    name = f"{inp.topic}"
    if not pubs:
        similar = sorted({e.topic for e in graph if e.kind == "MP" and e.zid not in mine
                          and e.topic.rsplit("/", 1)[-1] == inp.topic.rsplit("/", 1)[-1]})
        hint = f"; topics of that name here: {', '.join(similar[:4])}" if similar else ""
        if inp.optional:
            return Check(SECTION, name, "ok", inp.optional)
        status = "fail" if inp.required else "warn"
        return Check(SECTION, name, status, f"no publisher in the ROS 2 graph{hint}",
                     f"start the robot's driver, or set {inp.setting} to the topic it publishes (ros2 topic list -t)")
    wrong_type = [e for e in pubs if e.type_name != inp.type_name]
    if wrong_type:
        got = wrong_type[0].type_name
        fix = ("set colour_compressed (or depth_compressed), or read the raw topic" if got.endswith("CompressedImage")
               else "this topic is raw: turn colour_compressed (depth_compressed) off" if got.endswith("/Image")
               else f"set {inp.setting} to a topic of type {inp.type_name}")
        return Check(SECTION, name, "fail", f"published as {got} by {_name(wrong_type[0])}; the node reads "
                                            f"{inp.type_name} there: nothing is delivered", fix)
    expected = known_hashes(inp.type_name)
    ours = next((h for h, d in expected.items() if distro in d.split(", ")), "")
    other = [e for e in pubs if e.type_hash != ours]
    if other:
        e = other[0]
        origin = (f"{expected[e.type_hash]}'s" if e.type_hash in expected
                  else "Humble's (no hash)" if "TypeHashNotSupported" in e.type_hash else "an unknown")
        return Check(SECTION, name, "fail",
                     f"{_name(e)} publishes {inp.type_name} with {origin} type hash {e.type_hash[:18]}...; the node "
                     f"expects {distro}'s {ours[:18]}...: nothing is delivered",
                     "set the ros2 node's distro to the robot's ROS 2 distribution (jazzy, kilted, rolling); "
                     "Humble's rmw_zenoh writes no hash and cannot be read")
    who = ", ".join(sorted({_name(e) for e in pubs}))
    return Check(SECTION, name, "ok", f"{inp.type_name} from {who}")


def ros2_checks(obs: Observation) -> list[Check]:
    """The ROS 2 section: shown when a ros2 node runs or the router carries a ROS 2 graph."""
    nodes = obs.running("ros2")
    graph = obs.ros2_graph
    if not nodes and not graph:
        return []
    out: list[Check] = []
    mine: set[str] = set()
    names = {n.settings.get("node_name", "people_perception") for n in nodes}
    mine = {e.zid for e in graph if e.kind == "NN" and e.node_name in names}
    others = [e for e in graph if e.zid not in mine]
    ros_nodes = sorted({_name(e) for e in others})
    topics = sorted({e.topic for e in others if e.topic})
    domain = nodes[0].settings.get("domain_id", "0") if nodes else str(obs.ros2_domain)
    if not others:
        out.append(Check(SECTION, "graph", "warn" if nodes else "ok",
                         f"no ROS 2 node but this project's on domain {domain}",
                         "start the robot's nodes with RMW_IMPLEMENTATION=rmw_zenoh_cpp, connected to this router, "
                         "and the same ROS_DOMAIN_ID" if nodes else ""))
    else:
        shown = ", ".join(ros_nodes[:6]) + (f" and {len(ros_nodes) - 6} more" if len(ros_nodes) > 6 else "")
        out.append(Check(SECTION, "graph", "ok", f"domain {domain}: {len(ros_nodes)} nodes ({shown}), {len(topics)} topics"))
    for node in nodes:
        distro = node.settings.get("distro", "jazzy")
        lasers = frozenset(n.settings.get("laser", "front") for n in obs.running("laser"))
        for inp in input_topics(node, lasers):
            out.append(_topic_check(inp, graph, mine, distro))
        for counter, fix in _INPUT_FIXES.items():
            n = node.counters.get(counter, 0)
            if n > 0:
                out.append(Check(SECTION, f"ros2 {counter.removeprefix('invalid_').replace('_', ' ')}", "fail",
                                 f"{n:g} ROS 2 samples unreadable" + (" (since it started)" if node.window_s == 0 else ""),
                                 fix))
        for reason, n in node.drops().items():
            out.append(Check(SECTION, f"ros2 {reason.replace('_', ' ')}", "warn",
                             f"{n:g} colour images dropped", "publish depth aligned to colour with the colour image's "
                             "stamps (or set require_depth: false for an RGB-only camera)"
                             if "depth" in reason else "see the ros2 node's log"))
        if node.settings.get("people_out", "true") == "true":
            readers = sorted({_name(e) for e in others if e.kind == "MS" and e.topic.startswith(
                node.settings.get("humans_namespace", "/humans"))})
            out.append(Check(SECTION, "people out", "ok",
                             f"{node.settings.get('humans_namespace', '/humans')}/bodies/..., /tf, markers; read by "
                             + (", ".join(readers) if readers else "no ROS 2 node yet (ros2 topic echo "
                                                                  "/humans/bodies/tracked)")))
    return out
