"""The robot's map between ROS 2 (``nav_msgs/msg/OccupancyGrid``, what Nav2's map_server and
slam_toolbox publish on ``/map``) and this project's :class:`~common.messages.schemas.StaticMap`.
Both keep the grid as ROS does: row 0 at the lowest y, one signed byte per cell (percent, -1
unknown); the origin's pose is reduced to its yaw (a map lies on the floor)."""

from __future__ import annotations

import math
from typing import Any, Callable

import numpy as np

from common.messages.schemas import Header, StaticMap
from services.ros2.core.types import RosTypes

__all__ = ["MapRelay", "occupancy_grid_message", "static_map_from_ros"]


def static_map_from_ros(msg: Any, source: str = "ros2") -> StaticMap:
    """A ``nav_msgs/msg/OccupancyGrid`` as a :class:`StaticMap` (ValueError when inconsistent)."""
    info = msg.info
    q = info.origin.orientation
    yaw = math.atan2(2.0 * (q.w * q.z + q.x * q.y), 1.0 - 2.0 * (q.y * q.y + q.z * q.z))
    stamp = int(msg.header.stamp.sec) * 1_000_000_000 + int(msg.header.stamp.nanosec)
    data = np.asarray(msg.data, np.int8).tobytes()
    return StaticMap(header=Header(stamp_ns=max(stamp, 0), frame_id=str(msg.header.frame_id), source=source),
                     resolution=float(info.resolution), width=int(info.width), height=int(info.height),
                     origin=(float(info.origin.position.x), float(info.origin.position.y), yaw), data=data)


def occupancy_grid_message(types: RosTypes, grid: StaticMap) -> Any:
    """A :class:`StaticMap` as ``nav_msgs/msg/OccupancyGrid`` (for a stand-in robot and tests)."""
    x, y, yaw = grid.origin
    pose = types.cls("geometry_msgs/msg/Pose")(
        position=types.cls("geometry_msgs/msg/Point")(x=x, y=y, z=0.0),
        orientation=types.cls("geometry_msgs/msg/Quaternion")(x=0.0, y=0.0, z=math.sin(yaw / 2), w=math.cos(yaw / 2)))
    header = types.header(grid.header.stamp_ns, grid.header.frame_id)
    info = types.cls("nav_msgs/msg/MapMetaData")(map_load_time=header.stamp, resolution=grid.resolution,
                                                 width=grid.width, height=grid.height, origin=pose)
    return types.cls("nav_msgs/msg/OccupancyGrid")(header=header, info=info, data=grid.occupancy().reshape(-1).copy())



class MapRelay:
    """``/map`` to ``static_map``: each map received goes out at once (``send``), and the newest
    again every ``period_s`` for this project's late joiners (``poll``)."""

    def __init__(self, send: Callable[[StaticMap], None], period_s: float) -> None:
        self.send, self.period_s = send, period_s
        self.latest: StaticMap | None = None
        self.received = 0
        self._sent_at = -1e9

    def take(self, msg: Any, now: float) -> None:
        self.latest = static_map_from_ros(msg)
        self.received += 1
        self._sent_at = now
        self.send(self.latest)

    def poll(self, now: float) -> None:
        if self.latest is not None and now - self._sent_at >= self.period_s:
            self._sent_at = now
            self.send(self.latest)
