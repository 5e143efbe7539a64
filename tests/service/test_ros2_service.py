"""The ROS 2 node on the in-memory transport: a ROS 2 camera and tf in, the people out, and
every kind of bad ROS 2 input counted and survived.

The ROS 2 side here is this project's own writer (services.ros2.participant); the third-party
implementation (zenoh-ros2-sdk) is on the other side in tests/integration/test_ros2_zenoh.py.
"""

from __future__ import annotations

import struct
from typing import Any

import numpy as np
import pytest

from common.messages.keys import RELIABLE, Delivery, Keys
from common.transport.memory import MemoryBus
from common.runtime.service import Counters
from common.messages.schemas import (CameraInfo, Header, Image, RGBDFrame, StaticMap, Tracks, TrackState, Transform,
                                     TransformBatch)
from services.ros2.config import Ros2Config
from services.ros2.convert import camera_info_message, image_message, tf_message
from services.ros2.core.types import types_of
from services.ros2.core.wire import parse_token
from services.ros2.participant import QOS_TF_STATIC, RosParticipant
from services.ros2.service import Ros2Service

KEYS = Keys()
T = types_of()
COLOUR, DEPTH, INFO = ("/camera/camera/color/image_raw", "/camera/camera/aligned_depth_to_color/image_raw",
                       "/camera/camera/color/camera_info")
STAMP = 1_700_000_000_123_456_789


def _frame(stamp: int = STAMP, h: int = 48, w: int = 64) -> RGBDFrame:
    rng = np.random.default_rng(stamp % 1000)
    header = Header(stamp_ns=stamp, frame_id="camera_color_optical_frame", source="head")
    yy, xx = np.mgrid[0:h, 0:w]
    rgb = np.stack([xx * 255 // w, yy * 255 // h, (xx + yy) * 127 // (w + h) + rng.integers(0, 60)], -1).astype(np.uint8)
    depth = rng.integers(500, 5000, (h, w), dtype=np.uint16)
    K = np.array([[50.0, 0, w / 2], [0, 50.0, h / 2], [0, 0, 1]])
    return RGBDFrame(header=header, rgb=Image.from_array(rgb, "rgb8", header), depth=Image.from_array(depth, "16UC1", header),
                     camera_info=CameraInfo(header=header, width=w, height=h, K=K, distortion_model="none"))


class Rig:
    def __init__(self, **settings: Any) -> None:
        self.bus = MemoryBus()
        self.robot_t = self.bus.transport()
        self.robot = RosParticipant(self.robot_t, T, domain_id=0, node_name="camera")
        self.config = Ros2Config(**{"domain_id": 0, **settings})
        self.node_t = self.bus.transport()
        self.node = Ros2Service(self.node_t, KEYS, self.config, Counters())
        self.app = self.bus.transport()
        self.frames = self.app.subscribe(KEYS.frames("head"), RGBDFrame, Delivery(latest=False, queue=64, congestion="drop"))
        self.tf = self.app.subscribe(KEYS.tf(), TransformBatch, RELIABLE)
        self.tf_static = self.app.subscribe(KEYS.tf_static(), TransformBatch, RELIABLE)
        self.tracks = self.app.publisher(KEYS.tracks(), Tracks, RELIABLE)

    def send_frame(self, frame: RGBDFrame, depth: bool = True) -> None:
        self.robot.publisher(INFO, "sensor_msgs/msg/CameraInfo").put(camera_info_message(T, frame))
        if depth:
            self.robot.publisher(DEPTH, "sensor_msgs/msg/Image").put(image_message(T, frame, depth=True))
        self.robot.publisher(COLOUR, "sensor_msgs/msg/Image").put(image_message(T, frame))

    def got(self, sub: Any) -> list[Any]:
        out = []
        while (g := sub.try_recv()) is not None:
            out.append(g.msg)
        return out

    @property
    def extra(self) -> dict[str, float]:
        return self.node.counters.extra


def test_a_ros2_rgbd_camera_becomes_frames_pixel_for_pixel() -> None:
    rig = Rig()
    sent = [_frame(STAMP + k * 33_000_000) for k in range(3)]
    for f in sent:
        rig.send_frame(f)
    rig.node.poll(0.0)
    got = rig.got(rig.frames)
    assert [f.header.stamp_ns for f in got] == [f.header.stamp_ns for f in sent]
    for a, b in zip(got, sent):
        assert a.header.frame_id == "camera_color_optical_frame" and a.header.source == "head"
        assert np.array_equal(a.rgb.to_array(), b.rgb.to_array())
        assert np.array_equal(a.depth.to_array(), b.depth.to_array())
        assert np.allclose(a.camera_info.K, b.camera_info.K)
    assert [f.header.seq for f in got] == [1, 2, 3]


def test_colour_and_depth_pair_by_nearest_stamp_within_the_slop() -> None:
    rig = Rig(slop_s=0.02)
    f = _frame()
    rig.robot.publisher(INFO, "sensor_msgs/msg/CameraInfo").put(camera_info_message(T, f))
    depth_early = _frame(STAMP - 15_000_000)
    depth_near = _frame(STAMP + 4_000_000)
    rig.robot.publisher(DEPTH, "sensor_msgs/msg/Image").put(image_message(T, depth_early, depth=True))
    rig.robot.publisher(COLOUR, "sensor_msgs/msg/Image").put(image_message(T, f))
    rig.node.poll(0.0)
    assert rig.got(rig.frames) == [], "the colour image must wait: a nearer depth image may come"
    rig.robot.publisher(DEPTH, "sensor_msgs/msg/Image").put(image_message(T, depth_near, depth=True))
    rig.node.poll(0.01)
    (got,) = rig.got(rig.frames)
    assert np.array_equal(got.depth.to_array(), depth_near.depth.to_array())
    # a colour image with no depth near it is dropped and counted
    lone = _frame(STAMP + 500_000_000)
    rig.robot.publisher(COLOUR, "sensor_msgs/msg/Image").put(image_message(T, lone))
    rig.node.poll(0.02)
    rig.node.poll(5.0)
    assert rig.got(rig.frames) == []
    assert rig.node.counters.extra.get("dropped_colour_depth_late", 0) + rig.node.counters.extra.get(
        "dropped_colour_no_depth", 0) + rig.node.counters.extra.get("dropped_colour_no_depth_near", 0) == 1


def test_an_rgb_only_camera_needs_no_depth() -> None:
    rig = Rig(depth_topic="", require_depth=False)
    rig.send_frame(_frame(), depth=False)
    rig.node.poll(0.0)
    (got,) = rig.got(rig.frames)
    assert got.depth is None


def test_compressed_colour_is_kept_compressed() -> None:
    import cv2

    rig = Rig(colour_topic="/camera/color/image_raw/compressed", colour_compressed=True, depth_topic="",
              require_depth=False)
    f = _frame()
    ok, jpg = cv2.imencode(".jpg", cv2.cvtColor(f.rgb.to_array(), cv2.COLOR_RGB2BGR))
    msg = T.cls("sensor_msgs/msg/CompressedImage")(header=image_message(T, f).header, format="rgb8; jpeg compressed bgr8",
                                                    data=jpg.reshape(-1))
    rig.robot.publisher(INFO, "sensor_msgs/msg/CameraInfo").put(camera_info_message(T, f))
    rig.robot.publisher("/camera/color/image_raw/compressed", "sensor_msgs/msg/CompressedImage").put(msg)
    rig.node.poll(0.0)
    (got,) = rig.got(rig.frames)
    assert got.rgb.encoding == "jpeg" and got.rgb.shape == (48, 64, 3)
    assert np.abs(got.rgb.to_array().astype(int) - f.rgb.to_array()).mean() < 8  # a lossy copy of the same image


def _drain(sub: Any) -> list[Any]:
    out = []
    while (g := sub.try_recv()) is not None:
        out.append(g.msg)
    return out


def test_tf_and_a_late_joiners_tf_static() -> None:
    bus = MemoryBus()
    robot = RosParticipant(bus.transport(), T, domain_id=0, node_name="robot_state_publisher")
    static = TransformBatch(header=Header(stamp_ns=STAMP), transforms=[
        Transform(parent_frame="base_link", child_frame="camera_link", stamp_ns=STAMP, translation=np.array([0.1, 0, 1.2]),
                  rotation_xyzw=np.array([0, 0, 0, 1.0]), static=True)])
    # the static publisher keeps its last sample for late joiners (transient local), as rmw_zenoh's does
    robot.publisher("/tf_static", "tf2_msgs/msg/TFMessage", QOS_TF_STATIC, cache=1).put(tf_message(T, static))
    node = Ros2Service(bus.transport(), KEYS, Ros2Config(domain_id=0, camera_in=False, people_out=False), Counters())
    app = bus.transport()
    tf_static = app.subscribe(KEYS.tf_static(), TransformBatch, RELIABLE)
    tf = app.subscribe(KEYS.tf(), TransformBatch, RELIABLE)
    moving = TransformBatch(header=Header(stamp_ns=STAMP), transforms=[
        Transform(parent_frame="map", child_frame="base_link", stamp_ns=STAMP + 5, translation=np.array([1.0, 2.0, 0]),
                  rotation_xyzw=np.array([0, 0, np.sin(0.25), np.cos(0.25)]))])
    robot.publisher("/tf", "tf2_msgs/msg/TFMessage").put(tf_message(T, moving))
    node.poll(0.0)
    (st,) = _drain(tf_static)
    assert st.transforms[0].child_frame == "camera_link" and st.transforms[0].static
    assert np.allclose(st.transforms[0].translation, [0.1, 0, 1.2])
    (mv,) = _drain(tf)
    assert mv.transforms[0].parent_frame == "map" and mv.transforms[0].stamp_ns == STAMP + 5
    assert np.allclose(mv.transforms[0].rotation_xyzw, [0, 0, np.sin(0.25), np.cos(0.25)])


def _track(tid: int, x: float, status: str = "confirmed") -> TrackState:
    return TrackState(id=tid, status=status, position=np.array([x, 1.0, 0.9]), velocity=np.array([0.5, 0, 0]),
                      covariance=np.eye(6), last_update_ns=STAMP, hits=5, age_s=1.0)


def test_people_go_out_as_ros4hri_topics_tf_frames_and_markers() -> None:
    rig = Rig(camera_in=False, tf_in=False)
    reader = rig.bus.transport()
    subs = {name: reader.subscribe_raw(f"0/humans/{name}/*/*", Delivery(latest=False, queue=64, congestion="drop"))
            for name in ("bodies/tracked", "bodies/p3/position", "bodies/p3/velocity", "markers")}
    tf_sub = reader.subscribe_raw("0/tf/*/*", Delivery(latest=False, queue=64, congestion="drop"))
    header = Header(stamp_ns=STAMP, frame_id="map")
    rig.tracks.put(Tracks(header=header, tracks=[_track(3, 2.0), _track(4, 3.0, "tentative")]))
    rig.node.poll(0.0)
    (ids,) = [T.deserialize(s.payload, "hri_msgs/msg/IdsList") for s in iter(subs["bodies/tracked"].try_recv, None)]
    assert list(ids.ids) == ["p3"] and ids.header.frame_id == "map"
    assert ids.header.stamp.sec * 10**9 + ids.header.stamp.nanosec == STAMP
    (pos,) = [T.deserialize(s.payload, "geometry_msgs/msg/PointStamped") for s in iter(subs["bodies/p3/position"].try_recv, None)]
    assert (pos.point.x, pos.point.y, pos.point.z) == (2.0, 1.0, 0.9)
    (vel,) = [T.deserialize(s.payload, "geometry_msgs/msg/TwistStamped") for s in iter(subs["bodies/p3/velocity"].try_recv, None)]
    assert vel.twist.linear.x == 0.5
    (tfm,) = [T.deserialize(s.payload, "tf2_msgs/msg/TFMessage") for s in iter(tf_sub.try_recv, None)]
    assert [t.child_frame_id for t in tfm.transforms] == ["body_p3"] and tfm.transforms[0].header.frame_id == "map"
    (mk,) = [T.deserialize(s.payload, "visualization_msgs/msg/MarkerArray") for s in iter(subs["markers"].try_recv, None)]
    assert {(m.ns, m.id, m.action) for m in mk.markers} == {("people", 3, 0), ("people_ids", 3, 0)}
    # the person leaves: tracked is empty and their markers are deleted
    rig.tracks.put(Tracks(header=Header(stamp_ns=STAMP + 10**8, frame_id="map"), tracks=[]))
    rig.node.poll(0.1)
    (ids,) = [T.deserialize(s.payload, "hri_msgs/msg/IdsList") for s in iter(subs["bodies/tracked"].try_recv, None)]
    assert list(ids.ids) == []
    (mk,) = [T.deserialize(s.payload, "visualization_msgs/msg/MarkerArray") for s in iter(subs["markers"].try_recv, None)]
    assert {(m.ns, m.id, m.action) for m in mk.markers} == {("people", 3, 2), ("people_ids", 3, 2)}


def test_the_node_is_in_the_ros2_graph_and_leaves_it_on_close() -> None:
    rig = Rig()
    rig.tracks.put(Tracks(header=Header(stamp_ns=STAMP, frame_id="map"), tracks=[_track(1, 1.0)]))
    rig.node.poll(0.0)
    mine = [parse_token(k) for k in rig.bus.tokens if f"/{rig.node_t.session_id()}/" in k]
    names = {(e.kind, e.topic) for e in mine}
    assert ("NN", "") in names
    assert {("MS", COLOUR), ("MS", DEPTH), ("MS", INFO), ("MS", "/tf"), ("MS", "/tf_static")} <= names
    assert {("MP", "/humans/bodies/tracked"), ("MP", "/humans/bodies/p1/position"), ("MP", "/humans/markers")} <= names
    assert all(e.node_name == "people_perception" for e in mine)
    static = next(e for e in mine if e.topic == "/tf_static")
    assert static.qos.transient_local
    rig.node.close()
    assert not [k for k in rig.bus.tokens if f"/{rig.node_t.session_id()}/" in k]


def _put(rig: Rig, topic: str, type_name: str, payload: bytes, attachment: bytes | None = b"default") -> None:
    pub = rig.robot.publisher(topic, type_name)
    if attachment == b"default":
        pub.put_cdr(payload)
    else:
        pub.pub.put(payload, attachment)


def _image(encoding: str, h: int, w: int, step: int, nbytes: int) -> bytes:
    return T.serialize(T.cls("sensor_msgs/msg/Image")(
        header=image_message(T, _frame()).header, height=h, width=w, encoding=encoding, is_bigendian=0, step=step,
        data=np.zeros(nbytes, np.uint8)), "sensor_msgs/msg/Image")


@pytest.mark.parametrize("case, reason", [
    ("truncated", "invalid_cdr"),
    ("garbage", "invalid_cdr"),
    ("unknown encoding", "invalid_unknown_encoding"),
    ("step", "invalid_bad_step"),
    ("sizes differ", "invalid_size"),
    ("no attachment", "invalid_attachment"),
    ("short attachment", "invalid_attachment"),
    ("type hash", "invalid_type_hash"),
    ("wrong type", "invalid_wrong_type"),
])
def test_bad_ros2_input_is_counted_and_survived(case: str, reason: str) -> None:
    rig = Rig()
    good = _frame()
    rig.robot.publisher(INFO, "sensor_msgs/msg/CameraInfo").put(camera_info_message(T, good))
    colour = T.serialize(image_message(T, good), "sensor_msgs/msg/Image")
    if case == "truncated":
        _put(rig, COLOUR, "sensor_msgs/msg/Image", colour[:200])
    elif case == "garbage":
        _put(rig, COLOUR, "sensor_msgs/msg/Image", bytes(np.random.default_rng(1).integers(0, 255, 5000, dtype=np.uint8)))
    elif case == "unknown encoding":
        _put(rig, COLOUR, "sensor_msgs/msg/Image", _image("yuv422", 48, 64, 128, 48 * 128))
    elif case == "step":
        _put(rig, COLOUR, "sensor_msgs/msg/Image", _image("rgb8", 48, 64, 100, 48 * 100))
    elif case == "sizes differ":
        small = _frame(h=24, w=32)
        rig.robot.publisher(DEPTH, "sensor_msgs/msg/Image").put(image_message(T, small, depth=True))
        rig.robot.publisher(COLOUR, "sensor_msgs/msg/Image").put(image_message(T, good))
    elif case == "no attachment":
        _put(rig, COLOUR, "sensor_msgs/msg/Image", colour, attachment=None)
    elif case == "short attachment":
        _put(rig, COLOUR, "sensor_msgs/msg/Image", colour, attachment=struct.pack("<qq", 1, 2))
    elif case == "type hash":
        other = rig.robot_t.raw_publisher(f"0{COLOUR}/sensor_msgs::msg::dds_::Image_/RIHS01_{'ab' * 32}",
                                          Delivery(latest=False, queue=4, congestion="drop"))
        other.put(colour, struct.pack("<qqB", 1, STAMP, 16) + bytes(16))
    elif case == "wrong type":
        other = RosParticipant(rig.bus.transport(), T, domain_id=0, node_name="other_camera")
        other.publisher(COLOUR, "sensor_msgs/msg/CompressedImage").put(T.cls("sensor_msgs/msg/CompressedImage")(
            header=image_message(T, good).header, format="jpeg", data=np.zeros(10, np.uint8)))
    rig.node.poll(0.0)
    rig.node.poll(5.0)
    assert rig.extra.get(reason, 0) >= 1, rig.extra
    assert rig.node.counters.invalid >= 1
    # and the node goes on: a good frame after it passes
    rig.got(rig.frames)
    later = _frame(STAMP + 10**9)
    rig.send_frame(later)
    rig.node.poll(5.1)
    assert [f.header.stamp_ns for f in rig.got(rig.frames)] == [later.header.stamp_ns]


def _grid_message(stamp: int = STAMP, frame_id: str = "map") -> Any:
    """A 5 x 4 nav_msgs/OccupancyGrid built with rosbags' own classes: a wall along the top row,
    one unknown cell, the origin turned 90 degrees."""
    cls = T.store.types
    data = np.zeros(20, np.int8)
    data[15:] = 100
    data[7] = -1
    q = cls["geometry_msgs/msg/Quaternion"](x=0.0, y=0.0, z=np.sin(np.pi / 4), w=np.cos(np.pi / 4))
    pose = cls["geometry_msgs/msg/Pose"](position=cls["geometry_msgs/msg/Point"](x=2.0, y=-1.0, z=0.0), orientation=q)
    header = T.header(stamp, frame_id)
    info = cls["nav_msgs/msg/MapMetaData"](map_load_time=header.stamp, resolution=0.05, width=5, height=4, origin=pose)
    return cls["nav_msgs/msg/OccupancyGrid"](header=header, info=info, data=data)


def test_the_robots_map_reaches_a_late_joiner_and_is_sent_again() -> None:
    """/map is transient local (map_server publishes it once): a node started after it still gets it,
    passes it on as static_map, and sends it again every map_period_s for this project's late joiners."""
    bus = MemoryBus()
    robot = RosParticipant(bus.transport(), T, domain_id=0, node_name="map_server")
    robot.publisher("/map", "nav_msgs/msg/OccupancyGrid", QOS_TF_STATIC, cache=1).put(_grid_message())
    node = Ros2Service(bus.transport(), KEYS, Ros2Config(domain_id=0, camera_in=False, people_out=False,
                                                         map_period_s=5.0), Counters())
    maps = bus.transport().subscribe(KEYS.static_map(), StaticMap, RELIABLE)
    node.poll(0.0)
    (grid,) = _drain(maps)
    assert (grid.width, grid.height, grid.resolution, grid.header.frame_id) == (5, 4, pytest.approx(0.05), "map")
    assert grid.origin == pytest.approx((2.0, -1.0, np.pi / 2))
    cells = grid.occupancy()
    assert cells[3].tolist() == [100] * 5 and cells[1, 2] == -1 and cells[0].tolist() == [0] * 5
    node.poll(1.0)
    assert not _drain(maps)
    node.poll(5.5)
    assert len(_drain(maps)) == 1 and node.counters.extra["maps"] == 1
    assert "/map -> static_map" in node.describe()


def test_a_map_of_another_type_is_counted_not_taken() -> None:
    bus = MemoryBus()
    robot = RosParticipant(bus.transport(), T, domain_id=0, node_name="robot")
    node = Ros2Service(bus.transport(), KEYS, Ros2Config(domain_id=0, camera_in=False, people_out=False), Counters())
    maps = bus.transport().subscribe(KEYS.static_map(), StaticMap, RELIABLE)
    robot.publisher("/map", "tf2_msgs/msg/TFMessage").put(T.cls("tf2_msgs/msg/TFMessage")(transforms=[]))
    node.poll(0.0)
    assert not _drain(maps) and node.counters.extra["invalid_wrong_type"] == 1
