"""What a ROS 2 user sees of ``perception demo --ros2``: ``/humans/bodies/tracked`` read as
``ros2 topic echo`` would, over rmw_zenoh's wire format."""

from __future__ import annotations

from typing import Any

from common.messages.keys import Delivery
from common.transport.base import Transport
from services.ros2.core.types import CdrError, types_of
from services.ros2.core.wire import parse_attachment

__all__ = ["TrackedEcho"]


class TrackedEcho:
    """Counts the ``hri_msgs/msg/IdsList`` messages on ``/humans/bodies/tracked`` and the bodies in them."""

    def __init__(self, transport: Transport, domain_id: int = 0, topic: str = "/humans/bodies/tracked") -> None:
        self.types = types_of("jazzy")
        self.topic = topic
        self.sub = transport.subscribe_raw(self.types.key(domain_id, topic, "hri_msgs/msg/IdsList"),
                                           Delivery(latest=False, queue=1024, congestion="drop"))
        self.messages = 0
        self.invalid = 0
        self.bodies: dict[str, int] = {}
        self.last: Any = None

    def poll(self) -> None:
        while (sample := self.sub.try_recv()) is not None:
            try:
                parse_attachment(sample.attachment)
                msg = self.types.deserialize(sample.payload, "hri_msgs/msg/IdsList")
            except (ValueError, CdrError):
                self.invalid += 1
                continue
            self.messages += 1
            self.last = msg
            for body in msg.ids:
                self.bodies[body] = self.bodies.get(body, 0) + 1

    def report(self) -> dict[str, Any]:
        return {"topic": self.topic, "messages": self.messages, "invalid": self.invalid,
                "bodies": dict(sorted(self.bodies.items(), key=lambda kv: -kv[1]))}

    def line(self) -> str:
        top = ", ".join(f"{b} ({n})" for b, n in list(self.report()["bodies"].items())[:6]) or "none"
        return f"ROS 2: {self.messages} messages on {self.topic}; bodies (messages naming them): {top}"
