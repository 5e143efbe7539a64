"""The simulated robot as a ROS 2 robot (``perception simulate --ros2``): its head camera as
the RealSense ROS 2 driver publishes it (rgb8 colour, 16UC1 depth aligned to colour, camera
info, on the driver's default topics), its transforms on ``/tf`` and ``/tf_static``, its map
on ``/map`` (as Nav2's map_server: once, transient local) and, with ``--laser``, its base laser on
``/scan``,
through rmw_zenoh's wire format. The ``perception ros2`` node reads them back into this
project's streams, as it would on a real ROS 2 robot."""

from __future__ import annotations

from typing import Any

from common.messages.schemas import LaserScan, RGBDFrame, StaticMap, TransformBatch
from common.transport.base import Transport
from services.ros2.config import Ros2Config
from services.ros2.convert import camera_info_message, image_message, scan_message, tf_message
from services.ros2.core.types import types_of
from services.ros2.maps import occupancy_grid_message
from services.ros2.participant import QOS_SENSOR, QOS_TF, QOS_TF_STATIC, RosParticipant

__all__ = ["RosRobot"]

_DEFAULTS = Ros2Config(domain_id=0)


class _Out:
    """A publisher-shaped adapter (``key``, ``published``, ``put``), so the simulator and its
    status treat it like its other publishers."""

    def __init__(self, key: str, send: Any, matching: Any) -> None:
        self.key = key
        self._send = send
        self._matching = matching
        self.published = 0
        self.unmatched = 0

    def put(self, msg: Any) -> None:
        self._send(msg)
        self.published += 1

    def has_subscribers(self) -> bool:
        return bool(self._matching())

    def close(self) -> None:
        pass


class RosRobot:
    """A ROS 2 node ``camera`` with the camera's three topics, and tf's two."""

    def __init__(self, transport: Transport, domain_id: int = 0) -> None:
        self.types = types_of("jazzy")
        self.ros = RosParticipant(transport, self.types, domain_id=domain_id, node_name="camera", namespace="/camera")
        c = _DEFAULTS
        self.colour = self.ros.publisher(c.colour_topic, "sensor_msgs/msg/Image", QOS_SENSOR)
        self.depth = self.ros.publisher(c.depth_topic, "sensor_msgs/msg/Image", QOS_SENSOR)
        self.info = self.ros.publisher(c.camera_info_topic, "sensor_msgs/msg/CameraInfo", QOS_SENSOR)
        self.tf = self.ros.publisher(c.tf_topic, "tf2_msgs/msg/TFMessage", QOS_TF)
        self.tf_static = self.ros.publisher(c.tf_static_topic, "tf2_msgs/msg/TFMessage", QOS_TF_STATIC)
        # the robot's map server: /map once, transient local (kept for late joiners)
        self.map = self.ros.publisher(c.map_topic, "nav_msgs/msg/OccupancyGrid", QOS_TF_STATIC, cache=1)

    def publish_map(self, grid: StaticMap) -> None:
        self.map.put(occupancy_grid_message(self.types, grid), grid.header.stamp_ns)

    def _frame(self, frame: RGBDFrame) -> None:
        stamp = frame.header.stamp_ns
        self.info.put(camera_info_message(self.types, frame), stamp)
        if frame.depth is not None:
            self.depth.put(image_message(self.types, frame, depth=True), stamp)
        self.colour.put(image_message(self.types, frame), stamp)

    def laser(self, topic: str = "/scan") -> _Out:
        """The base laser's driver: ``sensor_msgs/msg/LaserScan`` on ``topic``."""
        pub = self.ros.publisher(topic, "sensor_msgs/msg/LaserScan", QOS_SENSOR)

        def send(scan: LaserScan) -> None:
            pub.put(scan_message(self.types, scan), scan.header.stamp_ns)

        return _Out(pub.key, send, pub.pub.has_subscribers)

    def camera(self) -> _Out:
        return _Out(self.colour.key, self._frame, self.colour.pub.has_subscribers)

    def transforms(self, static: bool) -> _Out:
        pub = self.tf_static if static else self.tf

        def send(batch: TransformBatch) -> None:
            pub.put(tf_message(self.types, batch), batch.header.stamp_ns)

        return _Out(pub.key, send, pub.pub.has_subscribers)

    def close(self) -> None:
        self.ros.close()
