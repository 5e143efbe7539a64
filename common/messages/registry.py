"""The one list of the project's nodes and the streams each one reads and writes.

Everything that names the nodes is derived from :data:`NODES` or checked against it:
``perception``'s command table (each node's ``commands`` module), the key table and
``perception keys`` (:mod:`common.messages.keys`), the certificate roles (:mod:`common.transport.certs`) and the
access-control rules (:mod:`common.transport.acl`), the demo's processes and the viewer's and doctor's
stages (the entries with ``stage=True``, in data-flow order), and the import rules
(``.importlinter``, ``tests/integration/test_architecture.py``). A test builds every node on the in-memory
transport and fails when what it really subscribes, publishes and serves differs from its entry
here (``tests/service/test_registry.py``).

Adding a node: its folder (``services/NAME/`` in the node shape, ARCHITECTURE.md "Writing a
node") and one :class:`NodeEntry` line below.

This module imports nothing, so that every layer, pure cores included, may read it.
"""

from __future__ import annotations

from dataclasses import dataclass

__all__ = ["NODES", "NodeEntry", "node", "pipeline", "stages"]


@dataclass(frozen=True)
class NodeEntry:
    """One node: its name and where it lives, and the streams of :data:`common.messages.keys.STREAMS` it uses.

    ``subscribes``/``publishes``/``serves`` are stream names (``frames``, ``tracks``,
    ``track_query``...), the union over the node's settings (the detector reads ``tf`` only with a
    floor from the transforms). ``stage``: a stage of the pipeline chain (frames -> tracks),
    started by ``perception demo`` and metered by the viewer and the doctor. In the secure
    deployment each node logs in under its own name and is granted exactly these streams.
    """

    name: str
    #: The package; its ``commands`` module adds to the ``perception`` command table.
    package: str
    #: ``module:Class`` of the node and of its settings model (the node shape, ``common.runtime.node``).
    node: str
    config: str
    summary: str
    subscribes: tuple[str, ...] = ()
    publishes: tuple[str, ...] = ()
    serves: tuple[str, ...] = ()
    #: Liveliness it watches (``alive``: the other nodes' tokens).
    watches: tuple[str, ...] = ()
    #: It also speaks ROS 2 on the same Zenoh (rmw_zenoh's keys, outside this project's base key).
    ros2: bool = False
    stage: bool = False


NODES: tuple[NodeEntry, ...] = (
    NodeEntry("detector", "services.detector", "services.detector.service:DetectorService",
              "services.detector.config:DetectorConfig", "finds people in a camera's frames",
              subscribes=("frames", "tf", "tf_static"), publishes=("detections",), stage=True),
    NodeEntry("localizer", "services.localizer", "services.localizer.service:LocalizerService",
              "services.localizer.config:LocalizerConfig", "puts each detection in the map frame",
              subscribes=("frames", "detections", "tf", "tf_static"), publishes=("localized",), stage=True),
    NodeEntry("embedder", "services.embedder", "services.embedder.service:EmbedderService",
              "services.embedder.config:EmbedderConfig", "describes each detection's appearance",
              subscribes=("frames", "detections"), publishes=("embeddings",), stage=True),
    NodeEntry("tracker", "services.tracker", "services.tracker.service:TrackerService",
              "services.tracker.config:TrackerConfig", "keeps the tracks and the ID memory",
              subscribes=("localized", "embeddings", "static_map"), publishes=("tracks", "id_decisions"),
              serves=("track_query", "forget_query"),
              stage=True),
    NodeEntry("laser", "services.laser", "services.laser.service:LaserService", "services.laser.config:LaserConfig",
              "finds people's legs in a 2-D laser's scans, all around the robot",
              subscribes=("scans", "tf", "tf_static", "static_map"), publishes=("localized",)),
    NodeEntry("attention", "services.attention", "services.attention.service:AttentionService",
              "services.attention.config:AttentionConfig", "turns the robot's head to keep a person in view",
              subscribes=("frames", "tracks", "tf", "tf_static"), publishes=("head_command",),
              serves=("attention_query",)),
    NodeEntry("camera", "services.camera", "services.camera.service:CameraService", "services.camera.config:CameraConfig",
              "a camera, a video file or a folder of images to frames/{camera}",
              subscribes=("detections",), publishes=("frames",)),
    NodeEntry("ros2", "services.ros2", "services.ros2.service:Ros2Service", "services.ros2.config:Ros2Config",
              "a ROS 2 robot's camera, transforms and laser scans in, the people out as ROS 2 topics (rmw_zenoh)",
              subscribes=("tracks",), publishes=("frames", "tf", "tf_static", "static_map", "scans"), ros2=True),
    NodeEntry("viewer", "tools.viewer", "tools.viewer.node:ViewerNode", "tools.viewer.config:ViewerConfig",
              "the operator's live page",
              subscribes=("frames", "detections", "localized", "embeddings", "tracks", "id_decisions", "tf", "tf_static",
                          "static_map", "scans", "status"),
              watches=("alive",)),
)


def node(name: str) -> NodeEntry:
    """The entry named ``name``; KeyError names the known nodes."""
    for entry in NODES:
        if entry.name == name:
            return entry
    raise KeyError(f"no node {name!r} (known: {', '.join(n.name for n in NODES)})")


def stages() -> tuple[str, ...]:
    """The pipeline's nodes in data-flow order (the demo starts them, the doctor checks them)."""
    return tuple(n.name for n in NODES if n.stage)


def pipeline() -> tuple[NodeEntry, ...]:
    return tuple(n for n in NODES if n.stage)
