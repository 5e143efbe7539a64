"""perception doctor's ROS 2 checks on hand-made facts: the graph it sees, and the silent
failures named with their fix (a topic of another distribution's type hash, a compressed topic
read as raw, a missing publisher, images the node cannot read). The same live:
tests/integration/test_doctor_ros2_zenoh.py."""

from __future__ import annotations

from typing import Any


from services.ros2.core.types import types_of
from services.ros2.core.wire import GraphEntity, Qos, ros_to_dds
from tools.doctor.core.checks import run_checks
from tools.doctor.core.facts import NodeFacts, Observation

T = types_of()
COLOUR, DEPTH, INFO = ("/camera/camera/color/image_raw", "/camera/camera/aligned_depth_to_color/image_raw",
                       "/camera/camera/color/camera_info")
SETTINGS = {"node_name": "people_perception", "domain_id": "0", "distro": "jazzy", "camera_in": "true",
            "colour_topic": COLOUR, "depth_topic": DEPTH, "camera_info_topic": INFO, "tf_in": "true",
            "people_out": "true", "humans_namespace": "/humans", "colour_compressed": "false",
            "depth_compressed": "false"}


def _pub(zid: str, node: str, topic: str, type_name: str, type_hash: str | None = None, eid: int = 1) -> GraphEntity:
    return GraphEntity(domain_id=0, zid=zid, node_id=0, entity_id=eid, kind="MP", node_name=node, namespace="/camera",
                       topic=topic, dds_type=ros_to_dds(type_name), type_hash=type_hash or T.hash(type_name), qos=Qos())


def _obs(graph: list[GraphEntity], counters: dict[str, float] | None = None) -> Observation:
    me = GraphEntity(domain_id=0, zid="me", node_id=0, entity_id=0, kind="NN", node_name="people_perception")
    node = NodeFacts("ros2", "pc-1", settings=dict(SETTINGS), counters=counters or {}, window_s=5.0)
    return Observation(duration_s=5.0, nodes=[node], ros2_graph=[me, *graph])


def _ros2(obs: Observation) -> dict[str, Any]:
    return {c.name: c for c in run_checks(obs) if c.section == "ROS 2"}


def test_a_healthy_ros2_camera() -> None:
    graph = [_pub("cam", "camera", COLOUR, "sensor_msgs/msg/Image"), _pub("cam", "camera", DEPTH, "sensor_msgs/msg/Image", eid=2),
             _pub("cam", "camera", INFO, "sensor_msgs/msg/CameraInfo", eid=3),
             _pub("rsp", "robot_state_publisher", "/tf_static", "tf2_msgs/msg/TFMessage")]
    checks = _ros2(_obs(graph))
    assert all(c.status in ("ok", "warn") for c in checks.values()), checks
    assert checks[COLOUR].status == "ok" and "/camera/camera" in checks[COLOUR].figure
    assert "2 nodes" in checks["graph"].figure
    assert checks["/tf"].status == "warn"  # nobody publishes /tf: a warning, the camera may be fixed
    assert checks["/map"].status == "ok" and "no map" in checks["/map"].figure  # a map is welcome, not required
    with_map = _ros2(_obs([*graph, _pub("ms", "map_server", "/map", "nav_msgs/msg/OccupancyGrid")]))
    assert with_map["/map"].status == "ok" and "map_server" in with_map["/map"].figure


def test_another_distributions_hash_a_compressed_topic_and_a_missing_publisher_are_named() -> None:
    graph = [_pub("cam", "camera", COLOUR, "sensor_msgs/msg/Image", "TypeHashNotSupported"),
             _pub("cam", "camera", DEPTH, "sensor_msgs/msg/CompressedImage", eid=2),
             _pub("cam", "camera", "/camera/other/camera_info", "sensor_msgs/msg/CameraInfo", eid=3)]
    checks = _ros2(_obs(graph, {"invalid_unknown_encoding": 12.0}))
    assert checks[COLOUR].status == "fail" and "Humble" in checks[COLOUR].figure and "distro" in checks[COLOUR].fix
    assert checks[DEPTH].status == "fail" and "CompressedImage" in checks[DEPTH].figure
    assert "depth_compressed" in checks[DEPTH].fix or "colour_compressed" in checks[DEPTH].fix
    assert checks[INFO].status == "fail" and "/camera/other/camera_info" in checks[INFO].figure
    assert checks["ros2 unknown encoding"].status == "fail" and "rgb8" in checks["ros2 unknown encoding"].fix


def test_no_ros2_section_without_ros2() -> None:
    assert _ros2(Observation(duration_s=5.0)) == {}
