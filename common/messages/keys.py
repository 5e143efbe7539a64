"""The only place where Zenoh key expressions are spelled.

Every key is ``{prefix}/{robot}/perception/v1/{stream}[/{camera or service}...]``. The
version segment changes only with an incompatible schema change, so old and new
services never read each other's payloads by mistake.

:data:`STREAMS` describes each stream: message type, publisher, subscribers and delivery
policy; who among the nodes publishes and subscribes comes from :data:`common.messages.registry.NODES`. The README's key table is generated from it (``perception keys --markdown``).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Literal, NamedTuple

from common.messages.registry import NODES

__all__ = ["COMMANDS", "DEFAULT_PREFIX", "DEFAULT_ROBOT", "SCANS", "STREAMS", "AliveKey", "Delivery", "Keys", "MAPS", "Stream", "stream", "validate_chunk"]

DEFAULT_PREFIX = "pp"
DEFAULT_ROBOT = "robot"
API_VERSION = "v1"
_FORBIDDEN = set("/*$?#")


def validate_chunk(value: str, what: str) -> str:
    """Check that ``value`` is one key-expression chunk (no '/', wildcards or '$?#')."""
    if not value or any(c in _FORBIDDEN for c in value) or value != value.strip():
        raise ValueError(f"{what} {value!r} must be a non-empty key chunk without '/', '*', '$', '?', '#' or spaces at the ends")
    return value


@dataclass(frozen=True)
class Delivery:
    """How a stream is delivered.

    ``latest``: subscribers keep only the newest sample (a ring of one), so a slow
    consumer always works on the freshest frame and never builds a queue.
    Otherwise subscribers keep a FIFO of ``queue`` samples and count what overflows.
    ``congestion``: what the publisher does when the network cannot keep up.
    ``wake``: False for a subscriber that reads on its own schedule (a page refreshed ten
    times a second): samples wait inside the transport, the newest ``queue`` of them, and no
    thread is woken per sample; :meth:`~common.transport.base.Subscription.recv` does not wait on
    them and what overflows is not counted.
    """

    latest: bool
    queue: int
    congestion: Literal["drop", "block"]
    express: bool = False
    wake: bool = True

    def describe(self) -> str:
        sub = "latest-only (ring of 1)" if self.latest else f"FIFO of {self.queue}, overflow counted"
        if not self.wake:
            sub = f"read when polled (ring of {1 if self.latest else self.queue})"
        return f"{sub}; publisher {self.congestion}s on congestion" + ("; express" if self.express else "")


FRAMES = Delivery(latest=True, queue=1, congestion="drop", express=True)
#: A laser's scans: small and frequent, each one counts (a leg seen in every scan), but a stale
#: one is worth less than the next: a short FIFO, dropped on congestion.
SCANS = Delivery(latest=False, queue=16, congestion="drop", express=True)
#: The robot's map: only the newest counts, and none is lost to congestion.
MAPS = Delivery(latest=True, queue=1, congestion="block")
RELIABLE = Delivery(latest=False, queue=256, congestion="block")
STATUS = Delivery(latest=False, queue=64, congestion="drop")
#: Commands to an actuator: only the newest matters, and it must not wait behind older ones.
COMMANDS = Delivery(latest=True, queue=1, congestion="drop", express=True)


@dataclass(frozen=True)
class Stream:
    """One kind of key: its template under the base key and who uses it.

    Who publishes and who subscribes among the project's nodes comes from
    :data:`common.messages.registry.NODES`; ``others_publish`` and ``others_subscribe`` name the parties
    that are not nodes (a camera driver, the simulator, navigation).
    """

    name: str
    template: str
    message: str
    others_publish: str
    others_subscribe: str
    delivery: Delivery | None
    kind: Literal["pub/sub", "liveliness", "query"] = "pub/sub"

    def published_by(self) -> tuple[str, ...]:
        """The nodes that publish (or, for a query, serve) this stream."""
        return tuple(n.name for n in NODES if self.name in n.publishes or self.name in n.serves)

    def subscribed_by(self) -> tuple[str, ...]:
        return tuple(n.name for n in NODES if self.name in n.subscribes or self.name in n.watches)

    @property
    def publishers(self) -> str:
        return ", ".join(p for p in (*self.published_by(), self.others_publish) if p)

    @property
    def subscribers(self) -> str:
        return ", ".join(p for p in (*self.subscribed_by(), self.others_subscribe) if p)


STREAMS: tuple[Stream, ...] = (
    Stream("frames", "frames/{camera}", "RGBDFrame", "camera driver, simulator, replay", "", FRAMES),
    Stream("scans", "scans/{laser}", "LaserScan", "ros2 (/scan), replay, simulator", "", SCANS),
    Stream("detections", "detections/{camera}", "Detections", "", "simulator (paces itself with --max)", RELIABLE),
    Stream("localized", "localized/{camera}", "LocalizedDetections", "", "", RELIABLE),
    Stream("embeddings", "embeddings/{camera}", "Embeddings", "", "", RELIABLE),
    Stream("tracks", "tracks", "Tracks", "", "navigation, HRI, recorder", RELIABLE),
    Stream("id_decisions", "id_decisions", "IdDecisions", "", "HRI, recorder", RELIABLE),
    Stream("tf", "tf", "TransformBatch", "localization, odometry, simulator, replay", "", RELIABLE),
    Stream("tf_static", "tf_static", "TransformBatch", "robot description, simulator, replay", "", RELIABLE),
    Stream("static_map", "static_map", "StaticMap", "", "", MAPS),
    Stream("groundtruth", "groundtruth", "PeopleGroundTruth", "simulator, replay", "perception demo, evaluation, recorder",
           RELIABLE),
    Stream("status", "status/{service}/{instance}", "ServiceStatus", "every node (1 Hz, and on query)",
           "perception status, doctor, monitors", STATUS),
    Stream("alive", "alive/{service}/{instance}", "liveliness token", "every node", "perception status, launcher",
           None, "liveliness"),
    Stream("track_query", "query/track", "query `?id=K` → TrackState", "", "any client", None, "query"),
    Stream("forget_query", "query/forget", "query `?id=K` or `?all=1` → ForgetReply", "", "perception forget", None,
           "query"),
    Stream("head_command", "head/command", "HeadCommand", "", "the head's driver, simulator", COMMANDS),
    Stream("attention_query", "query/attention",
           "query `?target=K`, `nearest`, `lock` or `none` (none: the state) → AttentionReply", "",
           "perception look, HRI", None, "query"),
)


def stream(name: str) -> Stream:
    """The stream named ``name``; KeyError for an unknown one."""
    for s in STREAMS:
        if s.name == name:
            return s
    raise KeyError(f"no stream {name!r}")


class AliveKey(NamedTuple):
    """The service and instance named by a liveliness key."""

    service: str
    instance: str


@dataclass(frozen=True)
class Keys:
    """Key expressions of one robot. Pass ``"*"`` as a camera or service to match all."""

    robot: str = DEFAULT_ROBOT
    prefix: str = DEFAULT_PREFIX

    def __post_init__(self) -> None:
        for part in self.prefix.split("/"):
            validate_chunk(part, "key prefix segment")
        validate_chunk(self.robot, "robot name")

    @property
    def base(self) -> str:
        return f"{self.prefix}/{self.robot}/perception/{API_VERSION}"

    def _join(self, *chunks: str) -> str:
        for c in chunks:
            if c not in ("*", "**"):
                validate_chunk(c, "key chunk")
        return "/".join((self.base, *chunks))

    def frames(self, camera: str) -> str:
        return self._join("frames", camera)

    def scans(self, laser: str) -> str:
        """A 2-D laser's scans (:class:`~common.messages.schemas.LaserScan`)."""
        return self._join("scans", laser)

    def detections(self, camera: str) -> str:
        return self._join("detections", camera)

    def localized(self, camera: str) -> str:
        return self._join("localized", camera)

    def embeddings(self, camera: str) -> str:
        return self._join("embeddings", camera)

    def tracks(self) -> str:
        return self._join("tracks")

    def id_decisions(self) -> str:
        """Why the tracker gave IDs (:class:`~common.messages.schemas.IdDecisions`)."""
        return self._join("id_decisions")

    def tf(self) -> str:
        return self._join("tf")

    def tf_static(self) -> str:
        return self._join("tf_static")

    def static_map(self) -> str:
        """The robot's map (:class:`~common.messages.schemas.StaticMap`; the ros2 node's ``/map``)."""
        return self._join("static_map")

    def groundtruth(self) -> str:
        """True people positions (map frame) from a simulator or motion capture."""
        return self._join("groundtruth")

    def status(self, service: str = "*", instance: str = "*") -> str:
        return self._join("status", service, instance)

    def alive(self, service: str = "*", instance: str = "*") -> str:
        return self._join("alive", service, instance)

    def parse_alive(self, key: str) -> AliveKey:
        """(service, instance) of a liveliness key ``{base}/alive/{service}/{instance}``.

        Raises ValueError for any other key (another robot or prefix, another stream,
        a missing or extra chunk, a wildcard).
        """
        head = self.base + "/alive/"
        parts = key[len(head) :].split("/") if key.startswith(head) else []
        if len(parts) != 2 or any(not p or p != p.strip() or any(c in _FORBIDDEN for c in p) for p in parts):
            raise ValueError(f"{key!r} is not a liveliness key {head}SERVICE/INSTANCE")
        return AliveKey(parts[0], parts[1])

    def track_query(self) -> str:
        return self._join("query", "track")

    def forget_query(self) -> str:
        return self._join("query", "forget")

    def head_command(self) -> str:
        """Pan/tilt velocity commands for the robot's head (the attention node's output)."""
        return self._join("head", "command")

    def attention_query(self) -> str:
        """Whom the attention node looks at: ``?target=K``, ``?target=nearest``, ``?target=lock``, ``?target=none``."""
        return self._join("query", "attention")

    def pattern(self, stream_name: str) -> str:
        """The key expression of every key of the stream ``stream_name`` (``frames/*``, ``status/*/*``)."""
        template = stream(stream_name).template
        return f"{self.base}/" + template.format(camera="*", laser="*", service="*", instance="*")

    def all(self) -> str:
        return self._join("**")

    def stream_of(self, key: str) -> str | None:
        """The stream name of a concrete key under this robot's base, or None."""
        if not key.startswith(self.base + "/"):
            return None
        first = key[len(self.base) + 1 :].split("/", 1)[0]
        return first if any(s.template.split("/", 1)[0] == first for s in STREAMS) else None

    def markdown_table(self) -> str:
        """The key table for the README."""
        rows = [
            "| key (under `" + self.base.replace(self.robot, "{robot}").replace(self.prefix, "{prefix}", 1) + "/`) "
            "| message | published by | subscribed by | delivery |",
            "|---|---|---|---|---|",
        ]
        for s in STREAMS:
            delivery = s.delivery.describe() if s.delivery else s.kind
            rows.append(f"| `{s.template}` | {s.message} | {s.publishers} | {s.subscribers} | {delivery} |")
        return "\n".join(rows)
