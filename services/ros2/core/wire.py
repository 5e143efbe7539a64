"""rmw_zenoh's wire format: the data key of a topic, the graph's liveliness tokens, the QoS
text in them and the attachment every sample carries.

From ``ros2/rmw_zenoh``'s ``docs/design.md`` and ``rmw_zenoh_cpp/src/detail/``
(``liveliness_utils.cpp``, ``attachment_helpers.cpp``, ``qos.cpp``); the layouts are those of
Jazzy >= 0.2.4, Kilted and Rolling (Jazzy 0.2.0-0.2.3 used another attachment layout, and
Humble writes no type hash). Pure Python: no Zenoh here, so that every format is testable
byte for byte.
"""

from __future__ import annotations

import hashlib
import struct
from dataclasses import dataclass
from typing import Literal

__all__ = ["ADMIN_SPACE", "ATTACHMENT_SIZE", "Attachment", "GraphEntity", "Qos", "attachment", "data_key", "entity_gid",
           "mangle", "parse_attachment", "parse_token", "unmangle"]

#: The key space of rmw_zenoh's graph (liveliness tokens); hermetic: ``**`` does not match it.
ADMIN_SPACE = "@ros2_lv"
#: int64 sequence number, int64 source timestamp (ns), the GID's length (16) and the GID.
ATTACHMENT_SIZE = 33
_GID_SIZE = 16

Kind = Literal["NN", "MP", "MS", "SS", "SC"]
_KINDS = ("NN", "MP", "MS", "SS", "SC")


def mangle(name: str) -> str:
    """A name as one key chunk: every ``/`` becomes ``%`` (``/`` alone becomes ``%``)."""
    return name.replace("/", "%")


def unmangle(chunk: str) -> str:
    return chunk.replace("%", "/")


def _strip(topic: str) -> str:
    return topic.strip("/")


def data_key(domain_id: int, topic: str, dds_type: str, type_hash: str) -> str:
    """``<domain>/<topic without leading and trailing '/'>/<pkg>::msg::dds_::<Name>_/<RIHS01_...>``."""
    if not topic.strip("/"):
        raise ValueError(f"topic {topic!r} is empty")
    if "//" in _strip(topic) or any(c in topic for c in "*$?# "):
        raise ValueError(f"topic {topic!r} is not a valid ROS 2 topic name")
    return f"{domain_id}/{_strip(topic)}/{dds_type}/{type_hash}"


@dataclass(frozen=True)
class Qos:
    """The QoS policies the graph shows (rmw_zenoh's defaults: reliable, volatile, keep last 42)."""

    reliable: bool = True
    transient_local: bool = False
    keep_all: bool = False
    depth: int = 42

    def text(self) -> str:
        """The QoS field of a token: a value is left empty where it is rmw_zenoh's default.

        ``<rel>:<dur>:<hist>,<depth>:<deadline s>,<ns>:<lifespan s>,<ns>:<liveliness>,<lease s>,<ns>``;
        RELIABLE 1, BEST_EFFORT 2; TRANSIENT_LOCAL 1, VOLATILE 2; KEEP_LAST 1, KEEP_ALL 2. This
        project's entities keep infinite deadline, lifespan and lease and AUTOMATIC liveliness.
        """
        rel = "" if self.reliable else "2"
        dur = "1" if self.transient_local else ""
        hist = "2" if self.keep_all else ""
        depth = "" if self.depth == 42 else str(self.depth)
        return f"{rel}:{dur}:{hist},{depth}:,:,:,,"

    @classmethod
    def parse(cls, text: str) -> Qos:
        """The policies of a token's QoS field; ValueError when it is not one."""
        parts = text.split(":")
        if len(parts) < 6 or len(parts[2].split(",")) < 2:
            raise ValueError(f"{text!r} is not an rmw_zenoh QoS field")
        hist, depth = parts[2].split(",")[:2]
        try:
            return cls(reliable=parts[0] in ("", "0", "1"), transient_local=parts[1] == "1", keep_all=hist == "2",
                       depth=int(depth) if depth else 42)
        except ValueError as exc:
            raise ValueError(f"{text!r}: depth {depth!r} is not a number") from exc


@dataclass(frozen=True)
class GraphEntity:
    """One liveliness token of the ROS 2 graph: a node (``NN``) or one of its endpoints."""

    domain_id: int
    zid: str
    node_id: int
    entity_id: int
    kind: Kind
    node_name: str
    namespace: str = "/"
    enclave: str = "/"
    topic: str = ""
    dds_type: str = ""
    type_hash: str = ""
    qos: Qos = Qos()

    def token(self) -> str:
        """``@ros2_lv/<domain>/<zid>/<node id>/<entity id>/<kind>/<enclave>/<namespace>/<node>``,
        then for an endpoint ``/<topic>/<type>/<hash>/<qos>``, every name with ``/`` as ``%``."""
        # a node's own token repeats its node id where an endpoint's has its entity id
        entity_id = self.node_id if self.kind == "NN" else self.entity_id
        parts = [ADMIN_SPACE, str(self.domain_id), self.zid, str(self.node_id), str(entity_id), self.kind,
                 mangle(self.enclave), mangle(self.namespace), mangle(self.node_name)]
        if self.kind != "NN":
            parts += [mangle(self.topic), self.dds_type, self.type_hash, self.qos.text()]
        return "/".join(parts)

    @property
    def type_name(self) -> str:
        """``pkg/msg/Name`` of ``pkg::msg::dds_::Name_`` ('' for a node)."""
        return dds_to_ros(self.dds_type) if self.dds_type else ""


def dds_to_ros(dds_type: str) -> str:
    """``sensor_msgs::msg::dds_::Image_`` -> ``sensor_msgs/msg/Image``."""
    parts = dds_type.split("::")
    if len(parts) != 4 or parts[2] != "dds_" or not parts[3].endswith("_"):
        raise ValueError(f"{dds_type!r} is not a DDS type name pkg::msg::dds_::Name_")
    return f"{parts[0]}/{parts[1]}/{parts[3][:-1]}"


def ros_to_dds(ros_type: str) -> str:
    """``sensor_msgs/msg/Image`` -> ``sensor_msgs::msg::dds_::Image_``."""
    parts = ros_type.split("/")
    if len(parts) != 3 or not all(parts):
        raise ValueError(f"{ros_type!r} is not a ROS 2 type name pkg/msg/Name")
    return f"{parts[0]}::{parts[1]}::dds_::{parts[2]}_"


def parse_token(key: str) -> GraphEntity:
    """A liveliness token of rmw_zenoh's graph; ValueError for anything else."""
    parts = key.split("/")
    if len(parts) not in (9, 13) or parts[0] != ADMIN_SPACE or parts[5] not in _KINDS:
        raise ValueError(f"{key!r} is not an rmw_zenoh graph token")
    if (parts[5] == "NN") != (len(parts) == 9):
        raise ValueError(f"{key!r}: a {parts[5]} token has the wrong number of fields")
    try:
        domain, node_id, entity_id = int(parts[1]), int(parts[3]), int(parts[4])
    except ValueError as exc:
        raise ValueError(f"{key!r}: domain and ids must be numbers") from exc
    common = dict(domain_id=domain, zid=parts[2], node_id=node_id, entity_id=entity_id, kind=parts[5],
                  enclave=unmangle(parts[6]), namespace=unmangle(parts[7]), node_name=unmangle(parts[8]))
    if len(parts) == 9:
        return GraphEntity(**common)  # type: ignore[arg-type]
    return GraphEntity(**common, topic=unmangle(parts[9]), dds_type=parts[10], type_hash=parts[11],  # type: ignore[arg-type]
                       qos=Qos.parse(parts[12]))


def entity_gid(token: str) -> bytes:
    """A 16-byte publisher GID, unique per entity: rmw_zenoh takes an XXH3-128 of the token;
    subscribers do not check how it was made, so this takes the first 16 bytes of its SHA-256."""
    return hashlib.sha256(token.encode()).digest()[:_GID_SIZE]


@dataclass(frozen=True)
class Attachment:
    sequence: int
    source_timestamp_ns: int
    gid: bytes


def attachment(sequence: int, source_timestamp_ns: int, gid: bytes) -> bytes:
    """``int64 seq (LE) | int64 source timestamp ns (LE) | 0x10 | 16-byte GID``: 33 bytes, what
    zenoh-ext's serializer writes for (int64, int64, bytes) and rmw_zenoh reads."""
    if len(gid) != _GID_SIZE:
        raise ValueError(f"a GID has {_GID_SIZE} bytes, got {len(gid)}")
    return struct.pack("<qqB", sequence, source_timestamp_ns, _GID_SIZE) + gid


def parse_attachment(data: bytes | None) -> Attachment:
    """Read an rmw_zenoh attachment; ValueError names what is wrong (rmw_zenoh drops such samples)."""
    if data is None:
        raise ValueError("the sample has no attachment (rmw_zenoh drops such samples)")
    if len(data) != ATTACHMENT_SIZE:
        raise ValueError(f"the attachment has {len(data)} bytes, not {ATTACHMENT_SIZE} (seq, stamp, GID): "
                         "an rmw_zenoh before Jazzy 0.2.4 or not rmw_zenoh")
    seq, stamp, n = struct.unpack_from("<qqB", data)
    if n != _GID_SIZE:
        raise ValueError(f"the attachment's GID length is {n}, not {_GID_SIZE}")
    return Attachment(seq, stamp, bytes(data[17:]))
