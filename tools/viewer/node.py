"""The viewer node: listens to one camera's streams, the tracks, the transforms and the
nodes' health, and keeps the newest page state for any number of browsers.

It publishes nothing on Zenoh. ``poll`` drains what arrived, hands every message to the
optional sinks (the Foxglove bridge) and, at most ``state_hz`` times a second, writes the
page state into :class:`~tools.viewer.web.LatestState`. Each 2-D laser's newest scan
(``scans/*``) goes on the map through the transforms, and the people of a position-only stream
(``localized/*`` without a camera view: the laser's) as rings, never as image boxes. The camera
image is JPEG-encoded only while a browser asks for it, at most ``image_hz`` times a second.
"""

from __future__ import annotations

import threading
import time
from collections import deque
from dataclasses import replace
from typing import Any, Callable, Protocol

import numpy as np

from common.geometry.transforms import RigidTransform, TransformBuffer, TransformError
from common.geometry.messages import OCCUPIED_PERCENT, add_batch, static_map_from_grid
from common.messages.keys import MAPS, RELIABLE, SCANS, STATUS, Delivery, Keys
from common.runtime.node import Node
from common.messages.registry import stages
from common.runtime.service import Counters, Shutdown
from common.messages.schemas import (Detections, Embeddings, Header, IdDecisions, IdDecisionState, LaserScan,
                                     LocalizedDetections, Message, RGBDFrame, ServiceStatus, StaticMap, Tracks,
                                     TransformBatch)
from common.transport.base import Subscription, Transport
from tools.drawing.images import jpeg_of
from tools.drawing.tracks import label_boxes, project_to_image
from tools.viewer.config import ViewerConfig
from tools.viewer.core.health import NodeSeen, health
from tools.drawing.meters import StageMeter
from tools.viewer.core.drawing import Trails, colour_hex, occupied_runs, yaw_of
from tools.viewer.core.scans import Newest, flat, no_box, scan_points
from tools.viewer.web import LatestState

__all__ = ["STAGES", "Sink", "ViewerNode"]

# The viewer reads on its own schedule (``wake=False``): samples wait in the transport until
# a poll, and no thread is woken per sample.
#: Small messages the viewer reads: the newest 64 (it only needs the newest).
#: the ID decisions the page lists
_DECISIONS = 6
#: a map file goes to the sinks (Foxglove) this often, for clients that connect later
_MAP_PERIOD_S = 5.0
_LOOSE = Delivery(latest=False, queue=64, congestion="drop", wake=False)
#: Frames: the few that arrive between two polls, so the camera's rate counts each of them
#: (only the newest is decoded); older ones are dropped uncounted.
_FEW_FRAMES = Delivery(latest=False, queue=16, congestion="drop", express=True, wake=False)
#: Scans: every laser's (``scans/*``), each one read, the newest of each drawn.
_SCANS = replace(SCANS, wake=False)
#: A laser's scan or people leave the page once none came for this long (s).
_LASER_STALE_S = 1.0
#: Transforms and statuses: every one is read.
_EVERY_TF = replace(RELIABLE, wake=False)
_EVERY_STATUS = replace(STATUS, wake=False)
#: With a sink (the Foxglove bridge) the viewer wakes at most this often (Hz) and forwards
#: every message; without one it wakes as often as the page refreshes. Each wake-up drains
#: every stream at once.
POLL_HZ = 20.0
#: The stages whose rate and latency the page shows, in pipeline order ("camera": the frames).
STAGES = ("camera", *stages())
#: A browser watches while it has asked for something within this long (s): images are
#: encoded, and states built at the page's rate, only then.
_IMAGE_INTEREST_S = 2.0
#: The stages' rates and latencies in the page state are recomputed this often (s).
_STAGES_EVERY_S = 1.0


class Sink(Protocol):
    """Another view of the streams (the Foxglove bridge): it gets every message the viewer reads."""

    def on_message(self, stream: str, msg: Message) -> None: ...

    def close(self) -> None: ...


class ViewerNode(Node):
    """Reads the streams of ``config.camera``; writes the page state to ``state``."""

    name = "viewer"

    def __init__(self, transport: Transport, keys: Keys, config: ViewerConfig, counters: Counters | None = None, *,
                 state: LatestState | None = None, sinks: tuple[Sink, ...] = ()) -> None:
        super().__init__(transport, keys, counters)
        self.config = config
        self.state = state
        self.sinks = sinks
        #: Wake-ups per second: the page needs no more than its own refresh rates.
        self.poll_hz = POLL_HZ if sinks else max(config.state_hz, config.image_hz)
        cam = config.camera
        self.subs: dict[str, Subscription[Any]] = {
            "camera": self.io.subscribe(keys.frames(cam), RGBDFrame, _FEW_FRAMES),
            "detector": self.io.subscribe(keys.detections(cam), Detections, _LOOSE),
            "localizer": self.io.subscribe(keys.localized(cam), LocalizedDetections, _LOOSE),
            "embedder": self.io.subscribe(keys.embeddings(cam), Embeddings, _LOOSE),
            "tracker": self.io.subscribe(keys.tracks(), Tracks, _LOOSE),
            "tf": self.io.subscribe(keys.tf(), TransformBatch, _EVERY_TF),
            "tf_static": self.io.subscribe(keys.tf_static(), TransformBatch, _EVERY_TF),
            "status": self.io.subscribe(keys.status(), ServiceStatus, _EVERY_STATUS),
            "id_decisions": self.io.subscribe(keys.id_decisions(), IdDecisions, _EVERY_STATUS),
            "static_map": self.io.subscribe(keys.static_map(), StaticMap, replace(MAPS, wake=False)),
            "scans": self.io.subscribe(keys.scans("*"), LaserScan, _SCANS),
            # every localized stream: only those without a camera view (a laser's people) are kept
            "laser": self.io.subscribe(keys.localized("*"), LocalizedDetections, _LOOSE),
        }
        self._camera_localized = keys.localized(cam)
        #: each laser's newest scan, and each position-only stream's newest people, by key name
        self.scans: Newest[LaserScan] = Newest(_LASER_STALE_S)
        self.laser_people: Newest[LocalizedDetections] = Newest(_LASER_STALE_S)
        self._map: dict[str, Any] | None = None  # the newest static map's version and extent
        self._file_map: StaticMap | None = None  # a map file, for the sinks too (every few seconds)
        self._file_map_at = -1e9
        if config.grid is not None:  # a map file: drawn in the map frame
            g = config.grid
            self._show_map(("file",), config.map_frame, g.resolution, g.origin, g.occupied)
            self._file_map = static_map_from_grid(g, Header(stamp_ns=time.time_ns(), frame_id=config.map_frame,
                                                            source="viewer"))
        self.meters = {stage: StageMeter() for stage in STAGES}
        self.trails = Trails(span_s=config.trail_s)
        self.buffer = TransformBuffer(history_s=10.0, tolerance_s=0.1)
        self.latest: dict[str, Any] = {}
        #: the tracker's latest ID decisions, newest last: (when they arrived, the decision)
        self.decisions: deque[tuple[float, IdDecisionState]] = deque(maxlen=_DECISIONS)
        self.nodes: dict[tuple[str, str], NodeSeen] = {}
        self._alive_events: list[tuple[str, bool]] = []
        self._alive_lock = threading.Lock()
        self._dirty = True
        self._last_state = -1e9
        self._last_image = -1e9
        self._image_seq = -1
        self._image_info: dict[str, int] | None = None
        self._stages_cache: dict[str, dict[str, Any]] | None = None
        self._stages_at = -1e9
        self._on_close: list[Any] = []
        self._unwatch = transport.watch_alive(keys.alive(), self._on_alive)

    def on_close(self, fn: Any) -> None:
        """Call ``fn()`` when the node closes (the page's server)."""
        self._on_close.append(fn)

    def describe(self) -> str:
        return f"viewing camera {self.config.camera!r} and the tracks in {self.config.map_frame!r}"

    def _on_alive(self, key: str, alive: bool) -> None:  # the transport's thread
        with self._alive_lock:
            self._alive_events.append((key, alive))

    # ------------------------------------------------------------------ inputs

    def _take(self, now: float) -> None:
        for stream, sub in self.subs.items():
            if stream in self.meters and not self.sinks:
                self._take_newest(stream, sub, now)
                continue
            while (got := sub.try_recv()) is not None:
                msg = got.msg
                if stream == "laser" and (got.key == self._camera_localized or msg.view is not None):
                    continue  # the camera's own (read as "localizer"), or another camera's
                self._dirty = True
                for sink in self.sinks:
                    sink.on_message(stream, msg)
                if stream in self.meters:
                    self.meters[stream].add(now, (got.recv_ns - msg.header.stamp_ns) / 1e6)
                    self.latest[stream] = msg
                if isinstance(msg, Tracks):
                    self._trail(msg, now)
                elif isinstance(msg, IdDecisions):
                    self.decisions.extend((now, d) for d in msg.decisions)
                elif isinstance(msg, StaticMap):
                    self._take_map(msg)
                elif isinstance(msg, LaserScan):
                    self.scans.put(got.key.rsplit("/", 1)[-1], now, msg)
                elif stream == "laser":
                    self.laser_people.put(got.key.rsplit("/", 1)[-1], now, msg)
                elif isinstance(msg, TransformBatch):
                    add_batch(self.buffer, msg, static=stream == "tf_static")
                elif isinstance(msg, ServiceStatus):
                    seen = self.nodes.setdefault((msg.name, msg.instance), NodeSeen(msg.name, msg.instance))
                    seen.status_at, seen.state, seen.error = now, msg.state, msg.error
                    seen.counters = {"received": msg.received, "published": msg.published, "dropped": msg.dropped,
                                     "invalid": msg.invalid, "host": msg.host}
                    if msg.state == "failed":
                        seen.alive = False
        with self._alive_lock:
            events, self._alive_events = self._alive_events, []
        for key, alive in events:
            try:
                name, instance = self.keys.parse_alive(key)
            except ValueError:
                continue
            self.nodes.setdefault((name, instance), NodeSeen(name, instance)).alive = alive
            self._dirty = True

    def _take_newest(self, stream: str, sub: Subscription[Any], now: float) -> None:
        """A stream the page shows only the newest of: every arrival counts towards its rate,
        but only the newest is decoded (with no sink, that is the viewer's main saving: it
        decodes at most one camera frame per wake-up, not each of 30 a second)."""
        got, arrivals = sub.take_newest()
        if not arrivals:
            return
        wall_ns = time.time_ns()
        meter = self.meters[stream]
        meter.arrived(now - (wall_ns - recv_ns) / 1e9 for recv_ns in arrivals)
        if got is None:
            return
        self._dirty = True
        meter.sample(now, (got.recv_ns - got.msg.header.stamp_ns) / 1e6)
        self.latest[stream] = got.msg
        if isinstance(got.msg, Tracks):
            self._trail(got.msg, now)

    def _take_map(self, grid: StaticMap) -> None:
        """The static_map stream's map (cells 65 % occupied and more), unless a file was given."""
        if self.config.grid is None:
            self._show_map(grid.content(), grid.header.frame_id, grid.resolution, grid.origin,
                           grid.occupancy() >= OCCUPIED_PERCENT)

    def _show_map(self, seen: tuple[object, ...], frame_id: str, resolution: float, origin: tuple[float, float, float],
                  occupied: np.ndarray) -> None:
        """The robot's map for the page: its occupied cells as runs, sent once per map (``/api/map``;
        ``seen``: what makes it this map); one re-sent unchanged is not sent again."""
        if self._map is not None and self._map["seen"] == seen:
            return
        version = 1 if self._map is None else self._map["version"] + 1
        self._map = {"seen": seen, "version": version, "frame_id": frame_id}
        if self.state is not None:
            self.state.set_map({"version": version, "frame_id": frame_id, "resolution": resolution,
                                "origin": list(origin), "width": occupied.shape[1], "height": occupied.shape[0],
                                "runs": occupied_runs(occupied)})

    def _trail(self, tracks: Tracks, now: float) -> None:
        for t in tracks.tracks:
            self.trails.add(t.id, now, float(t.position[0]), float(t.position[1]))

    # ------------------------------------------------------------------ outputs

    def _robot(self) -> dict[str, float] | None:
        try:
            tf = self.buffer.lookup(self.config.map_frame, self.config.base_frame, None)
        except (TransformError, KeyError):
            return None
        return {"x": float(tf.translation[0]), "y": float(tf.translation[1]), "yaw": yaw_of(tf.rotation_matrix)}

    def _to_map(self, frame: str, stamp_ns: int) -> RigidTransform | None:
        """``frame`` -> the map frame at ``stamp_ns``, else the newest (a scan a little ahead of the
        transforms is drawn where the robot was last seen); None without a chain of transforms."""
        for stamp in (stamp_ns, None):
            try:
                return self.buffer.lookup(self.config.map_frame, frame, stamp)
            except (TransformError, KeyError):
                continue
        return None

    def _scans(self, now: float) -> list[dict[str, Any]]:
        """Each laser's newest scan: its returns' points in the map (flat x, y pairs), or why none."""
        out = []
        for laser, (at, scan) in self.scans.fresh(now).items():
            frame = scan.header.frame_id
            entry: dict[str, Any] = {"laser": laser, "frame_id": frame, "age_s": round(now - at, 2),
                                     "beams": len(scan.ranges), "points": []}
            tf = self._to_map(frame, scan.header.stamp_ns) if frame else None
            if not frame:
                entry["error"] = "the scan names no frame"
            elif tf is None:
                entry["error"] = f"no transform {self.config.map_frame} <- {frame}"
            else:
                entry["points"] = flat(scan_points(scan.ranges, scan.angle_min, scan.angle_increment, scan.range_min,
                                                   scan.range_max, tf.rotation_matrix, tf.translation))
            out.append(entry)
        return out

    def _laser_people(self, now: float) -> list[dict[str, Any]]:
        """The people of each position-only stream (the laser's): those with no image box, in the map."""
        out = []
        for source, (_, loc) in self.laser_people.fresh(now).items():
            if not loc.detections:
                continue
            frame = loc.header.frame_id or self.config.map_frame
            tf = self._to_map(frame, loc.header.stamp_ns)
            if tf is None:
                continue
            unboxed = no_box(np.array([d.bbox_xyxy for d in loc.detections], np.float64))
            for d in (d for d, empty in zip(loc.detections, unboxed) if empty):
                x, y = (tf.rotation_matrix @ np.asarray(d.position, np.float64) + tf.translation)[:2]
                out.append({"source": source, "x": round(float(x), 3), "y": round(float(y), 3),
                            "score": round(float(d.score), 3)})
        return out

    def _boxes(self) -> list[dict[str, Any]]:
        dets: Detections | None = self.latest.get("detector")
        if dets is None:
            return []
        boxes = np.array([d.bbox_xyxy for d in dets.detections], np.float64).reshape(-1, 4)
        drawn = ~no_box(boxes)  # a zero box (a position-only detection) is no box to draw
        boxes, kept = boxes[drawn], [d for d, box in zip(dets.detections, drawn) if box]
        tracks: Tracks | None = self.latest.get("tracker")
        loc: LocalizedDetections | None = self.latest.get("localizer")
        labels: list[int | None] = [None] * len(boxes)
        if tracks is not None and tracks.tracks and loc is not None and loc.view is not None:
            view = loc.view
            pixels = project_to_image(np.array([t.position for t in tracks.tracks]), view.camera_to_frame, view.K,
                                      view.width, view.height)
            labels = label_boxes(boxes, pixels, np.array([t.id for t in tracks.tracks]))
        return [{"bbox": [round(float(v), 1) for v in box], "score": round(d.score, 3), "id": label,
                 "colour": colour_hex(label) if label is not None else "#cccccc"}
                for box, d, label in zip(boxes, kept, labels)]

    def snapshot(self, now: float) -> dict[str, Any]:
        """The page state: tracks with trails, the robot, the image's boxes, stages and nodes."""
        self.trails.prune(now)
        tracks: Tracks | None = self.latest.get("tracker")
        out_tracks = []
        for t in sorted(tracks.tracks if tracks else [], key=lambda t: t.id):
            out_tracks.append({"id": t.id, "x": round(float(t.position[0]), 3), "y": round(float(t.position[1]), 3),
                               "vx": round(float(t.velocity[0]), 3), "vy": round(float(t.velocity[1]), 3),
                               "status": t.status, "hits": t.hits, "age_s": round(t.age_s, 1),
                               "colour": colour_hex(t.id),
                               "trail": [[round(x, 3), round(y, 3)] for x, y in self.trails.get(t.id)]})
        nodes = []
        for (name, instance), seen in sorted(self.nodes.items()):
            nodes.append({"name": name, "instance": instance, "health": health(seen, now), "error": seen.error,
                          **seen.counters})
        return {
            "time": time.time(),
            "camera": self.config.camera,
            "map_frame": self.config.map_frame,
            "static_map": None if self._map is None else {"version": self._map["version"],
                                                           "frame_id": self._map["frame_id"]},
            "robot": self._robot(),
            "tracks": out_tracks,
            "appearance_available": tracks.appearance_available if tracks else None,
            "image": self._image_info,
            "boxes": self._boxes(),
            "scans": self._scans(now),
            "laser_people": self._laser_people(now),
            "stages": self._stages(now),
            "nodes": nodes,
            "id_decisions": [{"id": d.id, "outcome": d.outcome, "text": d.summary, "age_s": round(now - at, 1)}
                             for at, d in reversed(self.decisions)],
        }

    def _stages(self, now: float) -> list[dict[str, Any]]:
        """Each stage's count, rate and latency. Rates and latencies are windows of seconds and
        are recomputed at most once a second (their percentiles were the page state's largest
        cost); the counts are current."""
        if self._stages_cache is None or now - self._stages_at >= _STAGES_EVERY_S:
            self._stages_cache = {s: {"rate_hz": round(m.rate_hz(now), 2),
                                      "latency_p50_ms": _round(m.latency_ms(50, now)),
                                      "latency_p95_ms": _round(m.latency_ms(95, now))}
                                  for s, m in self.meters.items()}
            self._stages_at = now
        return [{"name": s, "count": m.count, **self._stages_cache[s]} for s, m in self.meters.items()]

    def poll(self, now: float) -> list[Any]:
        self._take(now)
        if self._file_map is not None and self.sinks and now - self._file_map_at >= _MAP_PERIOD_S:
            self._file_map_at = now
            msg = self._file_map.model_copy(update={"header": self._file_map.header.model_copy(
                update={"stamp_ns": time.time_ns()})})
            for sink in self.sinks:
                sink.on_message("static_map", msg)
        if self.state is None:
            return []
        frame: RGBDFrame | None = self.latest.get("camera")
        watched = time.monotonic() - self.state.watched_at < _IMAGE_INTEREST_S
        if (frame is not None and frame.header.seq != self._image_seq and watched
                and now - self._last_image >= 1.0 / self.config.image_hz):
            self.state.set_image(jpeg_of(frame, self.config.jpeg_quality), frame.header.seq)
            self._image_seq, self._last_image = frame.header.seq, now
            self._image_info = {"seq": frame.header.seq, "width": frame.camera_info.width,
                                "height": frame.camera_info.height}
            self._dirty = True
        # nobody watching: one state a second keeps the page's first request fresh, and costs little
        period = 1.0 / self.config.state_hz if watched else 1.0
        if (self._dirty and now - self._last_state >= period) or now - self._last_state >= 1.0:
            self.state.set_state(self.snapshot(now))
            self._dirty, self._last_state = False, now
        return []

    def run(self, shutdown: Shutdown, clock: Callable[[], float] = time.monotonic) -> None:
        """Poll at most ``poll_hz`` times a second: a page refreshed at ``state_hz`` needs no
        wake-up per message, and batching them is much of the viewer's CPU saving."""
        while not shutdown.is_set():
            started = clock()
            self.poll(started)
            wait = self.deadline(clock())
            shutdown.wait(max(1.0 / self.poll_hz - (clock() - started), 0.0 if wait is None else min(wait, 0.2)))

    def deadline(self, now: float) -> float | None:
        return max(0.0, self._last_state + 1.0 / self.config.state_hz - now) if self._dirty else None

    def close(self) -> None:
        self._unwatch()
        for fn in self._on_close:
            fn()
        for sink in self.sinks:
            sink.close()
        super().close()


def _round(value: float | None) -> float | None:
    return None if value is None else round(value, 1)
