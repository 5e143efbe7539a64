"""A ROS 2 participant on this project's transport: a node in the ROS 2 graph, its publishers
(CDR, rmw_zenoh's attachment, a graph token each) and its subscriptions (every type and hash of
a topic, so that a mismatch can be named instead of never arriving)."""

from __future__ import annotations

import time
from typing import Any

from common.messages.keys import Delivery
from common.runtime.node import NodeIO
from common.transport.base import RawPublisher, RawSubscription, Token, Transport
from services.ros2.core.types import RosTypes
from services.ros2.core.wire import GraphEntity, Qos, attachment, entity_gid, ros_to_dds

__all__ = ["QOS_DEFAULT", "QOS_SENSOR", "QOS_TF", "QOS_TF_STATIC", "RosParticipant", "RosPublisher"]

#: QoS shown in the graph: images as sensor data (best effort, keep last 5); everything else
#: reliable, keep last 10; /tf keep last 100 and /tf_static transient local, keep last 1, as tf2.
QOS_SENSOR = Qos(reliable=False, depth=5)
QOS_DEFAULT = Qos(depth=10)
QOS_TF = Qos(depth=100)
QOS_TF_STATIC = Qos(transient_local=True, depth=1)
_IN = Delivery(latest=False, queue=16, congestion="drop")
_OUT = Delivery(latest=False, queue=16, congestion="drop")


class RosPublisher:
    """One ROS 2 publisher: its data key, its graph token, and the attachment's sequence (from 1)
    and GID."""

    def __init__(self, pub: RawPublisher, token: Token, entity: GraphEntity, types: RosTypes, type_name: str) -> None:
        self.pub = pub
        self.token = token
        self.entity = entity
        self.types = types
        self.type_name = type_name
        self.gid = entity_gid(entity.token())
        self.seq = 0

    @property
    def key(self) -> str:
        return self.pub.key

    def put(self, msg: Any, stamp_ns: int | None = None) -> None:
        self.put_cdr(self.types.serialize(msg, self.type_name), stamp_ns)

    def put_cdr(self, payload: bytes, stamp_ns: int | None = None) -> None:
        self.seq += 1
        self.pub.put(payload, attachment(self.seq, time.time_ns() if stamp_ns is None else stamp_ns, self.gid))

    def close(self) -> None:
        self.pub.close()
        self.token.close()


class RosParticipant:
    """A ROS 2 node (its ``NN`` token) and its endpoints on ``transport``.

    ``io``: when given, subscriptions are declared through it, so the node's status counts them.
    """

    def __init__(self, transport: Transport, types: RosTypes, *, domain_id: int, node_name: str, namespace: str = "/",
                 io: NodeIO | None = None) -> None:
        self.transport = transport
        self.types = types
        self.domain_id = domain_id
        self.node_name = node_name
        self.namespace = namespace
        self.io = io
        self.zid = transport.session_id()
        self._next = 1
        self.tokens: list[Token] = [transport.declare_token(self._entity("NN").token())]
        self.publishers: dict[str, RosPublisher] = {}
        self.gids: set[bytes] = set()

    def _entity(self, kind: str, topic: str = "", type_name: str = "", qos: Qos = QOS_DEFAULT) -> GraphEntity:
        entity_id = 0
        if kind != "NN":
            entity_id, self._next = self._next, self._next + 1
        return GraphEntity(domain_id=self.domain_id, zid=self.zid, node_id=0, entity_id=entity_id, kind=kind,  # type: ignore[arg-type]
                           node_name=self.node_name, namespace=self.namespace, topic=topic,
                           dds_type=ros_to_dds(type_name) if type_name else "",
                           type_hash=self.types.hash(type_name) if type_name else "", qos=qos)

    def subscription(self, topic: str, type_name: str, qos: Qos, *, history: int = 0) -> RawSubscription:
        """Samples of ``topic`` of any type and hash (``<domain>/<topic>/*/*``); ``history`` > 0 asks
        publishers that keep a cache (rmw_zenoh's transient-local ones) for their last samples."""
        key = f"{self.domain_id}/{topic.strip('/')}/*/*"
        sub = (self.io.subscribe_raw(key, _IN, history=history) if self.io is not None
               else self.transport.subscribe_raw(key, _IN, history=history))
        self.tokens.append(self.transport.declare_token(self._entity("MS", topic, type_name, qos).token()))
        return sub

    def publisher(self, topic: str, type_name: str, qos: Qos = QOS_DEFAULT, *, cache: int = 0) -> RosPublisher:
        """The publisher of ``topic`` (made on first use); ``cache`` > 0 keeps the last samples for
        late joiners, as rmw_zenoh does for a transient-local publisher."""
        if topic not in self.publishers:
            entity = self._entity("MP", topic, type_name, qos)
            raw = self.transport.raw_publisher(self.types.key(self.domain_id, topic, type_name), _OUT, cache=cache)
            pub = RosPublisher(raw, self.transport.declare_token(entity.token()), entity, self.types, type_name)
            self.publishers[topic] = pub
            self.gids.add(pub.gid)
        return self.publishers[topic]

    def drop(self, topic: str) -> int:
        """Undeclare ``topic``'s publisher; how many samples it published."""
        pub = self.publishers.pop(topic, None)
        if pub is None:
            return 0
        pub.close()
        return pub.seq

    def close(self) -> None:
        for pub in self.publishers.values():
            pub.close()
        self.publishers.clear()
        for token in self.tokens:
            token.close()
        self.tokens.clear()
