"""perception ros2 as a real process on a real router, against a third party's implementation
of rmw_zenoh's protocol on the other side: PyPI's zenoh-ros2-sdk publishes a ROS 2 RGB-D camera
and /tf, and subscribes to the people; its graph discovery lists this node's topics. The
transient-local late joiner is tested against zenoh-ext's advanced publisher, the one rmw_zenoh
itself uses for /tf_static.
"""

from __future__ import annotations

import subprocess
import time
from typing import Any

import numpy as np
import pytest

from common.messages.keys import FRAMES, RELIABLE
from common.messages.schemas import Header, RGBDFrame, StaticMap, Tracks, TrackState, Transform, TransformBatch
from services.ros2.convert import camera_info_message, image_message, tf_message
from services.ros2.core.wire import attachment
from tests.helpers.ros2_sdk import DOMAIN, KEYS, T, sdk
from tests.helpers.ros2_sdk import fields as _fields
from tests.helpers.ros2_sdk import ros2_node as _node
from tests.helpers.ros2_sdk import ros2_publisher as _pub
from tests.helpers.ros2_sdk import stop as _stop
from tests.helpers.ros2_sdk import wait_alive as _wait_alive

pytestmark = [pytest.mark.zenoh, pytest.mark.slow]
COLOUR, DEPTH, INFO = ("/camera/camera/color/image_raw", "/camera/camera/aligned_depth_to_color/image_raw",
                       "/camera/camera/color/camera_info")


def _frame(k: int) -> RGBDFrame:
    from common.messages.samples import rgbd_frame

    return rgbd_frame(64, 48, stamp_ns=1_700_000_000_000_000_000 + k * 50_000_000)


def test_a_third_party_ros2_camera_in_and_the_people_out(router: Any, zenoh_client: Any, sdk_session: Any) -> None:
    app = zenoh_client()
    frames = app.subscribe(KEYS.frames("head"), RGBDFrame, FRAMES.__class__(latest=False, queue=64, congestion="drop"))
    tf = app.subscribe(KEYS.tf(), TransformBatch, RELIABLE)
    tracks = app.publisher(KEYS.tracks(), Tracks, RELIABLE)
    node = _node(router)
    try:
        _wait_alive(app, node)
        info, colour, depth = (_pub(sdk_session, INFO, "sensor_msgs/msg/CameraInfo"),
                               _pub(sdk_session, COLOUR, "sensor_msgs/msg/Image"),
                               _pub(sdk_session, DEPTH, "sensor_msgs/msg/Image"))
        tf_pub = _pub(sdk_session, "/tf", "tf2_msgs/msg/TFMessage")
        got: list[RGBDFrame] = []
        sent: list[RGBDFrame] = []
        deadline = time.monotonic() + 30
        k = 0
        while len(got) < 3 and time.monotonic() < deadline:
            f = _frame(k)
            k += 1
            sent.append(f)
            info.publish(**_fields(camera_info_message(T, f)))
            depth.publish(**_fields(image_message(T, f, depth=True)))
            colour.publish(**_fields(image_message(T, f)))
            stamp = f.header.stamp_ns
            tf_pub.publish(**_fields(tf_message(T, TransformBatch(header=Header(stamp_ns=stamp), transforms=[
                Transform(parent_frame="map", child_frame="base_link", stamp_ns=stamp, translation=np.array([1.0, 2.0, 0]),
                          rotation_xyzw=np.array([0, 0, 0, 1.0]))]))))
            time.sleep(0.1)  # the camera's frame period
            while (g := frames.try_recv()) is not None:
                got.append(g.msg)
        assert len(got) >= 3, "no frames/head from the ROS 2 camera"
        by_stamp = {f.header.stamp_ns: f for f in sent}
        for g in got:
            s = by_stamp[g.header.stamp_ns]
            assert np.array_equal(g.rgb.to_array(), s.rgb.to_array())
            assert np.array_equal(g.depth.to_array(), s.depth.to_array())
        tfs = []
        end = time.monotonic() + 10
        while not tfs and time.monotonic() < end:
            if (m := tf.recv(timeout=0.2)) is not None:
                tfs.append(m.msg)
        assert tfs and tfs[0].transforms[0].child_frame == "base_link"

        # the people, read by the third party's subscribers
        _, host, port = sdk_session
        seen: dict[str, list[Any]] = {"tracked": [], "position": [], "markers": []}

        def sub(topic: str, type_name: str, bucket: str) -> Any:
            return sdk.ROS2Subscriber(topic, type_name, seen[bucket].append, msg_definition=T.definition(type_name),
                                      type_hash=T.hash(type_name), domain_id=DOMAIN, router_ip=host, router_port=port)

        subs = [sub("/humans/bodies/tracked", "hri_msgs/msg/IdsList", "tracked"),
                sub("/humans/bodies/p3/position", "geometry_msgs/msg/PointStamped", "position"),
                sub("/humans/markers", "visualization_msgs/msg/MarkerArray", "markers")]
        end = time.monotonic() + 20
        while time.monotonic() < end and not (seen["tracked"] and seen["position"] and seen["markers"]):
            stamp = time.time_ns()
            tracks.put(Tracks(header=Header(stamp_ns=stamp, frame_id="map"), tracks=[TrackState(
                id=3, status="confirmed", position=np.array([2.5, 1.0, 0.9]), velocity=np.zeros(3),
                covariance=np.eye(6), last_update_ns=stamp, hits=5, age_s=1.0)]))
            time.sleep(0.1)  # the tracker's output period
        assert seen["tracked"] and list(seen["tracked"][-1].ids) == ["p3"]
        p = seen["position"][-1]
        assert (p.point.x, p.point.y, p.point.z) == (2.5, 1.0, 0.9) and p.header.frame_id == "map"
        assert {m.ns for m in seen["markers"][-1].markers} == {"people", "people_ids"}

        # the graph, as the third party's `ros2 topic list` sees it
        topics = dict(sdk.get_topic_names_and_types(domain_id=DOMAIN, router_ip=host, router_port=port, timeout=2.0))
        assert topics.get("/humans/bodies/tracked") == ["hri_msgs/msg/IdsList"]
        assert "sensor_msgs/msg/Image" in topics.get(COLOUR, [])
        assert "/humans/markers" in topics and "/tf_static" in topics
        for s in subs:
            s.close()
    finally:
        out = _stop(node)
    assert "Traceback" not in out


def _transient_local(router: Any, topic: str, type_name: str) -> tuple[Any, Any]:
    """(session, publisher): a robot's transient-local ROS 2 publisher as rmw_zenoh makes one, zenoh-ext's
    advanced publisher with a cache of one sample, on a session that timestamps its samples."""
    import zenoh
    from zenoh import ext as zext

    conf = zenoh.Config()
    for path, value in (("mode", '"client"'), ("connect/endpoints", f'["{router.endpoint}"]'),
                        ("scouting/multicast/enabled", "false"), ("timestamping/enabled", "true")):
        conf.insert_json5(path, value)
    robot = zenoh.open(conf)
    return robot, zext.declare_advanced_publisher(robot, T.key(DOMAIN, topic, type_name),
                                                  cache=zext.CacheConfig(max_samples=1), publisher_detection=True)


def _first(sub: Any, node: subprocess.Popen[str], what: str) -> Any:
    """The first message on ``sub`` within 30 s, the node staying up."""
    deadline = time.monotonic() + 30
    while time.monotonic() < deadline:
        if (m := sub.recv(timeout=0.2)) is not None:
            return m.msg
        assert node.poll() is None
    raise AssertionError(f"{what} published before the node started never came")


def test_a_late_joiner_gets_the_static_transforms(router: Any, zenoh_client: Any) -> None:
    """/tf_static is transient local: rmw_zenoh publishes it with zenoh-ext's advanced publisher and a
    cache; a node started after it must still get the robot's static transforms."""
    robot, pub = _transient_local(router, "/tf_static", "tf2_msgs/msg/TFMessage")
    stamp = 1_700_000_000_000_000_000
    batch = TransformBatch(header=Header(stamp_ns=stamp), transforms=[
        Transform(parent_frame="base_link", child_frame="camera_link", stamp_ns=stamp, translation=np.array([0.1, 0, 1.2]),
                  rotation_xyzw=np.array([0, 0, 0, 1.0]), static=True)])
    pub.put(T.serialize(tf_message(T, batch), "tf2_msgs/msg/TFMessage"), attachment=attachment(1, stamp, bytes(range(16))))
    app = zenoh_client()
    tf_static = app.subscribe(KEYS.tf_static(), TransformBatch, RELIABLE)
    node = _node(router, "--no-camera", "--no-people")
    try:
        got = _first(tf_static, node, "the static transforms")
        assert got.transforms[0].child_frame == "camera_link" and got.transforms[0].static
    finally:
        pub.undeclare()
        robot.close()
        _stop(node)


def test_a_late_joiner_gets_the_robots_map(router: Any, zenoh_client: Any) -> None:
    """/map is transient local (Nav2's map_server publishes it once, with zenoh-ext's advanced publisher
    and a cache under rmw_zenoh): a node started after it gets it and passes it on as static_map."""
    type_name = "nav_msgs/msg/OccupancyGrid"
    robot, pub = _transient_local(router, "/map", type_name)
    cls = T.store.types  # rosbags' classes and CDR, not this project's writer
    stamp = 1_700_000_000_000_000_000
    origin = cls["geometry_msgs/msg/Pose"](position=cls["geometry_msgs/msg/Point"](x=-3.0, y=-2.0, z=0.0),
                                           orientation=cls["geometry_msgs/msg/Quaternion"](x=0.0, y=0.0, z=0.0, w=1.0))
    header = T.header(stamp, "map")
    data = np.zeros(6 * 4, np.int8)
    data[:6], data[10] = 100, -1
    grid = cls[type_name](header=header, data=data, info=cls["nav_msgs/msg/MapMetaData"](
        map_load_time=header.stamp, resolution=0.05, width=6, height=4, origin=origin))
    pub.put(bytes(T.store.serialize_cdr(grid, type_name)), attachment=attachment(1, stamp, bytes(range(16))))
    app = zenoh_client()
    maps = app.subscribe(KEYS.static_map(), StaticMap, RELIABLE)
    node = _node(router, "--no-camera", "--no-people")
    try:
        got = _first(maps, node, "the map")
        assert (got.width, got.height, got.header.frame_id, got.origin) == (6, 4, "map", (-3.0, -2.0, 0.0))
        assert got.occupancy()[0].tolist() == [100] * 6 and got.occupancy()[1, 4] == -1
    finally:
        pub.undeclare()
        _stop(node)
        robot.close()


def test_a_ros2_robots_session_timestamps_its_samples() -> None:
    """A transient-local ROS 2 publisher (a cached advanced publisher: the simulated robot's /map)
    needs timestamping, as rmw_zenoh's sessions have it; other sessions go without."""
    from common.transport.zenoh_config import ZenohOptions, build_zenoh_config

    assert build_zenoh_config(ZenohOptions(timestamping=True)).get_json("timestamping/enabled") == "true"
    assert build_zenoh_config(ZenohOptions()).get_json("timestamping/enabled") != "true"
