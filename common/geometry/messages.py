"""Build :mod:`common.geometry.transforms` objects from messages, and messages from them.

Kept apart from :mod:`common.geometry.transforms` so that the geometry stays free of pydantic.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any, Iterable

import numpy as np

from common.geometry.occupancy import ObstacleMap
from common.geometry.transforms import FrameTreeError, PinholeCamera, RigidTransform, TransformBuffer
from common.messages.schemas import CameraInfo, Header, StaticMap, Transform, TransformBatch

if TYPE_CHECKING:
    from common.geometry.map_file import OccupancyGrid
    from common.runtime.ratelog import RateLimitedLog
    from common.runtime.service import Counters
    from common.transport.base import Subscription

__all__ = [
    "add_batch",
    "add_transform",
    "batch_from_ros",
    "camera_from_info",
    "OCCUPIED_PERCENT",
    "obstacles_from_map",
    "static_map_from_grid",
    "rigid_from_msg",
    "take_transforms",
    "transform_from_ros",
    "transform_msg",
]


def camera_from_info(info: CameraInfo) -> PinholeCamera:
    """The pinhole model of a :class:`CameraInfo` (K, D and distortion model)."""
    return PinholeCamera(
        K=np.asarray(info.K),
        width=info.width,
        height=info.height,
        D=np.asarray(info.D),
        distortion_model=info.distortion_model,
    )


def rigid_from_msg(msg: Transform) -> RigidTransform:
    """The rigid transform of a :class:`Transform` (maps child points into the parent)."""
    return RigidTransform.from_quat(msg.translation, msg.rotation_xyzw)


def transform_msg(parent: str, child: str, stamp_ns: int, tf: RigidTransform, static: bool = False) -> Transform:
    """A :class:`Transform` message of ``tf`` for the edge ``parent -> child``."""
    return Transform(
        parent_frame=parent,
        child_frame=child,
        stamp_ns=stamp_ns,
        translation=tf.translation.copy(),
        rotation_xyzw=tf.quat_xyzw,
        static=static,
    )


def add_transform(buffer: TransformBuffer, msg: Transform, static: bool = False) -> None:
    """Put one message in ``buffer``; static if ``static`` or ``msg.static``."""
    buffer.set_transform(
        msg.parent_frame, msg.child_frame, msg.stamp_ns, rigid_from_msg(msg), static=static or msg.static
    )


def add_batch(buffer: TransformBuffer, batch: TransformBatch, static: bool = False) -> int:
    """Put every transform of ``batch`` in ``buffer``; returns how many were added.

    Raises :class:`common.geometry.transforms.FrameTreeError` at the first transform that breaks
    the tree (the ones before it are kept).
    """
    for msg in batch.transforms:
        add_transform(buffer, msg, static)
    return len(batch.transforms)


def take_transforms(buffer: TransformBuffer, subscriptions: Iterable[tuple[Subscription[TransformBatch], bool]],
                    counters: Counters, log: RateLimitedLog) -> None:
    """A node's transform input: drain each ``(subscription, static)`` pair (``tf_static``
    first) into ``buffer``. A transform that breaks the frame tree is counted
    (``transforms_rejected``) and logged; the others of its batch are kept."""
    for sub, static in subscriptions:
        while (got := sub.try_recv()) is not None:
            for msg in got.msg.transforms:
                try:
                    add_transform(buffer, msg, static=static)
                except FrameTreeError as exc:
                    counters.count("transforms_rejected")
                    log.warning("tf_tree", "rejected transform from %s: %s", got.key, exc)


def transform_from_ros(ts: Any, static: bool = False) -> Transform:
    """A :class:`Transform` from a ROS ``geometry_msgs/TransformStamped``.

    Duck-typed: works with rclpy/rospy messages and with those the ``rosbags`` library
    deserializes (``header.stamp.sec`` plus ``nanosec`` (ROS 2) or ``nsecs`` (ROS 1)).
    A leading ``/`` of ROS 1 frame ids is removed.
    """
    stamp = ts.header.stamp
    secs: int = int(stamp.sec if hasattr(stamp, "sec") else stamp.secs)
    nanos: int = int(stamp.nanosec if hasattr(stamp, "nanosec") else stamp.nsecs)
    tr, rot = ts.transform.translation, ts.transform.rotation
    return Transform(
        parent_frame=str(ts.header.frame_id).lstrip("/"),
        child_frame=str(ts.child_frame_id).lstrip("/"),
        stamp_ns=int(secs) * 1_000_000_000 + int(nanos),
        translation=np.array([tr.x, tr.y, tr.z], dtype=np.float64),
        rotation_xyzw=np.array([rot.x, rot.y, rot.z, rot.w], dtype=np.float64),
        static=static,
    )


def batch_from_ros(tf_message: Any, static: bool = False, source: str = "tf") -> TransformBatch:
    """A :class:`TransformBatch` from a ROS ``tf2_msgs/TFMessage`` (``/tf``, or ``/tf_static`` with ``static``)."""
    transforms = [transform_from_ros(ts, static) for ts in tf_message.transforms]
    stamp = max((t.stamp_ns for t in transforms), default=0)
    return TransformBatch(header=Header(stamp_ns=stamp, source=source), transforms=transforms)


#: A cell of a :class:`StaticMap` at least this occupied (percent) is an obstacle: map_server's
#: ``occupied_thresh``, 0.65.
OCCUPIED_PERCENT = 65


def obstacles_from_map(grid: StaticMap, min_extent_m: float = 0.0) -> ObstacleMap:
    """The distances to a :class:`StaticMap`'s obstacles (cells at least :data:`OCCUPIED_PERCENT`
    occupied; posts under ``min_extent_m`` left out)."""
    occupied = grid.occupancy() >= OCCUPIED_PERCENT
    return ObstacleMap.from_occupied(occupied, grid.resolution, grid.origin, min_extent_m)


def static_map_from_grid(grid: OccupancyGrid, header: Header) -> StaticMap:
    """An occupancy grid (e.g. a map file's, :func:`common.geometry.map_file.read_map`) as a
    :class:`StaticMap`, as a map server publishes it: 100 occupied, 0 free, -1 unknown."""
    cells = np.where(grid.occupied, 100, np.where(grid.unknown, -1, 0)).astype(np.int8)
    h, w = cells.shape
    return StaticMap(header=header, resolution=grid.resolution, width=w, height=h, origin=grid.origin,
                     data=cells.tobytes())
