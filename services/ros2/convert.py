"""This project's frames, laser scans and transforms as ROS 2 messages: what a ROS 2 camera
driver, a laser driver and tf publish. For a stand-in ROS 2 robot (``perception simulate --ros2``) and for tests."""

from __future__ import annotations

from typing import Any

import numpy as np

from common.messages.schemas import Header, LaserScan, RGBDFrame, TransformBatch
from services.ros2.core.types import RosTypes

__all__ = ["camera_info_message", "header_message", "image_message", "scan_message", "tf_message"]


def header_message(types: RosTypes, header: Header, frame_id: str | None = None) -> Any:
    return types.header(header.stamp_ns, header.frame_id if frame_id is None else frame_id)


def image_message(types: RosTypes, frame: RGBDFrame, depth: bool = False) -> Any:
    """The frame's colour (or depth) image as ``sensor_msgs/msg/Image``, raw (a compressed image is
    decoded: rgb8 for colour, 16UC1 millimetres for depth)."""
    img = frame.depth if depth else frame.rgb
    if img is None:
        raise ValueError("the frame has no depth image")
    if img.encoding in ("jpeg", "png"):
        arr = img.to_array()
        encoding = "16UC1" if arr.dtype == np.uint16 else ("rgb8" if arr.ndim == 3 else "mono8")
    else:
        arr = np.frombuffer(img.data, dtype=img.dtype).reshape(img.shape)
        encoding = img.encoding
    arr = np.ascontiguousarray(arr)
    h, w = arr.shape[:2]
    return types.cls("sensor_msgs/msg/Image")(
        header=header_message(types, frame.header), height=h, width=w, encoding=encoding, is_bigendian=0,
        step=arr.strides[0], data=arr.reshape(-1).view(np.uint8))


def camera_info_message(types: RosTypes, frame: RGBDFrame) -> Any:
    info = frame.camera_info
    d = np.asarray(info.D, dtype=np.float64)
    model = info.distortion_model if info.distortion_model != "none" else "plumb_bob"
    if info.distortion_model == "none":
        d = np.zeros(5)
    k = np.asarray(info.K, dtype=np.float64)
    p = np.zeros((3, 4))
    p[:, :3] = k
    roi = types.cls("sensor_msgs/msg/RegionOfInterest")(x_offset=0, y_offset=0, height=0, width=0, do_rectify=False)
    return types.cls("sensor_msgs/msg/CameraInfo")(
        header=header_message(types, frame.header), height=info.height, width=info.width, distortion_model=model,
        d=d, k=k.reshape(-1), r=np.eye(3).reshape(-1), p=p.reshape(-1), binning_x=0, binning_y=0, roi=roi)


def tf_message(types: RosTypes, batch: TransformBatch) -> Any:
    """A transform batch as ``tf2_msgs/msg/TFMessage``."""
    ts_cls = types.cls("geometry_msgs/msg/TransformStamped")
    vec, quat = types.cls("geometry_msgs/msg/Vector3"), types.cls("geometry_msgs/msg/Quaternion")
    out = []
    for t in batch.transforms:
        header = header_message(types, Header(stamp_ns=t.stamp_ns), frame_id=t.parent_frame)
        x, y, z = (float(v) for v in t.translation)
        qx, qy, qz, qw = (float(v) for v in t.rotation_xyzw)
        out.append(ts_cls(header=header, child_frame_id=t.child_frame, transform=types.cls("geometry_msgs/msg/Transform")(
            translation=vec(x=x, y=y, z=z), rotation=quat(x=qx, y=qy, z=qz, w=qw))))
    return types.cls("tf2_msgs/msg/TFMessage")(transforms=out)


def scan_message(types: RosTypes, scan: LaserScan) -> Any:
    """The scan as ``sensor_msgs/msg/LaserScan``, as a laser driver publishes it."""
    intensities = np.zeros(0, np.float32) if scan.intensities is None else np.asarray(scan.intensities, np.float32)
    return types.cls("sensor_msgs/msg/LaserScan")(
        header=header_message(types, scan.header), angle_min=float(scan.angle_min), angle_max=float(scan.angle_max),
        angle_increment=float(scan.angle_increment), time_increment=float(scan.time_increment),
        scan_time=float(scan.scan_time), range_min=float(scan.range_min), range_max=float(scan.range_max),
        ranges=np.ascontiguousarray(scan.ranges, np.float32), intensities=intensities)
