"""rmw_zenoh's wire format, byte for byte: against the design document's examples, against
zenoh's own serializer, and against a third party's implementation (zenoh-ros2-sdk's key
builders and QoS codec)."""

from __future__ import annotations

import os
import struct

import numpy as np
import pytest

from services.ros2.core.images import ImageError, compressed_pixels, intrinsics, raw_pixels
from services.ros2.core.people import PeopleWriter, Person
from services.ros2.core.types import CdrError, known_hashes, types_of
from services.ros2.core.wire import (GraphEntity, Qos, attachment, data_key, dds_to_ros, parse_attachment, parse_token,
                                     ros_to_dds)

T = types_of()
CHATTER = ("0/chatter/std_msgs::msg::dds_::String_/"
           "RIHS01_df668c740482bbd48fb39d76a70dfd4bd59db1288021743503259e948f6b1a18")


def test_the_design_documents_chatter_key() -> None:
    assert T.key(0, "/chatter", "std_msgs/msg/String") == CHATTER
    assert T.key(0, "chatter/", "std_msgs/msg/String") == CHATTER
    assert data_key(3, "/robot1/chatter", "std_msgs::msg::dds_::String_", "RIHS01_x") == \
        "3/robot1/chatter/std_msgs::msg::dds_::String_/RIHS01_x"
    with pytest.raises(ValueError):
        data_key(0, "/", "std_msgs::msg::dds_::String_", "RIHS01_x")


def test_hashes_come_from_rosbags_and_agree_across_distributions() -> None:
    # checked against values computed independently (ROS2_NOTES): never typed into the code
    assert T.hash("hri_msgs/msg/IdsList") == "RIHS01_7e0812d1ac945c98fd3e393568d581ad0ab567f37b24eff633eab778c1bfe62d"
    assert T.hash("geometry_msgs/msg/PointStamped") == \
        "RIHS01_4c0296af86e01e562e9e0405d138a01537247580076c58ea38d7923ac1045897"
    for t in ("sensor_msgs/msg/Image", "sensor_msgs/msg/CameraInfo", "tf2_msgs/msg/TFMessage",
              "visualization_msgs/msg/MarkerArray", "hri_msgs/msg/BodyPosture"):
        assert list(known_hashes(t).values()) == ["jazzy, kilted, rolling"]


def test_the_worked_token_example_and_qos_texts() -> None:
    e = GraphEntity(domain_id=0, zid="1234abcd", node_id=0, entity_id=1, kind="MP", node_name="hri_tracker",
                    topic="/humans/tracks", dds_type=ros_to_dds("geometry_msgs/msg/PoseArray"),
                    type_hash=T.hash("geometry_msgs/msg/PoseArray"), qos=Qos(depth=10))
    assert e.token() == ("@ros2_lv/0/1234abcd/0/1/MP/%/%/hri_tracker/%humans%tracks/geometry_msgs::msg::dds_::PoseArray_/"
                         "RIHS01_af0cc36d190e104d546d168d6b39df04fa4b4ccecf59cb4c9ed328d3d5004aa0/::,10:,:,:,,")
    assert parse_token(e.token()) == e
    node = GraphEntity(domain_id=0, zid="1234abcd", node_id=0, entity_id=0, kind="NN", node_name="hri_tracker")
    assert node.token() == "@ros2_lv/0/1234abcd/0/0/NN/%/%/hri_tracker"
    assert Qos(reliable=False, depth=5).text() == "2::,5:,:,:,,"
    assert Qos(transient_local=True, depth=1).text() == ":1:,1:,:,:,,"
    assert Qos().text() == "::,:,:,:,,"
    assert dds_to_ros("sensor_msgs::msg::dds_::Image_") == "sensor_msgs/msg/Image"
    for bad in ("@ros2_lv/0/z/0/1/MP/%/%/n", "0/chatter/x/y", "@ros2_lv/x/z/0/0/NN/%/%/n"):
        with pytest.raises(ValueError):
            parse_token(bad)


def test_tokens_and_qos_agree_with_a_third_party_implementation() -> None:
    os.environ.setdefault("GIT_PYTHON_REFRESH", "quiet")
    keyexpr = pytest.importorskip("zenoh_ros2_sdk.keyexpr", reason="zenoh-ros2-sdk (the test extra) is not installed")
    from zenoh_ros2_sdk.entity import EndpointEntity, EntityKind, NodeEntity
    from zenoh_ros2_sdk.qos import QosProfile

    for ns, qos in (("/", Qos(depth=10)), ("/robot1", Qos(reliable=False, depth=5)),
                    ("/", Qos(transient_local=True, depth=1))):
        ours = GraphEntity(domain_id=7, zid="ab12", node_id=3, entity_id=9, kind="MS", node_name="people_perception",
                           namespace=ns, topic="/humans/bodies/tracked", dds_type=ros_to_dds("hri_msgs/msg/IdsList"),
                           type_hash=T.hash("hri_msgs/msg/IdsList"), qos=qos)
        node = NodeEntity(domain_id=7, session_id="ab12", node_id=3, node_name="people_perception", namespace=ns)
        theirs = EndpointEntity(node=node, entity_id=9, kind=EntityKind.SUBSCRIPTION, name="/humans/bodies/tracked",
                                dds_type_name=ours.dds_type, type_hash=ours.type_hash, qos=qos.text())
        assert ours.token() == keyexpr.endpoint_liveliness_keyexpr(theirs)
        assert GraphEntity(domain_id=7, zid="ab12", node_id=3, entity_id=3, kind="NN", node_name="people_perception",
                           namespace=ns).token() == keyexpr.node_liveliness_keyexpr(node)
        decoded = QosProfile.decode(qos.text())
        assert decoded.history_depth == qos.depth
        assert (decoded.reliability.value == 1) == qos.reliable
        assert (decoded.durability.value == 1) == qos.transient_local
    assert keyexpr.topic_keyexpr(0, "/chatter", "std_msgs::msg::dds_::String_", T.hash("std_msgs/msg/String")) == CHATTER


def test_the_attachment_is_what_zenohs_serializer_writes() -> None:
    from zenoh.ext import Int64, z_serialize

    gid = bytes(range(16))
    ours = attachment(7, 1_700_000_000_123_456_789, gid)
    assert ours == z_serialize((Int64(7), Int64(1_700_000_000_123_456_789), gid)).to_bytes()
    assert len(ours) == 33 and ours[16] == 16
    back = parse_attachment(ours)
    assert (back.sequence, back.source_timestamp_ns, back.gid) == (7, 1_700_000_000_123_456_789, gid)
    for bad in (None, ours[:-1], struct.pack("<qqB", 1, 2, 8) + bytes(16)):
        with pytest.raises(ValueError):
            parse_attachment(bad)


def test_cdr_round_trip_and_garbage() -> None:
    msg = T.cls("std_msgs/msg/String")(data="hello")
    raw = T.serialize(msg, "std_msgs/msg/String")
    assert raw[:4] == b"\x00\x01\x00\x00"
    assert T.deserialize(raw, "std_msgs/msg/String").data == "hello"
    for bad in (b"", b"\x00\x01", b"\x07\x07\x00\x00abcd", raw[:6]):
        with pytest.raises(CdrError):
            T.deserialize(bad, "std_msgs/msg/String")


def _img(encoding: str, h: int, w: int, step: int, data: np.ndarray, big: int = 0) -> object:
    return T.cls("sensor_msgs/msg/Image")(header=T.cls("std_msgs/msg/Header")(
        stamp=T.cls("builtin_interfaces/msg/Time")(sec=1, nanosec=0), frame_id="c"), height=h, width=w, encoding=encoding,
        is_bigendian=big, step=step, data=data)


def test_raw_images_padding_byte_order_and_errors() -> None:
    depth = np.arange(12, dtype=np.uint16).reshape(3, 4) * 100
    padded = np.zeros((3, 12), np.uint8)
    padded[:, :8] = depth.view(np.uint8)
    px = raw_pixels(_img("16UC1", 3, 4, 12, padded.reshape(-1)), depth=True)
    assert px.shape == (3, 4) and np.array_equal(np.frombuffer(px.data, np.uint16).reshape(3, 4), depth)
    big = depth.astype(">u2")
    px = raw_pixels(_img("16UC1", 3, 4, 8, big.view(np.uint8).reshape(-1), big=1), depth=True)
    assert np.array_equal(np.frombuffer(px.data, np.uint16).reshape(3, 4), depth)
    rgb = np.arange(3 * 4 * 3, dtype=np.uint8)
    assert raw_pixels(_img("bgr8", 3, 4, 12, rgb), depth=False).encoding == "bgr8"
    assert raw_pixels(_img("8UC1", 3, 4, 4, rgb[:12]), depth=False).encoding == "mono8"
    cases = [("yuv422", 4 * 2, "unknown_encoding", False), ("rgb8", 10, "bad_step", False),
             ("rgb8", 12, "not_depth", True), ("32FC1", 16, "not_colour", False)]
    for enc, step, reason, want_depth in cases:
        with pytest.raises(ImageError) as err:
            raw_pixels(_img(enc, 3, 4, step, np.zeros(3 * step, np.uint8)), depth=want_depth)
        assert err.value.reason == reason
    with pytest.raises(ImageError) as err:
        raw_pixels(_img("rgb8", 3, 4, 12, np.zeros(30, np.uint8)), depth=False)
    assert err.value.reason == "bad_size"


def test_compressed_images_are_sized_from_their_headers() -> None:
    import cv2

    colour = np.zeros((30, 40, 3), np.uint8)
    depth = (np.arange(30 * 40, dtype=np.uint16).reshape(30, 40) * 3)
    msg = T.cls("sensor_msgs/msg/CompressedImage")
    header = T.cls("std_msgs/msg/Header")(stamp=T.cls("builtin_interfaces/msg/Time")(sec=1, nanosec=0), frame_id="c")
    jpg = cv2.imencode(".jpg", colour)[1].reshape(-1)
    png16 = cv2.imencode(".png", depth)[1].reshape(-1)
    assert compressed_pixels(msg(header=header, format="jpeg", data=jpg), depth=False).shape == (30, 40, 3)
    px = compressed_pixels(msg(header=header, format="16UC1; compressedDepth png",
                               data=np.concatenate([np.zeros(12, np.uint8), png16])), depth=True)
    assert px.shape == (30, 40) and px.dtype == "uint16" and px.data[:8] == b"\x89PNG\r\n\x1a\n"
    for data, want_depth, reason in ((jpg, True, "not_depth"), (np.zeros(50, np.uint8), False, "unknown_encoding"),
                                     (jpg[:20], False, "corrupt")):
        with pytest.raises(ImageError) as err:
            compressed_pixels(msg(header=header, format="jpeg", data=data), depth=want_depth)
        assert err.value.reason == reason


def test_camera_info() -> None:
    info = T.cls("sensor_msgs/msg/CameraInfo")
    roi = T.cls("sensor_msgs/msg/RegionOfInterest")(x_offset=0, y_offset=0, height=0, width=0, do_rectify=False)
    header = T.cls("std_msgs/msg/Header")(stamp=T.cls("builtin_interfaces/msg/Time")(sec=1, nanosec=0), frame_id="c")

    def make(k: list[float], d: list[float], model: str = "plumb_bob") -> object:
        return info(header=header, height=480, width=640, distortion_model=model, d=np.array(d, float),
                    k=np.array(k, float), r=np.eye(3).reshape(-1), p=np.zeros(12), binning_x=0, binning_y=0, roi=roi)

    k = [600.0, 0, 320, 0, 600, 240, 0, 0, 1]
    got = intrinsics(make(k, [0.1, -0.2, 0, 0, 0.01]))
    assert got.distortion_model == "plumb_bob" and got.K[0, 2] == 320 and len(got.D) == 5
    assert intrinsics(make(k, [0, 0, 0, 0, 0])).distortion_model == "none"
    with pytest.raises(ImageError):
        intrinsics(make([0.0] * 9, []))  # an uncalibrated camera


def test_people_writer_ids_posture_and_facing() -> None:
    w = PeopleWriter(T, prefix="p")
    standing_facing_y = Person(4, (1.0, 2.0, 0.9), (0.0, 0.3, 0.0), posture=(0.9, 0.05, 0.05),
                               orientation=(0.02, 0.02, 0.86, 0.02, 0.02, 0.02, 0.02, 0.02))
    unknown = Person(5, (3.0, 2.0, 0.9), (0.0, 0.0, 0.0))
    msgs = {topic: (t, m) for topic, t, m in w.messages(5_000_000_001, [standing_facing_y, unknown])}
    assert list(msgs["/humans/bodies/tracked"][1].ids) == ["p4", "p5"]
    assert msgs["/humans/bodies/p4/posture"][1].posture == 1
    assert "/humans/bodies/p5/posture" not in msgs
    tf = msgs["/tf"][1]
    q4 = tf.transforms[0].transform.rotation
    assert tf.transforms[0].child_frame_id == "body_p4" and abs(2 * np.arctan2(q4.z, q4.w) - np.pi / 2) < 0.05
    assert tf.transforms[1].transform.rotation.w == 1.0
    for topic, (type_name, m) in msgs.items():  # every message serializes as its type
        assert T.deserialize(T.serialize(m, type_name), type_name) is not None, topic
