"""The tracker's people as ROS 2 messages, in ROS4HRI's conventions (REP 155) and for RViz.

- ``/humans/bodies/tracked`` (``hri_msgs/msg/IdsList``): the confirmed bodies' IDs;
- ``/humans/bodies/<id>/position`` (``geometry_msgs/msg/PointStamped``) and ``/velocity``
  (``geometry_msgs/msg/TwistStamped``), in the tracking frame, as ``hri_fullbody`` publishes them;
- ``/humans/bodies/<id>/posture`` (``hri_msgs/msg/BodyPosture``) when the tracker knows it;
- a ``body_<id>`` frame per body on ``/tf``: at the person's position, its x axis along the
  direction the upper body faces when the tracker knows it, else along the tracking frame's x;
- ``/humans/markers`` (``visualization_msgs/msg/MarkerArray``): a cylinder and the ID per body,
  deleted when the body is no longer tracked.

A ROS 2 name token must not start with a digit, so a body's ID is ``<prefix><track id>``
(``p7``: ``/humans/bodies/p7/position``, frame ``body_p7``). Pure: takes plain
:class:`Person` records and returns ``(topic, type, message)``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np

from services.ros2.core.types import RosTypes

__all__ = ["Person", "PeopleWriter", "body_id"]

POSTURES = ("standing", "sitting", "lying")
#: hri_msgs/BodyPosture: STANDING 1, SITTING 2, LAYING 4.
_POSTURE_CODE = {"standing": 1, "sitting": 2, "lying": 4}
#: A distribution is 'known' when its largest share beats uniform by this much.
_KNOWN_MARGIN = 0.15


@dataclass(frozen=True)
class Person:
    """One confirmed track, in the tracking frame."""

    track_id: int
    position: tuple[float, float, float]
    velocity: tuple[float, float, float]
    #: P(standing, sitting, lying); uniform: unknown.
    posture: tuple[float, ...] = (1 / 3, 1 / 3, 1 / 3)
    #: P(upper body faces bin k), bin k centred on k * 45 degrees from the frame's x axis.
    orientation: tuple[float, ...] = (1 / 8,) * 8

    def posture_name(self) -> str | None:
        p = np.asarray(self.posture, float)
        if p.size != 3 or p.max() < 1 / 3 + _KNOWN_MARGIN:
            return None
        return POSTURES[int(p.argmax())]

    def facing_rad(self) -> float | None:
        """The direction the upper body faces (circular mean of the bins), or None when unknown."""
        p = np.asarray(self.orientation, float)
        if p.size != 8 or p.max() < 1 / 8 + _KNOWN_MARGIN:
            return None
        angles = np.arange(8) * (math.pi / 4)
        return float(math.atan2(float(p @ np.sin(angles)), float(p @ np.cos(angles))))


def body_id(track_id: int, prefix: str = "p") -> str:
    return f"{prefix}{track_id}"


class PeopleWriter:
    """Turns each Tracks output into the ROS 2 messages of its people.

    It remembers which bodies it has published, so that a body that is no longer tracked gets
    its markers deleted once.
    """

    def __init__(self, types: RosTypes, *, frame: str = "map", prefix: str = "p", namespace: str = "/humans",
                 markers_topic: str = "/humans/markers", marker_lifetime_s: float = 2.0) -> None:
        self.t = types
        self.frame = frame
        self.prefix = prefix
        self.ns = "/" + namespace.strip("/")
        self.markers_topic = markers_topic
        self.lifetime_s = marker_lifetime_s
        self._shown: set[int] = set()

    # --- message parts
    def _header(self, stamp_ns: int) -> Any:
        return self.t.header(stamp_ns, self.frame)

    def _vec(self, v: tuple[float, float, float]) -> Any:
        return self.t.cls("geometry_msgs/msg/Vector3")(x=float(v[0]), y=float(v[1]), z=float(v[2]))

    def _quat_yaw(self, yaw: float | None) -> Any:
        q = self.t.cls("geometry_msgs/msg/Quaternion")
        if yaw is None:
            return q(x=0.0, y=0.0, z=0.0, w=1.0)
        return q(x=0.0, y=0.0, z=math.sin(yaw / 2), w=math.cos(yaw / 2))

    def topic(self, person_or_id: Person | int, leaf: str) -> str:
        tid = person_or_id.track_id if isinstance(person_or_id, Person) else person_or_id
        return f"{self.ns}/bodies/{body_id(tid, self.prefix)}/{leaf}"

    # --- the messages of one output
    def tracked(self, stamp_ns: int, people: list[Person]) -> tuple[str, str, Any]:
        ids = [body_id(p.track_id, self.prefix) for p in people]
        msg = self.t.cls("hri_msgs/msg/IdsList")(header=self._header(stamp_ns), ids=ids)
        return f"{self.ns}/bodies/tracked", "hri_msgs/msg/IdsList", msg

    def per_body(self, stamp_ns: int, person: Person) -> list[tuple[str, str, Any]]:
        header = self._header(stamp_ns)
        point = self.t.cls("geometry_msgs/msg/Point")(x=float(person.position[0]), y=float(person.position[1]),
                                                     z=float(person.position[2]))
        out = [
            (self.topic(person, "position"), "geometry_msgs/msg/PointStamped",
             self.t.cls("geometry_msgs/msg/PointStamped")(header=header, point=point)),
            (self.topic(person, "velocity"), "geometry_msgs/msg/TwistStamped",
             self.t.cls("geometry_msgs/msg/TwistStamped")(
                 header=header, twist=self.t.cls("geometry_msgs/msg/Twist")(linear=self._vec(person.velocity),
                                                                            angular=self._vec((0.0, 0.0, 0.0))))),
        ]
        if (posture := person.posture_name()) is not None:
            out.append((self.topic(person, "posture"), "hri_msgs/msg/BodyPosture",
                        self.t.cls("hri_msgs/msg/BodyPosture")(header=header, posture=_POSTURE_CODE[posture])))
        return out

    def transforms(self, stamp_ns: int, people: list[Person]) -> tuple[str, str, Any] | None:
        """``body_<id>`` frames on ``/tf`` (None when nobody is tracked)."""
        if not people:
            return None
        tf = self.t.cls("geometry_msgs/msg/TransformStamped")
        transforms = [
            tf(header=self._header(stamp_ns), child_frame_id=f"body_{body_id(p.track_id, self.prefix)}",
               transform=self.t.cls("geometry_msgs/msg/Transform")(
                   translation=self._vec(p.position), rotation=self._quat_yaw(p.facing_rad())))
            for p in people
        ]
        return "/tf", "tf2_msgs/msg/TFMessage", self.t.cls("tf2_msgs/msg/TFMessage")(transforms=transforms)

    def markers(self, stamp_ns: int, people: list[Person]) -> tuple[str, str, Any] | None:
        """A cylinder (1.7 m, 0.5 m across, standing on the floor) and a text with the ID per body,
        and DELETE for the bodies shown before and gone now. None when there is nothing to say."""
        marker = self.t.cls("visualization_msgs/msg/Marker")
        colour = self.t.cls("std_msgs/msg/ColorRGBA")
        duration = self.t.cls("builtin_interfaces/msg/Duration")
        life = duration(sec=int(self.lifetime_s), nanosec=int((self.lifetime_s % 1) * 1e9))
        pose = self.t.cls("geometry_msgs/msg/Pose")
        point = self.t.cls("geometry_msgs/msg/Point")
        header = self._header(stamp_ns)
        now = {p.track_id for p in people}
        out = []

        def make(tid: int, ns: str, kind: int, action: int, position: tuple[float, float, float] = (0.0, 0.0, 0.0),
                 scale: tuple[float, float, float] = (0.0, 0.0, 0.0), text: str = "") -> Any:
            rgb = _colour_of(tid)
            return marker(header=header, ns=ns, id=tid, type=kind, action=action,
                          pose=pose(position=point(x=position[0], y=position[1], z=position[2]),
                                    orientation=self._quat_yaw(None)),
                          scale=self._vec(scale), color=colour(r=rgb[0], g=rgb[1], b=rgb[2], a=0.8 if kind == 3 else 1.0),
                          lifetime=life, frame_locked=False, points=[], colors=[], texture_resource="",
                          texture=self.t.cls("sensor_msgs/msg/CompressedImage")(header=header, format="", data=np.zeros(0, np.uint8)),
                          uv_coordinates=[], text=text, mesh_resource="",
                          mesh_file=self.t.cls("visualization_msgs/msg/MeshFile")(filename="", data=np.zeros(0, np.uint8)),
                          mesh_use_embedded_materials=False)

        for p in people:
            x, y, _ = (float(v) for v in p.position)
            out.append(make(p.track_id, "people", 3, 0, (x, y, 0.85), (0.5, 0.5, 1.7)))  # CYLINDER, ADD
            out.append(make(p.track_id, "people_ids", 9, 0, (x, y, 1.95), (0.0, 0.0, 0.3),  # TEXT_VIEW_FACING
                            text=body_id(p.track_id, self.prefix)))
        for tid in sorted(self._shown - now):
            out.append(make(tid, "people", 3, 2))  # DELETE
            out.append(make(tid, "people_ids", 9, 2))
        self._shown = now
        if not out:
            return None
        return self.markers_topic, "visualization_msgs/msg/MarkerArray", self.t.cls("visualization_msgs/msg/MarkerArray")(
            markers=out)

    def messages(self, stamp_ns: int, people: list[Person]) -> list[tuple[str, str, Any]]:
        """Everything one tracker output becomes, in the order a consumer wants it."""
        out = [self.tracked(stamp_ns, people)]
        for p in people:
            out += self.per_body(stamp_ns, p)
        for extra in (self.transforms(stamp_ns, people), self.markers(stamp_ns, people)):
            if extra is not None:
                out.append(extra)
        return out


def _colour_of(track_id: int) -> tuple[float, float, float]:
    """A stable, distinct colour per ID (golden-angle hues)."""
    h = (track_id * 0.618033988749895) % 1.0
    i = int(h * 6)
    f = h * 6 - i
    q, t = 1 - f, f
    return [(1, t, 0), (q, 1, 0), (0, 1, t), (0, q, 1), (t, 0, 1), (1, 0, q)][i % 6]
