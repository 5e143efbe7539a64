"""ROS 2 message types, their RIHS01 hashes and CDR, from ``rosbags`` (pure Python, no ROS install).

The type store is the one of a ROS 2 distribution (``jazzy`` by default); the ROS4HRI messages
this node publishes (``hri_msgs/msg/IdsList``, ``hri_msgs/msg/BodyPosture``) are registered from
their definitions, which ship here. Every hash is computed by ``rosbags``, never written by hand.
"""

from __future__ import annotations

from functools import lru_cache
from typing import Any

from rosbags.typesys import Stores, get_types_from_msg, get_typestore

from services.ros2.core.wire import data_key, ros_to_dds

__all__ = ["DISTROS", "HRI_MSGS", "CdrError", "RosTypes"]

#: The distributions this node speaks to (they share every hash it uses). Humble's rmw_zenoh
#: writes no type hash, so it cannot talk to Jazzy or later, nor to this node.
DISTROS: dict[str, Stores] = {"jazzy": Stores.ROS2_JAZZY, "kilted": Stores.ROS2_KILTED, "rolling": Stores.ROS2_LYRICAL}

#: ROS4HRI's messages this node publishes, as in ``ros4hri/hri_msgs`` (REP 155).
HRI_MSGS: dict[str, str] = {
    "hri_msgs/msg/IdsList": "std_msgs/Header header\nstring[] ids\n",
    "hri_msgs/msg/BodyPosture": ("std_msgs/Header header\n\nuint8 STANDING = 1\nuint8 SITTING = 2\nuint8 CROUCHING = 3\n"
                                 "uint8 LAYING = 4\n\nuint8 OTHER = 0\n\nuint8 posture\n"),
}


class CdrError(ValueError):
    """A payload that is not a CDR message of the expected type (truncated, garbage)."""


class RosTypes:
    """The message classes, hashes and CDR codec of one distribution's type store."""

    def __init__(self, distro: str = "jazzy") -> None:
        if distro not in DISTROS:
            raise ValueError(f"ROS 2 distribution {distro!r} is not one of {', '.join(DISTROS)}")
        self.distro = distro
        self.store = get_typestore(DISTROS[distro])
        for name, text in HRI_MSGS.items():
            self.store.register(get_types_from_msg(text, name))
        self._hashes: dict[str, str] = {}

    def cls(self, type_name: str) -> Any:
        """The message class (a dataclass) of ``pkg/msg/Name``."""
        try:
            return self.store.types[type_name]
        except KeyError:
            raise ValueError(f"unknown ROS 2 message type {type_name!r}") from None

    def hash(self, type_name: str) -> str:
        if type_name not in self._hashes:
            self.cls(type_name)
            self._hashes[type_name] = self.store.hash_rihs01(type_name)
        return self._hashes[type_name]

    def key(self, domain_id: int, topic: str, type_name: str) -> str:
        """The topic's data key, as rmw_zenoh builds it."""
        return data_key(domain_id, topic, ros_to_dds(type_name), self.hash(type_name))

    def header(self, stamp_ns: int, frame_id: str) -> Any:
        """A ``std_msgs/msg/Header`` of a stamp in ns since the epoch."""
        stamp = self.cls("builtin_interfaces/msg/Time")(sec=stamp_ns // 1_000_000_000, nanosec=stamp_ns % 1_000_000_000)
        return self.cls("std_msgs/msg/Header")(stamp=stamp, frame_id=frame_id)

    def definition(self, type_name: str) -> str:
        """The message definition text (with its dependencies), as a ROS 2 tool would show it."""
        return self.store.generate_msgdef(type_name, ros_version=2)[0]

    def serialize(self, msg: Any, type_name: str) -> bytes:
        """The 4-byte encapsulation header (little endian) and classic CDR."""
        return bytes(self.store.serialize_cdr(msg, type_name))

    def deserialize(self, data: bytes | memoryview, type_name: str) -> Any:
        """The message in ``data``; :class:`CdrError` for anything that is not one."""
        if len(data) < 4:
            raise CdrError(f"{len(data)} bytes: too short for the CDR encapsulation header")
        if bytes(data[:2]) not in (b"\x00\x00", b"\x00\x01"):
            raise CdrError(f"encapsulation header {bytes(data[:4]).hex()} is not plain CDR (00 00 or 00 01)")
        try:
            return self.store.deserialize_cdr(bytes(data), type_name)
        except Exception as exc:  # rosbags raises struct/index/unicode/assertion errors on garbage
            raise CdrError(f"not a {type_name} in CDR: {type(exc).__name__}: {exc}"[:300]) from exc


@lru_cache(maxsize=None)
def types_of(distro: str = "jazzy") -> RosTypes:
    """One shared :class:`RosTypes` per distribution (building a store costs ~0.1 s)."""
    return RosTypes(distro)


def known_hashes(type_name: str) -> dict[str, str]:
    """``type_name``'s hash in every distribution this node knows: hash -> distributions."""
    out: dict[str, str] = {}
    for distro in DISTROS:
        h = types_of(distro).hash(type_name)
        out[h] = f"{out[h]}, {distro}" if h in out else distro
    return out
