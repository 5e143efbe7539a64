"""ROS messages (as deserialised by rosbags, ROS 1 or ROS 2) -> perception messages.

Every function raises :class:`ConversionError` naming the problem; nothing else.

* ``sensor_msgs/Image``: rgb8, bgr8, mono8, 16UC1 (and mono16, millimetres), 32FC1
  (metres); row padding (``step``) and big-endian data are handled.
* ``sensor_msgs/CompressedImage``: jpeg or png (decoded once for its size; the
  compressed bytes are kept). ``compressedDepth`` is not supported.
* ``sensor_msgs/CameraInfo``: K, D and the distortion model.
* ``tf2_msgs/TFMessage``: one :class:`TransformBatch`, ``static`` set for /tf_static.
  Frame ids lose a leading ``/`` (ROS 1 tf).
* ``nav_msgs/Odometry``: the pose as one transform ``header.frame_id`` (odom) ->
  ``child_frame_id`` (base_link), in a TransformBatch for the tf stream.
* ``sensor_msgs/LaserScan``: :class:`LaserScan` (:meth:`LaserScan.from_ros`: every field, the
  frame id without a leading ``/``, ranges and intensities as float32).
"""

from __future__ import annotations

from typing import Any

import numpy as np

from common.messages.schemas import CameraInfo, Header, Image, LaserScan, Transform, TransformBatch

__all__ = ["ConversionError", "camera_info", "compressed_image", "image", "laser_scan", "odometry", "stamp_ns",
           "tf_message"]

_RAW: dict[str, tuple[str, str, int]] = {  # ROS encoding -> (our encoding, dtype, channels)
    "rgb8": ("rgb8", "uint8", 3),
    "bgr8": ("bgr8", "uint8", 3),
    "mono8": ("mono8", "uint8", 1),
    "8UC1": ("mono8", "uint8", 1),
    "16UC1": ("16UC1", "uint16", 1),
    "mono16": ("16UC1", "uint16", 1),
    "32FC1": ("32FC1", "float32", 1),
}
_DISTORTION = {"plumb_bob": "plumb_bob", "rational_polynomial": "rational_polynomial",
               "equidistant": "equidistant", "fisheye": "equidistant", "": "none", "none": "none"}


class ConversionError(ValueError):
    """A ROS message that cannot become a perception message."""


def _reason(exc: ValueError) -> str:
    """A rejected message's reason in one line: pydantic's errors (field: why), else the text."""
    errors = getattr(exc, "errors", None)
    if callable(errors):
        return "; ".join(("/".join(map(str, e["loc"])) + ": " if e["loc"] else "")
                         + str(e["msg"]).removeprefix("Value error, ") for e in errors())
    return str(exc).splitlines()[0] if str(exc) else type(exc).__name__


def stamp_ns(header: Any) -> int:
    """ROS ``header.stamp`` (sec, nanosec) as integer nanoseconds."""
    s = header.stamp
    return int(s.sec) * 1_000_000_000 + int(s.nanosec)


def _frame(name: str) -> str:
    return name.lstrip("/")


def _header(msg: Any, source: str, seq: int) -> Header:
    h = msg.header
    return Header(stamp_ns=max(0, stamp_ns(h)), frame_id=_frame(h.frame_id), seq=seq, source=source)


def image(msg: Any, source: str, seq: int = 0) -> Image:
    """``sensor_msgs/Image`` -> :class:`Image` (raw pixels copied, padding removed)."""
    layout = _RAW.get(msg.encoding)
    if layout is None:
        raise ConversionError(f"image encoding {msg.encoding!r} is not supported (supported: {', '.join(_RAW)})")
    enc, dtype, channels = layout
    h, w, step = int(msg.height), int(msg.width), int(msg.step)
    dt = np.dtype(dtype).newbyteorder(">" if msg.is_bigendian else "<")
    row = w * channels * dt.itemsize
    data = np.asarray(msg.data, dtype=np.uint8)
    if h <= 0 or w <= 0 or step < row or data.size < step * (h - 1) + row:
        raise ConversionError(f"image of {w}x{h} {msg.encoding} with step {step} has only {data.size} bytes")
    rows = np.lib.stride_tricks.as_strided(data, shape=(h, row), strides=(step, 1))
    pixels = np.ascontiguousarray(rows).view(dt).astype(dt.newbyteorder("="), copy=False)
    shape = (h, w, channels) if channels > 1 else (h, w)
    return Image.from_array(pixels.reshape(shape), enc, _header(msg, source, seq))  # type: ignore[arg-type]


def compressed_image(msg: Any, source: str, seq: int = 0) -> Image:
    """``sensor_msgs/CompressedImage`` (jpeg/png) -> :class:`Image` with the same bytes."""
    import cv2

    fmt = str(msg.format).lower()
    if "compresseddepth" in fmt:
        raise ConversionError(f"compressed depth ({msg.format!r}) is not supported; record raw depth images")
    data = bytes(np.asarray(msg.data, dtype=np.uint8))
    if data[:3] == b"\xff\xd8\xff":
        enc = "jpeg"
    elif data[:8] == b"\x89PNG\r\n\x1a\n":
        enc = "png"
    else:
        raise ConversionError(f"compressed image format {msg.format!r} is neither jpeg nor png")
    decoded = cv2.imdecode(np.frombuffer(data, np.uint8), cv2.IMREAD_UNCHANGED)
    if decoded is None:
        raise ConversionError(f"{enc} data could not be decoded")
    return Image(header=_header(msg, source, seq), encoding=enc, dtype=decoded.dtype.name,  # type: ignore[arg-type]
                 shape=decoded.shape, data=data)


def camera_info(msg: Any, source: str, seq: int = 0) -> CameraInfo:
    """``sensor_msgs/CameraInfo`` (ROS 1 ``K``/``D`` or ROS 2 ``k``/``d``) -> :class:`CameraInfo`."""
    k = np.asarray(msg.K if hasattr(msg, "K") else msg.k, dtype=np.float64)
    d = np.asarray(msg.D if hasattr(msg, "D") else msg.d, dtype=np.float64)
    model = _DISTORTION.get(str(msg.distortion_model))
    if model is None:
        raise ConversionError(f"distortion model {msg.distortion_model!r} is not supported")
    if model == "none" and np.any(d):
        model = "plumb_bob"
    if model == "none":
        d = np.zeros(0)
    elif model == "plumb_bob" and len(d) > 5 and not np.any(d[5:]):
        d = d[:5]
    try:
        return CameraInfo(header=_header(msg, source, seq), width=int(msg.width), height=int(msg.height),
                          K=k.reshape(3, 3), D=d, distortion_model=model)  # type: ignore[arg-type]
    except ValueError as exc:  # pydantic's ValidationError is a ValueError
        raise ConversionError(f"camera info rejected: {_reason(exc)}") from exc


def _transform(parent: str, child: str, stamp: int, t: Any, q: Any, static: bool) -> Transform:
    return Transform(parent_frame=_frame(parent), child_frame=_frame(child), stamp_ns=max(0, stamp),
                     translation=np.array([t.x, t.y, t.z], dtype=np.float64),
                     rotation_xyzw=np.array([q.x, q.y, q.z, q.w], dtype=np.float64), static=static)


def tf_message(msg: Any, static: bool, source: str = "tf") -> tuple[TransformBatch, int]:
    """``tf2_msgs/TFMessage`` -> (batch, number of invalid transforms left out)."""
    out: list[Transform] = []
    bad = 0
    for ts in msg.transforms:
        try:
            out.append(_transform(ts.header.frame_id, ts.child_frame_id, stamp_ns(ts.header),
                                  ts.transform.translation, ts.transform.rotation, static))
        except ValueError:
            bad += 1
    if not out:
        raise ConversionError(f"none of the {len(msg.transforms)} transforms is valid")
    stamp = max(t.stamp_ns for t in out)
    return TransformBatch(header=Header(stamp_ns=stamp, source=source), transforms=out), bad


def odometry(msg: Any, source: str = "odom") -> TransformBatch:
    """``nav_msgs/Odometry`` -> a batch of one transform ``frame_id -> child_frame_id``."""
    parent = _frame(msg.header.frame_id) or "odom"
    child = _frame(msg.child_frame_id) or "base_link"
    stamp = stamp_ns(msg.header)
    try:
        tr = _transform(parent, child, stamp, msg.pose.pose.position, msg.pose.pose.orientation, False)
    except ValueError as exc:
        raise ConversionError(f"odometry pose rejected: {_reason(exc)}") from exc
    return TransformBatch(header=Header(stamp_ns=max(0, stamp), frame_id=parent, source=source), transforms=[tr])


def laser_scan(msg: Any, source: str, seq: int = 0) -> LaserScan:
    """``sensor_msgs/LaserScan`` -> :class:`LaserScan` of the laser ``source``."""
    try:
        return LaserScan.from_ros(msg, source, seq)
    except ValueError as exc:  # pydantic's ValidationError is a ValueError
        raise ConversionError(f"laser scan rejected: {_reason(exc)}") from exc
