"""What ``perception doctor`` observed, as plain data, and what it concludes, as :class:`Check`.

The collector (:mod:`tools.doctor.collect`) fills an :class:`Observation` from a live
system or a recording; the checks (:mod:`tools.doctor.core.checks`) read nothing else,
so every diagnosis can be tested offline from hand-written facts.

Keys are stream keys under the robot's base (``frames/head``, ``tracks``,
``status/tracker/pc-12``), never full Zenoh keys.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Literal

import numpy as np

from services.ros2.core.wire import GraphEntity
from common.messages.registry import stages

__all__ = ["CHAIN", "NODES", "SYMBOLS", "Check", "EdgeFacts", "FrameFacts", "NodeFacts", "Observation", "ScanFacts",
           "Status", "StreamFacts"]

Status = Literal["ok", "warn", "fail"]
#: How each status is printed.
SYMBOLS: dict[str, str] = {"ok": "✓", "warn": "!", "fail": "✗"}
#: The pipeline's nodes, in data-flow order (the registry's stages).
NODES = stages()
#: The chain's stages: (stream, the node that produces it, the stream it is made from).
CHAIN: tuple[tuple[str, str, str], ...] = (
    ("frames", "", ""),
    ("detections", "detector", "frames"),
    ("localized", "localizer", "detections"),
    ("embeddings", "embedder", "detections"),
    ("tracks", "tracker", "localized"),
)


@dataclass(frozen=True)
class Check:
    """One line of the checklist: ``status``, the measured ``figure`` and, unless ok, the ``fix``."""

    section: str
    name: str
    status: Status
    figure: str
    fix: str = ""


@dataclass
class StreamFacts:
    """One key's traffic: how many payloads, how many invalid (the first error), when (receive ns)."""

    key: str
    count: int = 0
    invalid: int = 0
    error: str = ""
    first_ns: int = 0
    last_ns: int = 0

    def rate_hz(self, duration_s: float) -> float:
        return self.count / duration_s if duration_s > 0 else 0.0


@dataclass
class NodeFacts:
    """One service instance, from liveliness and its status messages.

    ``counters`` are what changed while the doctor watched (the last status minus the
    first: ``received``, ``published``, ``dropped``, ``invalid`` and every extra counter),
    over ``window_s`` seconds; with a single status they are the totals since its start
    and ``window_s`` is 0. ``alive`` is None when liveliness is unknown (a recording).
    """

    service: str
    instance: str
    alive: bool | None = True
    state: str = "running"
    error: str = ""
    exit_status: int | None = None
    host: str = ""
    uptime_s: float = 0.0
    counters: dict[str, float] = field(default_factory=dict)
    #: The last status's extra counters and gauges as they were (not differenced).
    last: dict[str, float] = field(default_factory=dict)
    window_s: float = 0.0
    settings: dict[str, str] = field(default_factory=dict)
    subscribes: list[str] = field(default_factory=list)
    publishes: list[str] = field(default_factory=list)
    has_status: bool = True

    def drops(self) -> dict[str, float]:
        """The node's own counted drops by reason (``dropped_<reason>`` counters > 0)."""
        return {k.removeprefix("dropped_"): v for k, v in self.counters.items()
                if k.startswith("dropped_") and k != "dropped_stale" and v > 0}


@dataclass
class FrameFacts:
    """One RGB-D frame as sent, read leniently (also when receivers refuse it).

    Shapes are ``(height, width)``. ``depth_sample`` holds raw depth values of a pixel
    subsample in the unit sent (mm for ``16UC1``), float64 (N,). ``error`` is the decode
    error when the frame is invalid.
    """

    camera: str
    stamp_ns: int
    recv_ns: int
    frame_id: str = ""
    rgb_hw: tuple[int, int] | None = None
    depth_hw: tuple[int, int] | None = None
    depth_encoding: str = ""
    depth_sample: np.ndarray | None = None
    info_hw: tuple[int, int] | None = None
    K: np.ndarray | None = None
    error: str = ""


@dataclass
class ScanFacts:
    """A laser's scans as received on ``scans/{laser}``: how many, their frames, stamps and sweep.

    ``backwards`` counts scans whose stamp was not after the one before (two drivers on one
    topic, a replay that loops); ``no_return`` is the share of beams without a return (NaN, inf
    or outside the scan's range limits), averaged over the scans; ``scan_time_s`` the last
    scan's own period (0: the driver does not say)."""

    laser: str
    count: int = 0
    frame_ids: list[str] = field(default_factory=list)
    first_stamp_ns: int = 0
    last_stamp_ns: int = 0
    first_recv_ns: int = 0
    last_recv_ns: int = 0
    backwards: int = 0
    beams: int = 0
    scan_time_s: float = 0.0
    no_return: float = 0.0

    def stamp_rate_hz(self) -> float:
        """The scans' rate by their stamps (0 with fewer than two, or stamps that do not advance)."""
        span = (self.last_stamp_ns - self.first_stamp_ns) / 1e9
        return (self.count - 1) / span if self.count > 1 and span > 0 else 0.0


@dataclass
class EdgeFacts:
    """A transform edge ``parent -> child`` as received on ``tf`` or ``tf_static``."""

    parent: str
    child: str
    static: bool
    count: int = 0
    first_stamp_ns: int = 0
    last_stamp_ns: int = 0


@dataclass
class Observation:
    """Everything the checks judge.

    ``stages[camera][stream]`` maps each join key ``(stamp_ns, source, seq)`` seen on a
    chain stream to its receive time (ns). ``offsets_ns[camera]`` holds receive time
    minus stamp for every frame. ``cards`` are the embedding model cards seen
    ``(name, dim, metric, has_thresholds)``; ``track_models`` the ``embedding_model``
    of the tracks, ``track_frames`` their frame ids, ``localized_frames`` those of the
    localized detections; ``position_only`` / ``tracks_total`` count Tracks messages;
    ``boxes_total`` the people detected.
    """

    duration_s: float
    source: str = "live"
    end_ns: int = 0
    streams: dict[str, StreamFacts] = field(default_factory=dict)
    nodes: list[NodeFacts] = field(default_factory=list)
    frames: dict[str, list[FrameFacts]] = field(default_factory=dict)
    #: each laser's scans (``scans/{laser}``), by laser name
    scans: dict[str, ScanFacts] = field(default_factory=dict)
    offsets_ns: dict[str, list[int]] = field(default_factory=dict)
    edges: list[EdgeFacts] = field(default_factory=list)
    stages: dict[str, dict[str, dict[tuple[int, str, int], int]]] = field(default_factory=dict)
    cards: list[tuple[str, int, str, bool]] = field(default_factory=list)
    track_models: list[str] = field(default_factory=list)
    track_frames: list[str] = field(default_factory=list)
    localized_frames: list[str] = field(default_factory=list)
    #: cameras (and their frames) whose people the localizer placed through a floor homography:
    #: they need no depth and no transforms
    floor_cameras: list[str] = field(default_factory=list)
    floor_camera_frames: list[str] = field(default_factory=list)
    position_only: int = 0
    tracks_total: int = 0
    boxes_total: int = 0
    #: People as the localizer placed them: (height above the map's z = 0, horizontal distance
    #: from the camera, the camera's frame, the camera's height, its range, the world z part of the
    #: image's up direction), one row per localized person (a sample).
    people: list[tuple[float, float, str, float, float, float]] = field(default_factory=list)
    #: Other robot names or key prefixes with nodes alive on the router: ``prefix/robot`` -> services.
    other_robots: dict[str, list[str]] = field(default_factory=dict)
    #: The ROS 2 graph on the router (rmw_zenoh's liveliness tokens) of domain ``ros2_domain``.
    ros2_graph: list[GraphEntity] = field(default_factory=list)
    ros2_domain: int = 0

    def stream(self, key: str) -> StreamFacts:
        return self.streams.get(key) or StreamFacts(key)

    def parents(self) -> dict[str, EdgeFacts]:
        """Each child frame's transform from its parent, the latest stamped where it came twice."""
        out: dict[str, EdgeFacts] = {}
        for e in self.edges:
            if e.child not in out or e.last_stamp_ns > out[e.child].last_stamp_ns:
                out[e.child] = e
        return out

    def running(self, service: str) -> list[NodeFacts]:
        """The instances of ``service`` that are up (alive, or with status in a recording)."""
        return [n for n in self.nodes if n.service == service and n.state == "running" and n.alive is not False]

    def failed(self, service: str | None = None) -> list[NodeFacts]:
        return [n for n in self.nodes if n.state == "failed" and (service is None or n.service == service)]

    def only_floor_cameras(self) -> bool:
        """Whether every camera in play is placed on the floor by its homography (no transforms needed)."""
        return bool(self.floor_cameras) and set(self.cameras()) <= set(self.floor_cameras)

    def cameras(self) -> list[str]:
        """The cameras in play: those with traffic, else those the nodes are set to, else ``head``."""
        seen = {key.split("/", 1)[1] for key in self.streams if key.split("/", 1)[0] in ("frames", "detections")
                and "/" in key}
        if not seen:
            seen = {n.settings["camera"] for n in self.nodes if n.settings.get("camera", "*") != "*"}
        return sorted(seen) or ["head"]
