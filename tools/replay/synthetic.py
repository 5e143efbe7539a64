"""Synthetic ROS 1 and ROS 2 bags of an RGB-D robot, for tests, demos and benchmarks.

:class:`SyntheticRun` defines the content (so a test knows what to expect);
:func:`write_bag` writes it with rosbags' own writers: colour images, registered depth,
camera info, /tf, /tf_static, /odom, and an unrelated /chatter topic.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Any, Literal

import numpy as np

__all__ = ["SyntheticRun", "write_bag"]

BagKind = Literal["ros1", "ros2-sqlite3", "ros2-mcap"]


@dataclass(frozen=True)
class SyntheticRun:
    """``frames`` RGB-D frames of ``width`` x ``height`` every ``period_ns``, from ``t0_ns``.

    Depth is stamped ``depth_offset_ns`` after its colour image, each message is logged
    ``log_delay_ns`` after its stamp, odometry moves base_link 0.1 m along x per frame.
    """

    frames: int = 20
    width: int = 64
    height: int = 48
    period_ns: int = 100_000_000
    t0_ns: int = 1_700_000_000_000_000_000
    depth_offset_ns: int = 3_000_000
    log_delay_ns: int = 5_000_000
    rgb_encoding: Literal["rgb8", "bgr8"] = "rgb8"
    depth_encoding: Literal["16UC1", "32FC1"] = "16UC1"
    row_padding: int = 0

    def stamp(self, i: int) -> int:
        return self.t0_ns + i * self.period_ns

    def rgb(self, i: int) -> np.ndarray:
        """(H, W, 3) uint8 in RGB order."""
        yy, xx = np.mgrid[0 : self.height, 0 : self.width]
        return np.stack([(xx * 4 + i) % 256, (yy * 5 + 2 * i) % 256, np.full_like(xx, (37 * i) % 256)], -1).astype(np.uint8)

    def depth_mm(self, i: int) -> np.ndarray:
        """(H, W) uint16 millimetres; the top-left pixel is invalid (0)."""
        d = (np.arange(self.width, dtype=np.uint16)[None, :] * 10 + 1000 + 7 * i).repeat(self.height, 0)
        d[0, 0] = 0
        return d.astype(np.uint16)

    def K(self) -> np.ndarray:
        return np.array([[50.0, 0, (self.width - 1) / 2], [0, 50.0, (self.height - 1) / 2], [0, 0, 1.0]])

    def odom_x(self, i: int) -> float:
        return 0.1 * i


def _time(store: Any, ns: int) -> Any:
    return store.types["builtin_interfaces/msg/Time"](sec=ns // 1_000_000_000, nanosec=ns % 1_000_000_000)


def _header(store: Any, ros1: bool, ns: int, frame: str, seq: int = 0) -> Any:
    H = store.types["std_msgs/msg/Header"]
    return H(seq=seq, stamp=_time(store, ns), frame_id=frame) if ros1 else H(stamp=_time(store, ns), frame_id=frame)


def _image(store: Any, ros1: bool, run: SyntheticRun, ns: int, arr: np.ndarray, enc: str, frame: str) -> Any:
    h, w = arr.shape[:2]
    rows = arr.reshape(h, -1).view(np.uint8)
    if run.row_padding:
        rows = np.concatenate([rows, np.full((h, run.row_padding), 0xAB, np.uint8)], 1)
    return store.types["sensor_msgs/msg/Image"](
        header=_header(store, ros1, ns, frame), height=h, width=w, encoding=enc, is_bigendian=0,
        step=rows.shape[1], data=np.ascontiguousarray(rows).reshape(-1))


def _camera_info(store: Any, ros1: bool, run: SyntheticRun, ns: int) -> Any:
    CI = store.types["sensor_msgs/msg/CameraInfo"]
    roi = store.types["sensor_msgs/msg/RegionOfInterest"](x_offset=0, y_offset=0, height=0, width=0, do_rectify=False)
    k = run.K().reshape(-1)
    p = np.hstack([run.K(), np.zeros((3, 1))]).reshape(-1)
    fields = dict(header=_header(store, ros1, ns, "camera_rgb_optical_frame"), height=run.height, width=run.width,
                  distortion_model="plumb_bob", binning_x=0, binning_y=0, roi=roi)
    if ros1:
        return CI(D=np.zeros(5), K=k, R=np.eye(3).reshape(-1), P=p, **fields)
    return CI(d=np.zeros(5), k=k, r=np.eye(3).reshape(-1), p=p, **fields)


def _tf(store: Any, ros1: bool, ns: int, parent: str, child: str, xyz: tuple[float, float, float],
        q: tuple[float, float, float, float]) -> Any:
    T = store.types
    tr = T["geometry_msgs/msg/Transform"](translation=T["geometry_msgs/msg/Vector3"](x=xyz[0], y=xyz[1], z=xyz[2]),
                                          rotation=T["geometry_msgs/msg/Quaternion"](x=q[0], y=q[1], z=q[2], w=q[3]))
    ts = T["geometry_msgs/msg/TransformStamped"](header=_header(store, ros1, ns, parent), child_frame_id=child, transform=tr)
    return T["tf2_msgs/msg/TFMessage"](transforms=[ts])


def _odom(store: Any, ros1: bool, ns: int, x: float) -> Any:
    T = store.types
    pose = T["geometry_msgs/msg/Pose"](position=T["geometry_msgs/msg/Point"](x=x, y=0.0, z=0.0),
                                       orientation=T["geometry_msgs/msg/Quaternion"](x=0.0, y=0.0, z=0.0, w=1.0))
    twist = T["geometry_msgs/msg/Twist"](linear=T["geometry_msgs/msg/Vector3"](x=1.0, y=0.0, z=0.0),
                                         angular=T["geometry_msgs/msg/Vector3"](x=0.0, y=0.0, z=0.0))
    return T["nav_msgs/msg/Odometry"](
        header=_header(store, ros1, ns, "odom"), child_frame_id="base_link",
        pose=T["geometry_msgs/msg/PoseWithCovariance"](pose=pose, covariance=np.zeros(36)),
        twist=T["geometry_msgs/msg/TwistWithCovariance"](twist=twist, covariance=np.zeros(36)))


#: Camera mounting used for /tf_static: base_link -> camera_link, 1.2 m up.
STATIC_XYZ = (0.1, 0.0, 1.2)
#: /tf: map -> odom, a fixed offset, re-published every frame.
MAP_ODOM_XYZ = (2.0, -1.0, 0.0)


def write_bag(path: Path, run: SyntheticRun, kind: BagKind = "ros1", *, rgb_topic: str = "/camera/rgb/image_color",
              depth_topic: str = "/camera/depth_registered/image_raw", info_topic: str = "/camera/rgb/camera_info",
              extra_topic: bool = True) -> Path:
    """Write ``run`` as a bag at ``path`` (a file for ROS 1, a new folder for ROS 2)."""
    from rosbags.typesys import Stores, get_typestore

    ros1 = kind == "ros1"
    store = get_typestore(Stores.ROS1_NOETIC if ros1 else Stores.ROS2_HUMBLE)
    if "tf2_msgs/msg/TFMessage" not in store.types:  # the ROS 1 store lacks it
        from rosbags.typesys import get_types_from_msg

        store.register(get_types_from_msg("geometry_msgs/TransformStamped[] transforms", "tf2_msgs/msg/TFMessage"))
    if ros1:
        from rosbags.rosbag1 import Writer as Writer1

        writer: Any = Writer1(path)
        ser = store.serialize_ros1
    else:
        from rosbags.rosbag2 import StoragePlugin
        from rosbags.rosbag2 import Writer as Writer2

        plugin = StoragePlugin.SQLITE3 if kind == "ros2-sqlite3" else StoragePlugin.MCAP
        writer = Writer2(path, version=9, storage_plugin=plugin)
        ser = store.serialize_cdr
    topics = {rgb_topic: "sensor_msgs/msg/Image", depth_topic: "sensor_msgs/msg/Image",
              info_topic: "sensor_msgs/msg/CameraInfo", "/tf": "tf2_msgs/msg/TFMessage",
              "/tf_static": "tf2_msgs/msg/TFMessage", "/odom": "nav_msgs/msg/Odometry"}
    if extra_topic:
        topics["/chatter"] = "std_msgs/msg/String"
    with writer:
        conns = {t: writer.add_connection(t, typ, typestore=store) for t, typ in topics.items()}

        def put(topic: str, log_ns: int, msg: Any) -> None:
            writer.write(conns[topic], log_ns, ser(msg, topics[topic]))

        put("/tf_static", run.t0_ns, _tf(store, ros1, 0, "base_link", "camera_link", STATIC_XYZ, (0.0, 0.0, 0.0, 1.0)))
        for i in range(run.frames):
            t = run.stamp(i)
            log_ns = t + run.log_delay_ns
            rgb = run.rgb(i)
            rgb_arr = rgb[..., ::-1] if run.rgb_encoding == "bgr8" else rgb
            put(rgb_topic, log_ns, _image(store, ros1, run, t, rgb_arr, run.rgb_encoding, "camera_rgb_optical_frame"))
            put(info_topic, log_ns, _camera_info(store, ros1, run, t))
            depth = run.depth_mm(i) if run.depth_encoding == "16UC1" else run.depth_mm(i).astype(np.float32) / 1000
            put(depth_topic, log_ns + run.depth_offset_ns,
                _image(store, ros1, run, t + run.depth_offset_ns, depth, run.depth_encoding, "camera_rgb_optical_frame"))
            put("/tf", log_ns, _tf(store, ros1, t, "map", "odom", MAP_ODOM_XYZ, (0.0, 0.0, 0.0, 1.0)))
            put("/odom", log_ns, _odom(store, ros1, t, run.odom_x(i)))
            if extra_topic:
                put("/chatter", log_ns, store.types["std_msgs/msg/String"](data=f"hello {i}"))
    return path
