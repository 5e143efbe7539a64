"""The ROS 2 node: a ROS 2 robot's camera, transforms and laser scans in, its people out, over rmw_zenoh.

ROS 2 topics are Zenoh keys with CDR payloads (``services.ros2.core.wire``), so this node is a
ROS 2 participant on the robot's own router: no bridge process, no ROS install. It appears in
the ROS 2 graph (``ros2 node list``, ``ros2 topic list``) through rmw_zenoh's liveliness tokens.

In (each switchable): colour + depth + camera info -> ``frames/{camera}`` (approximate-time
pairing); ``/tf`` and ``/tf_static`` -> ``tf`` and ``tf_static``; ``/map`` -> ``static_map``
(:class:`~services.ros2.maps.MapRelay`); each laser's ``sensor_msgs/LaserScan`` (``/scan``) ->
``scans/{laser}``. Out: the tracker's ``tracks``
-> ``/humans/bodies/...``, ``body_<id>`` frames on ``/tf`` and ``/humans/markers``.

Each ROS topic is read on ``<domain>/<topic>/*/*``, every type and hash: a sample of another
type or hash (another distribution, a compressed topic read as raw) is counted and named in the
log instead of never arriving. Every bad sample is counted under its reason, logged at most once
a second, and skipped.
"""

from __future__ import annotations

import logging
from dataclasses import dataclass
from functools import partial
from typing import Any, Callable

from common.geometry.messages import transform_from_ros
from common.messages.keys import FRAMES, MAPS, RELIABLE, SCANS, Delivery, Keys
from common.runtime.node import Node
from common.runtime.pairing import StampPairer
from common.runtime.ratelog import RateLimitedLog
from common.runtime.service import Counters
from common.messages.schemas import (CameraInfo, Header, Image, LaserScan, RGBDFrame, StaticMap, TrackState,
                                     TransformBatch, Tracks)
from common.transport.base import Publisher, RawSample, RawSubscription, Transport
from services.ros2.config import Ros2Config
from services.ros2.core.images import ImageError, Intrinsics, Pixels, compressed_pixels, intrinsics, raw_pixels
from services.ros2.core.people import PeopleWriter, Person
from services.ros2.core.scans import ScanError, checked_scan
from services.ros2.core.types import CdrError, known_hashes, types_of
from services.ros2.core.wire import Qos, dds_to_ros, parse_attachment
from services.ros2.maps import MapRelay
from services.ros2.participant import QOS_DEFAULT, QOS_SENSOR, QOS_TF, QOS_TF_STATIC, RosParticipant

__all__ = ["Ros2Service"]

log = logging.getLogger(__name__)

#: A body's publishers are kept this long after it was last tracked, then undeclared.
BODY_LINGER_S = 10.0


@dataclass
class _Topic:
    """One ROS topic this node reads: its expected type and what to do with a sample."""

    topic: str
    type_name: str
    handle: Callable[[Any], None]
    sub: RawSubscription


class Ros2Service(Node):
    """ROS 2 camera and tf in, people out; see the module's doc."""

    name = "ros2"

    def __init__(self, transport: Transport, keys: Keys, config: Ros2Config, counters: Counters | None = None) -> None:
        super().__init__(transport, keys, counters)
        self.config = config
        self.types = types_of(config.distro)
        self._log = RateLimitedLog(log, period_s=config.log_every_s)
        self.ros = RosParticipant(transport, self.types, domain_id=config.domain_id, node_name=config.node_name,
                                  namespace=config.namespace, io=self.io)
        self._topics: list[_Topic] = []
        self._body_seen: dict[int, float] = {}
        self._seq = 0
        self._now = 0.0
        self._camera_info: Intrinsics | None = None
        self._static: dict[str, Any] = {}
        self._static_sent = -1e9
        # an RGB-only camera: each colour image goes out at once
        # colour items carry the image's frame id along with its pixels
        self.pairer: StampPairer[tuple[str, Pixels], Pixels] = StampPairer(
            int(config.slop_s * 1e9), wait_s=config.pair_wait_s, queue=config.image_queue,
            expect_depth=bool(config.depth_topic), depth_queue=4 * config.image_queue)
        if config.camera_in:
            self.frames_pub = self.io.publisher(keys.frames(config.camera), RGBDFrame, FRAMES)
            colour_type = "sensor_msgs/msg/CompressedImage" if config.colour_compressed else "sensor_msgs/msg/Image"
            self._read(config.camera_info_topic, "sensor_msgs/msg/CameraInfo", self._on_camera_info, QOS_SENSOR)
            self._read(config.colour_topic, colour_type, self._on_colour, QOS_SENSOR)
            if config.depth_topic:
                depth_type = "sensor_msgs/msg/CompressedImage" if config.depth_compressed else "sensor_msgs/msg/Image"
                self._read(config.depth_topic, depth_type, self._on_depth, QOS_SENSOR)
        if config.tf_in:
            self.tf_pub = self.io.publisher(keys.tf(), TransformBatch, RELIABLE)
            self.tf_static_pub = self.io.publisher(keys.tf_static(), TransformBatch, RELIABLE)
            self._read(config.tf_topic, "tf2_msgs/msg/TFMessage", self._on_tf, QOS_TF)
            self._read(config.tf_static_topic, "tf2_msgs/msg/TFMessage", self._on_tf_static, QOS_TF_STATIC, history=16)
        self.maps: MapRelay | None = None
        if config.map_topic:  # the robot's map, transient local as map_server publishes it
            self.maps = MapRelay(self.io.publisher(keys.static_map(), StaticMap, MAPS).put, config.map_period_s)
            self._read(config.map_topic, "nav_msgs/msg/OccupancyGrid", self._on_map, QOS_TF_STATIC, history=1)
        # each laser's scans, as its driver publishes them (sensor data: best effort)
        self._scan_seq: dict[str, int] = {}
        for topic, laser in config.scan_topics():
            pub = self.io.publisher(keys.scans(laser), LaserScan, SCANS)
            self._scan_seq[laser] = 0
            self._read(topic, "sensor_msgs/msg/LaserScan", partial(self._on_scan, laser, pub), QOS_SENSOR)
        if config.people_out:
            self.tracks_sub = self.io.subscribe(keys.tracks(), Tracks, Delivery(latest=False, queue=config.queue,
                                                                                 congestion="block"))
            self.writer = PeopleWriter(self.types, prefix=config.body_prefix, namespace=config.humans_namespace,
                                       markers_topic=config.markers_topic, marker_lifetime_s=config.marker_lifetime_s)

    def _read(self, topic: str, type_name: str, handle: Callable[[Any], None], qos: Qos,
              history: int = 0) -> None:
        sub = self.ros.subscription(topic, type_name, qos, history=history)
        self._topics.append(_Topic(topic, type_name, handle, sub))

    # ------------------------------------------------------------------ input
    def _bad(self, reason: str, text: str) -> None:
        self.counters.count(f"invalid_{reason}")
        self.counters.invalid += 1
        self._log.warning(reason, "%s", text)

    def _take(self, t: _Topic, sample: RawSample) -> None:
        parts = sample.key.split("/")
        dds_type, type_hash = parts[-2], parts[-1]
        try:
            got_type = dds_to_ros(dds_type)
        except ValueError:
            self._bad("not_ros", f"{sample.key}: not an rmw_zenoh topic key (no type in it)")
            return
        if got_type != t.type_name:
            self._bad("wrong_type", f"{t.topic} carries {got_type}, this node reads {t.type_name} there: "
                                    + _type_fix(t.topic, got_type))
            return
        if type_hash != self.types.hash(t.type_name):
            distros = known_hashes(t.type_name).get(type_hash)
            origin = f"the hash of {distros}" if distros else ("Humble's rmw_zenoh, which writes no hash"
                                                               if "TypeHashNotSupported" in type_hash else "an unknown hash")
            self._bad("type_hash", f"{t.topic}: {t.type_name} with {type_hash[:18]}... ({origin}); this node reads "
                                   f"{self.config.distro}'s {self.types.hash(t.type_name)[:18]}...: set distro to the "
                                   "robot's ROS 2 distribution")
            return
        try:
            att = parse_attachment(sample.attachment)
        except ValueError as exc:
            self._bad("attachment", f"{t.topic}: {exc}")
            return
        if att.gid in self.ros.gids:
            return  # this node's own /tf
        try:
            msg = self.types.deserialize(sample.payload, t.type_name)
        except CdrError as exc:
            self._bad("cdr", f"{t.topic}: {exc}")
            return
        try:
            t.handle(msg)
        except (ImageError, ScanError) as exc:
            self._bad(exc.reason, f"{t.topic}: {exc}")
        except (ValueError, TypeError, AttributeError) as exc:
            self._bad("message", f"{t.topic}: {type(exc).__name__}: {exc}")

    def _on_camera_info(self, msg: Any) -> None:
        self._camera_info = intrinsics(msg)

    def _pixels(self, msg: Any, compressed: bool, depth: bool) -> Pixels:
        return compressed_pixels(msg, depth=depth) if compressed else raw_pixels(msg, depth=depth)

    def _on_colour(self, msg: Any) -> None:
        pixels = self._pixels(msg, self.config.colour_compressed, depth=False)
        self.pairer.add_colour(_stamp_ns(msg.header.stamp), (str(msg.header.frame_id), pixels), self._now)

    def _on_depth(self, msg: Any) -> None:
        self.pairer.add_depth(_stamp_ns(msg.header.stamp), self._pixels(msg, self.config.depth_compressed, depth=True))

    def _on_tf(self, msg: Any) -> None:
        transforms = [transform_from_ros(t) for t in msg.transforms]
        if transforms:
            self.tf_pub.put(TransformBatch(header=Header(stamp_ns=max(t.stamp_ns for t in transforms), source="ros2"),
                                           transforms=transforms))

    def _on_tf_static(self, msg: Any) -> None:
        for t in msg.transforms:
            tr = transform_from_ros(t, static=True)
            self._static[tr.child_frame] = tr
        self._send_static(force=True)

    def _send_static(self, force: bool = False) -> None:
        now = self._now
        if not self._static or (not force and now - self._static_sent < self.config.static_period_s):
            return
        self._static_sent = now
        transforms = list(self._static.values())
        self.tf_static_pub.put(TransformBatch(header=Header(stamp_ns=max(t.stamp_ns for t in transforms), source="ros2"),
                                              transforms=transforms))

    def _on_map(self, msg: Any) -> None:
        self.maps.take(msg, self._now)  # type: ignore[union-attr]
        self.counters.count("maps")

    def _on_scan(self, laser: str, pub: Publisher[LaserScan], msg: Any) -> None:
        checked = checked_scan(msg)
        seq = self._scan_seq[laser] + 1
        try:
            scan = LaserScan.from_ros(checked, laser, seq)
        except ValueError as exc:  # pydantic's: a field LaserScan refuses, named
            raise ScanError("scan", " ".join(str(exc).split())[:300]) from exc
        self._scan_seq[laser] = seq
        pub.put(scan)
        self.counters.count("scans")

    def _frames(self, now: float) -> list[RGBDFrame]:
        out = []
        for pair in self.pairer.ready(now):
            frame_id, colour = pair.colour
            if pair.depth is None and (self.config.require_depth and self.config.depth_topic):
                self.counters.drop(f"colour_{pair.why}")
                self._log.warning(pair.why, "a colour image at %.3f s has no depth image within %.0f ms on %s (%s): "
                                  "dropped; is the depth topic published, and aligned to colour?", pair.stamp_ns / 1e9,
                                  self.config.slop_s * 1e3, self.config.depth_topic, pair.why)
                continue
            if self._camera_info is None:
                self.counters.drop("no_camera_info")
                self._log.warning("no_camera_info", "no camera info yet on %s: images dropped until it comes",
                                  self.config.camera_info_topic)
                continue
            try:
                out.append(self._frame(pair.stamp_ns, frame_id, colour, pair.depth))
            except ImageError as exc:
                self._bad(exc.reason, f"{self.config.colour_topic}: {exc}")
            except ValueError as exc:
                self._bad("frame", f"{self.config.colour_topic}: {exc}")
        return out

    def _frame(self, stamp_ns: int, frame_id: str, colour: Pixels, depth: Pixels | None) -> RGBDFrame:
        info = self._camera_info
        assert info is not None
        h, w = colour.shape[:2]
        if (info.height, info.width) != (h, w):
            raise ImageError("size", f"camera info is {info.width}x{info.height}, the colour image {w}x{h}: is the "
                                     "camera info the colour camera's?")
        if depth is not None and depth.shape[:2] != (h, w):
            raise ImageError("size", f"depth is {depth.shape[1]}x{depth.shape[0]}, colour {w}x{h}: read the depth "
                                     "aligned to colour (aligned_depth_to_color)")
        self._seq += 1
        header = Header(stamp_ns=stamp_ns, frame_id=frame_id, seq=self._seq, source=self.config.camera)
        K = info.K
        return RGBDFrame(
            header=header,
            rgb=Image(header=header, encoding=colour.encoding, dtype=colour.dtype, shape=colour.shape,  # type: ignore[arg-type]
                      data=bytes(colour.data)),
            depth=None if depth is None else Image(header=header, encoding=depth.encoding, dtype=depth.dtype,  # type: ignore[arg-type]
                                                   shape=depth.shape, data=bytes(depth.data)),
            camera_info=CameraInfo(header=header, width=info.width, height=info.height, K=K, D=info.D,
                                   distortion_model=info.distortion_model))  # type: ignore[arg-type]

    # ------------------------------------------------------------------ output
    def _people(self, msg: Tracks) -> list[Person]:
        wanted = ("confirmed", "coasting") if self.config.include_coasting else ("confirmed",)
        return [_person(t) for t in msg.tracks if t.status in wanted]

    def _publish_people(self, msg: Tracks, now: float) -> int:
        self.writer.frame = msg.header.frame_id or "map"
        people = self._people(msg)
        count = 0
        for topic, type_name, ros_msg in self.writer.messages(msg.header.stamp_ns, people):
            if topic == "/tf" and not self.config.body_frames:
                continue
            qos = QOS_TF if topic == "/tf" else QOS_DEFAULT
            self.ros.publisher(topic, type_name, qos).put(ros_msg, msg.header.stamp_ns)
            count += 1
        for p in people:
            self._body_seen[p.track_id] = now
        for tid, seen in list(self._body_seen.items()):
            if now - seen > BODY_LINGER_S:
                del self._body_seen[tid]
                for leaf in ("position", "velocity", "posture"):
                    self.counters.count("ros_published_retired", self.ros.drop(self.writer.topic(tid, leaf)))
        return count

    # ------------------------------------------------------------------ the loop
    def poll(self, now: float) -> list[Any]:
        out: list[Any] = []
        self._now = now
        for t in self._topics:
            while (sample := t.sub.try_recv()) is not None:
                self._take(t, sample)
        if self.config.camera_in:
            for frame in self._frames(now):
                self.frames_pub.put(frame)
                out.append(frame)
            self.counters.gauge("depth_unpaired", self.pairer.stale_depth)
        if self.config.tf_in:
            self._send_static()
        if self.maps is not None:
            self.maps.poll(now)
        if self.config.people_out:
            while (got := self.tracks_sub.try_recv()) is not None:
                self._publish_people(got.msg, now)
                out.append(got.msg)
        self.counters.gauge("ros_publishers", len(self.ros.publishers))
        self.counters.gauge("ros_published", sum(p.seq for p in self.ros.publishers.values()))
        return out

    def deadline(self, now: float) -> float | None:
        if self.config.camera_in and len(self.pairer):
            return self.config.pair_wait_s / 4
        if self.config.tf_in and self._static:
            return self.config.static_period_s
        if self.maps is not None and self.maps.latest is not None:
            return self.config.map_period_s
        return None

    def describe(self) -> str:
        parts = []
        if self.config.camera_in:
            parts.append(f"{self.config.colour_topic} + {self.config.depth_topic or '(no depth)'} + "
                         f"{self.config.camera_info_topic} -> {self.keys.frames(self.config.camera)}")
        if self.config.tf_in:
            parts.append(f"{self.config.tf_topic}, {self.config.tf_static_topic} -> tf, tf_static")
        if self.config.map_topic:
            parts.append(f"{self.config.map_topic} -> static_map")
        for topic, laser in self.config.scan_topics():
            parts.append(f"{topic} -> {self.keys.scans(laser)}")
        if self.config.people_out:
            parts.append(f"tracks -> {self.config.humans_namespace}/bodies/..., /tf, {self.config.markers_topic}")
        return f"ROS 2 domain {self.config.domain_id} ({self.config.distro}), node {self.config.node_name}: " + "; ".join(parts)

    def close(self) -> None:
        self.ros.close()
        super().close()


def _stamp_ns(stamp: Any) -> int:
    return int(stamp.sec) * 1_000_000_000 + int(stamp.nanosec)


def _person(t: TrackState) -> Person:
    return Person(track_id=t.id, position=tuple(float(v) for v in t.position),  # type: ignore[arg-type]
                  velocity=tuple(float(v) for v in t.velocity), posture=tuple(t.posture),  # type: ignore[arg-type]
                  orientation=tuple(t.orientation))


def _type_fix(topic: str, got: str) -> str:
    if got == "sensor_msgs/msg/CompressedImage":
        return "set colour_compressed (or depth_compressed) for this topic"
    if got == "sensor_msgs/msg/Image":
        return "this topic is raw: turn colour_compressed (or depth_compressed) off"
    return f"point the setting at a topic of the right type (ros2 topic list -t shows types; {topic} is {got})"

