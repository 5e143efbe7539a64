"""From payloads, statuses and liveliness to the doctor's :class:`Observation`.

:class:`Observer` is fed the same way from a live system (:mod:`tools.doctor.live`) and
from a recording (:mod:`tools.doctor.recording`): every payload with its key and receive
time, every service status, every liveliness change. It decodes each payload itself, so
it also sees what the nodes refuse: an invalid frame is read field by field
(:func:`common.messages.codec.unpack_unchecked`) to say what is wrong with it.
"""

from __future__ import annotations

import dataclasses
from collections import defaultdict
from collections.abc import Callable
from typing import Any

import numpy as np

from common.messages.codec import DecodeError, decode_any, unpack_unchecked
from common.messages.schemas import (
    Detections,
    Embeddings,
    Image,
    LaserScan,
    LocalizedDetections,
    Message,
    RGBDFrame,
    ServiceStatus,
    Tracks,
    TransformBatch,
)
from services.ros2.core.wire import GraphEntity, parse_token
from tools.doctor.core.facts import (
    EdgeFacts,
    FrameFacts,
    NodeFacts,
    Observation,
    ScanFacts,
    StreamFacts,
)

__all__ = ["Observer", "relative_key"]

_MARK = "/perception/v1/"
#: Frames kept per camera for the camera checks, at least this far apart (s).
FRAMES_KEPT, FRAME_EVERY_S = 8, 0.25
#: Localized people kept for the geometry checks.
PEOPLE_KEPT = 4000
#: Depth pixels sampled per frame (a regular grid).
DEPTH_SAMPLES = 4096


def relative_key(key: str) -> str:
    """``pp/robot/perception/v1/frames/head`` -> ``frames/head`` (any robot and prefix)."""
    return key.split(_MARK, 1)[1] if _MARK in key else key


def _depth_sample(array: np.ndarray) -> np.ndarray:
    step = max(1, int(np.sqrt(array.size / DEPTH_SAMPLES)))
    return np.asarray(array[::step, ::step], dtype=np.float64).ravel()


def _hw(shape: Any) -> tuple[int, int] | None:
    try:
        return int(shape[0]), int(shape[1])
    except (TypeError, ValueError, IndexError):
        return None


def frame_facts(camera: str, frame: RGBDFrame, recv_ns: int) -> FrameFacts:
    """A valid frame's facts."""
    depth = frame.depth
    sample = None
    if depth is not None:
        try:
            sample = _depth_sample(depth.to_array())
        except ValueError:
            sample = None
    info = frame.camera_info
    return FrameFacts(camera, frame.header.stamp_ns, recv_ns, info.header.frame_id or frame.header.frame_id,
                      frame.rgb.shape[:2], depth.shape[:2] if depth is not None else None,
                      depth.encoding if depth is not None else "", sample, (info.height, info.width),
                      np.asarray(info.K, dtype=np.float64))


def _raw_depth(depth: dict[str, Any]) -> np.ndarray | None:
    try:
        image = Image.model_construct(**depth)
        if image.encoding in ("16UC1", "32FC1"):
            return _depth_sample(np.frombuffer(image.data, dtype=image.dtype).reshape(image.shape))
        return _depth_sample(image.to_array())
    except (ValueError, TypeError, KeyError):
        return None


def raw_frame_facts(camera: str, data: bytes, recv_ns: int, error: str) -> FrameFacts:
    """What can be read of a frame that does not validate (a zero K, an unregistered depth...)."""
    try:
        _, _, body = unpack_unchecked(data)
    except DecodeError:
        return FrameFacts(camera, 0, recv_ns, error=error)
    header = body.get("header") if isinstance(body.get("header"), dict) else {}
    rgb = body.get("rgb") if isinstance(body.get("rgb"), dict) else {}
    depth = body.get("depth") if isinstance(body.get("depth"), dict) else None
    info = body.get("camera_info") if isinstance(body.get("camera_info"), dict) else {}
    info_header = info.get("header") if isinstance(info.get("header"), dict) else {}
    K = info.get("K")
    try:
        stamp = int(header.get("stamp_ns", 0))
    except (TypeError, ValueError):
        stamp = 0
    return FrameFacts(
        camera, stamp, recv_ns, str(info_header.get("frame_id") or header.get("frame_id") or ""),
        _hw(rgb.get("shape")), _hw(depth.get("shape")) if depth else None,
        str(depth.get("encoding", "")) if depth else "", _raw_depth(depth) if depth else None,
        _hw((info.get("height"), info.get("width"))) if "height" in info else None,
        np.asarray(K, dtype=np.float64) if isinstance(K, np.ndarray) else None, error)


class Observer:
    """Accumulates what is seen; :meth:`observation` turns it into facts."""

    def __init__(self) -> None:
        self.streams: dict[str, StreamFacts] = {}
        self.frames: dict[str, list[FrameFacts]] = defaultdict(list)
        self.scans: dict[str, ScanFacts] = {}
        self.offsets: dict[str, list[int]] = defaultdict(list)
        self.edges: dict[tuple[str, str], EdgeFacts] = {}
        self.stages: dict[str, dict[str, dict[tuple[int, str, int], int]]] = defaultdict(lambda: defaultdict(dict))
        self.statuses: dict[tuple[str, str], list[ServiceStatus]] = defaultdict(list)
        self.alive: dict[tuple[str, str], bool] = {}
        self.cards: set[tuple[str, int, str, bool]] = set()
        self.track_models: set[str] = set()
        self.track_frames: set[str] = set()
        self.localized_frames: set[str] = set()
        self.floor_cameras: set[str] = set()
        self.floor_camera_frames: set[str] = set()
        self.position_only = self.tracks_total = self.boxes_total = 0
        self.first_ns = self.last_ns = 0
        self.ros2_tokens: set[str] = set()
        self.ros2_domain = 0
        self.other_robots: dict[str, set[str]] = {}
        self.people: list[tuple[float, float, str, float, float, float]] = []

    # ---------------------------------------------------------------- input
    def payload(self, key: str, data: bytes, recv_ns: int) -> None:
        """One payload received on ``key`` (a full key or one under the robot's base)."""
        rel = relative_key(key)
        stream, _, camera = rel.partition("/")
        self.first_ns = recv_ns if not self.first_ns else min(self.first_ns, recv_ns)
        self.last_ns = max(self.last_ns, recv_ns)
        facts = self.streams.setdefault(rel, StreamFacts(rel, first_ns=recv_ns))
        facts.count += 1
        facts.last_ns = recv_ns
        try:
            msg = decode_any(data)
        except DecodeError as exc:
            facts.invalid += 1
            facts.error = facts.error or str(exc)
            if stream == "frames":
                raw = raw_frame_facts(camera, data, recv_ns, str(exc))
                if raw.stamp_ns:
                    self.offsets[camera].append(recv_ns - raw.stamp_ns)
                self._keep_frame(camera, recv_ns, lambda: raw)
            return
        self.message(rel, msg, recv_ns)

    def message(self, rel: str, msg: Message, recv_ns: int) -> None:
        """One decoded message on the stream key ``rel``."""
        stream, _, camera = rel.partition("/")
        if isinstance(msg, ServiceStatus):
            self.status(msg)
            return
        if isinstance(msg, TransformBatch):
            for t in msg.transforms:
                e = self.edges.setdefault((t.parent_frame, t.child_frame),
                                          EdgeFacts(t.parent_frame, t.child_frame, stream == "tf_static" or t.static,
                                                    first_stamp_ns=t.stamp_ns))
                e.count += 1
                e.last_stamp_ns = max(e.last_stamp_ns, t.stamp_ns)
            return
        if isinstance(msg, LaserScan):
            self._scan(camera or msg.header.source, msg, recv_ns)
            return
        source = msg.header.source or camera
        if stream == "tracks" and isinstance(msg, Tracks) and msg.input_stamp_ns:
            # at a fixed output rate the stamp is the publish time: key the newest input frame
            self.stages[source][stream].setdefault((msg.input_stamp_ns, msg.header.source, msg.header.seq), recv_ns)
        elif stream in ("frames", "detections", "localized", "embeddings", "tracks"):
            self.stages[source][stream].setdefault(msg.header.join_key, recv_ns)
        if isinstance(msg, RGBDFrame):
            self.offsets[camera].append(recv_ns - msg.header.stamp_ns)
            self._keep_frame(camera, recv_ns, lambda: frame_facts(camera, msg, recv_ns))
        elif isinstance(msg, Detections):
            self.boxes_total += len(msg.detections)
        elif isinstance(msg, LocalizedDetections):
            self.localized_frames.add(msg.header.frame_id)
            if msg.floor_view is not None:  # placed on the floor by the camera's homography
                self.floor_cameras.add(camera)
                if msg.camera_frame:
                    self.floor_camera_frames.add(msg.camera_frame)
            if msg.view is not None and len(self.people) < PEOPLE_KEPT:
                pose = np.asarray(msg.view.camera_to_frame, dtype=np.float64)
                cam = pose[:3, 3]
                up = float(pose[2, :3] @ np.array([0.0, -1.0, 0.0]))  # the image's up (optical -y), world z part
                for d in msg.detections:
                    p = np.asarray(d.position, dtype=np.float64)
                    self.people.append((float(p[2]), float(np.hypot(*(p[:2] - cam[:2]))), msg.camera_frame,
                                        float(cam[2]), float(msg.view.max_range_m), up))
        elif isinstance(msg, Embeddings):
            self.cards.add((msg.model.name, msg.model.dim, msg.model.metric, msg.model.thresholds is not None))
        elif isinstance(msg, Tracks):
            self.tracks_total += 1
            self.position_only += 0 if msg.appearance_available else 1
            self.track_models.add(msg.embedding_model)
            self.track_frames.add(msg.header.frame_id)

    def _scan(self, laser: str, scan: LaserScan, recv_ns: int) -> None:
        s = self.scans.setdefault(laser, ScanFacts(laser, first_stamp_ns=scan.header.stamp_ns, first_recv_ns=recv_ns))
        if s.count and scan.header.stamp_ns <= s.last_stamp_ns:
            s.backwards += 1
        s.count += 1
        s.last_stamp_ns = max(s.last_stamp_ns, scan.header.stamp_ns)
        s.last_recv_ns = recv_ns
        if scan.header.frame_id not in s.frame_ids:
            s.frame_ids.append(scan.header.frame_id)
        r = np.asarray(scan.ranges, np.float32)
        with np.errstate(invalid="ignore"):
            missing = float(np.count_nonzero(~((r > scan.range_min) & (r < scan.range_max)))) / max(1, len(r))
        s.no_return += (missing - s.no_return) / s.count
        s.beams, s.scan_time_s = len(r), float(scan.scan_time)

    def _keep_frame(self, camera: str, recv_ns: int, make: Callable[[], FrameFacts]) -> None:
        """Keep a frame's facts, at most one per ``FRAME_EVERY_S`` and the last ``FRAMES_KEPT``."""
        kept = self.frames[camera]
        if kept and recv_ns - kept[-1].recv_ns < FRAME_EVERY_S * 1e9:
            return
        kept.append(make())
        del kept[:-FRAMES_KEPT]

    def status(self, status: ServiceStatus) -> None:
        self.statuses[(status.name, status.instance)].append(status)

    def liveliness(self, service: str, instance: str, alive: bool) -> None:
        self.alive[(service, instance)] = alive

    def ros2_domain_to_watch(self, default: int = 0) -> int:
        """The ROS 2 domain of the ros2 node seen (its status's settings), else ``default``."""
        for (service, _), seen in self.statuses.items():
            if service == "ros2" and seen and seen[-1].settings.get("domain_id", "").isdigit():
                return int(seen[-1].settings["domain_id"])
        return default

    def others(self, own_base: str, keys: list[str]) -> None:
        """Liveliness tokens of every robot and prefix on the router: those not under ``own_base``."""
        for key in keys:
            head, sep, rest = key.partition(_MARK + "alive/")
            if not sep or key.startswith(own_base + "/"):
                continue
            service = rest.split("/", 1)[0]
            self.other_robots.setdefault(head, set()).add(service)

    def ros2_graph(self, domain: int, tokens: list[str]) -> None:
        """The ROS 2 graph's liveliness tokens on the router (``@ros2_lv/<domain>/...``)."""
        self.ros2_domain = domain
        self.ros2_tokens |= set(tokens)

    # --------------------------------------------------------------- output
    def _node(self, service: str, instance: str) -> NodeFacts:
        seen = sorted(self.statuses.get((service, instance), []), key=lambda s: s.uptime_s)
        alive = self.alive.get((service, instance))
        if not seen:
            return NodeFacts(service, instance, alive=alive, has_status=False)
        first, last = seen[0], seen[-1]
        counters = {k: v - (first.extra.get(k, 0) if len(seen) > 1 else 0) for k, v in last.extra.items()}
        for name in ("received", "published", "dropped", "invalid"):
            counters[name] = getattr(last, name) - (getattr(first, name) if len(seen) > 1 else 0)
        return NodeFacts(
            service, instance, alive=alive if last.state == "running" else False, state=last.state, error=last.error,
            exit_status=last.exit_status, host=last.host, uptime_s=last.uptime_s, counters=counters,
            last=dict(last.extra),
            window_s=last.uptime_s - first.uptime_s if len(seen) > 1 else 0.0, settings=dict(last.settings),
            subscribes=[relative_key(k) for k in last.subscribes], publishes=[relative_key(k) for k in last.publishes])

    def observation(self, duration_s: float, source: str = "live", end_ns: int | None = None,
                    liveliness: bool = True) -> Observation:
        """The facts so far. Without ``liveliness`` (a recording) a node's ``alive`` is unknown."""
        names = set(self.statuses) | set(self.alive)
        nodes = [self._node(s, i) for s, i in sorted(names)]
        if not liveliness:
            for n in nodes:
                n.alive = None if n.state == "running" else False
        return Observation(
            duration_s=duration_s, source=source, end_ns=self.last_ns if end_ns is None else end_ns,
            streams=dict(self.streams), nodes=nodes, frames={k: list(v) for k, v in self.frames.items()},
            scans={k: dataclasses.replace(v, frame_ids=list(v.frame_ids)) for k, v in self.scans.items()},
            offsets_ns={k: list(v) for k, v in self.offsets.items()}, edges=list(self.edges.values()),
            stages={cam: {s: dict(keys) for s, keys in st.items()} for cam, st in self.stages.items()},
            cards=sorted(self.cards), track_models=sorted(self.track_models), track_frames=sorted(self.track_frames),
            localized_frames=sorted(self.localized_frames), floor_cameras=sorted(self.floor_cameras),
            floor_camera_frames=sorted(self.floor_camera_frames), position_only=self.position_only,
            tracks_total=self.tracks_total, boxes_total=self.boxes_total, ros2_graph=_graph(self.ros2_tokens),
            other_robots={k: sorted(v) for k, v in sorted(self.other_robots.items())}, people=list(self.people),
            ros2_domain=self.ros2_domain)


def _graph(tokens: set[str]) -> list[GraphEntity]:
    out = []
    for key in sorted(tokens):
        try:
            out.append(parse_token(key))
        except ValueError:
            continue  # a token of another rmw_zenoh version or not rmw_zenoh's
    return out
