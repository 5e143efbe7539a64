"""ROS 1 and ROS 2 bags as a replay source, read with rosbags (no ROS install needed).

Topics are routed by a :class:`~tools.replay.core.mapping.TopicPlan`. Colour and
depth images of a camera are paired by stamp into :class:`RGBDFrame` with the latest
camera info of that camera (frames wait, up to :attr:`BagOptions.max_waiting_frames`,
for the first camera info). TF, static TF and odometry become TransformBatch messages
on the tf / tf_static keys; each laser's scans LaserScan messages on scans/{laser}.
"""

from __future__ import annotations

import logging
from collections import deque
from dataclasses import dataclass, field
from pathlib import Path
from typing import Iterator

from common.messages.keys import Keys
from common.messages.schemas import CameraInfo, Image, LaserScan, Message, RGBDFrame, TransformBatch
from common.runtime.pairing import Pair, StampPairer
from tools.replay import rosconv
from tools.replay.core.mapping import TopicPlan, plan_topics
from tools.replay.source_base import Item, Source, SourceError, StreamSummary, Summary

__all__ = ["BagOptions", "BagSource"]

log = logging.getLogger(__name__)

_TYPES = {
    "rgb": ("sensor_msgs/msg/Image", "sensor_msgs/msg/CompressedImage"),
    "depth": ("sensor_msgs/msg/Image",),
    "camera_info": ("sensor_msgs/msg/CameraInfo",),
    "tf": ("tf2_msgs/msg/TFMessage", "tf/msg/tfMessage"),
    "tf_static": ("tf2_msgs/msg/TFMessage",),
    "odom": ("nav_msgs/msg/Odometry",),
    "scan": ("sensor_msgs/msg/LaserScan",),
}


@dataclass
class BagOptions:
    """How a bag's topics become perception streams (see the README's topic map)."""

    keys: Keys = field(default_factory=Keys)
    cameras: dict[str, dict[str, str]] = field(default_factory=dict)
    lists: dict[str, list[str]] = field(default_factory=dict)
    #: laser -> scan topic; None: every LaserScan topic (``/scan`` as ``front``, see ``plan_topics``)
    lasers: dict[str, str] | None = None
    default_camera: str = "head"
    pair_tolerance_ns: int = 20_000_000
    max_waiting_frames: int = 30


@dataclass
class _Camera:
    name: str
    pairer: StampPairer[tuple[Image, int], tuple[Image, int]]
    info: CameraInfo | None = None
    waiting: deque[tuple[int, Image, Image | None, int]] = field(default_factory=deque)
    seq: int = 0


class BagSource(Source):
    """A ROS 1 ``.bag`` file or a ROS 2 bag folder (sqlite3 or mcap storage)."""

    def __init__(self, path: Path, options: BagOptions) -> None:
        super().__init__(path)
        from rosbags.highlevel import AnyReader, AnyReaderError
        from rosbags.typesys import Stores, get_typestore

        self.options = options
        try:
            self._reader = AnyReader([path], default_typestore=get_typestore(Stores.LATEST))
            self._reader.open()
        except (AnyReaderError, OSError, ValueError, KeyError) as exc:
            raise SourceError(path, f"not a readable ROS bag ({type(exc).__name__}: {exc})") from exc
        if self._reader.message_count == 0:
            self._reader.close()
            raise SourceError(path, "the bag holds no messages")
        topics = self._reader.topics
        scans = [t for t, info in topics.items() if (info.msgtype or "") in _TYPES["scan"]]
        self.plan: TopicPlan = plan_topics(list(topics), options.cameras or None, options.lists or None,
                                           options.default_camera, options.lasers, scans)
        for topic, route in list(self.plan.routes.items()):
            msgtype = topics[topic].msgtype or ""
            if msgtype not in _TYPES[route.role]:
                del self.plan.routes[topic]
                self.plan.skipped[topic] = f"type {msgtype} cannot be the {route.role} stream"
        self.skipped.update({t: f"{why} [{topics[t].msgtype if t in topics else '-'}]" for t, why in self.plan.skipped.items()})
        for topic, why in self.skipped.items():
            log.debug("%s: skipping %s: %s", path, topic, why)

    def streams(self) -> dict[str, type[Message]]:
        keys = self.options.keys
        out: dict[str, type[Message]] = {}
        for route in self.plan.routes.values():
            if route.role == "rgb":
                out[keys.frames(route.camera)] = RGBDFrame
            elif route.role in ("tf", "odom"):
                out[keys.tf()] = TransformBatch
            elif route.role == "tf_static":
                out[keys.tf_static()] = TransformBatch
            elif route.role == "scan":
                out[keys.scans(route.laser)] = LaserScan
        return out

    def items(self) -> Iterator[Item]:
        keys = self.options.keys
        cams: dict[str, _Camera] = {}
        for name, roles in self.plan.cameras().items():
            if "rgb" not in roles:
                continue
            # a recording: a colour image waits until the colour stream is a second ahead of it
            pairer: StampPairer[tuple[Image, int], tuple[Image, int]] = StampPairer(
                self.options.pair_tolerance_ns, hold_ns=1_000_000_000, expect_depth="depth" in roles)
            cams[name] = _Camera(name, pairer)
        scan_seq: dict[str, int] = {}
        conns = [c for c in self._reader.connections if c.topic in self.plan.routes]
        try:
            for conn, log_ns, raw in self._reader.messages(connections=conns):
                route = self.plan.routes[conn.topic]
                try:
                    msg = self._reader.deserialize(raw, conn.msgtype)
                except Exception as exc:  # rosbags raises assorted errors on damaged data
                    self.problem(conn.topic, f"cannot be deserialised ({type(exc).__name__})")
                    continue
                cam = cams.get(route.camera)
                try:
                    if route.role == "tf" or route.role == "tf_static":
                        batch, bad = rosconv.tf_message(msg, static=route.role == "tf_static")
                        if bad:
                            self.problem(conn.topic, "invalid transforms left out")
                        key = keys.tf_static() if route.role == "tf_static" else keys.tf()
                        yield Item(batch.header.stamp_ns, log_ns, key, TransformBatch, message=batch)
                    elif route.role == "odom":
                        batch = rosconv.odometry(msg)
                        yield Item(batch.header.stamp_ns, log_ns, keys.tf(), TransformBatch, message=batch)
                    elif route.role == "scan":
                        scan = rosconv.laser_scan(msg, route.laser, scan_seq.get(route.laser, 0))
                        scan_seq[route.laser] = scan.header.seq + 1
                        yield Item(scan.header.stamp_ns, log_ns, keys.scans(route.laser), LaserScan, message=scan)
                    elif cam is None:
                        continue  # depth or camera info of a camera without colour topic
                    elif route.role == "camera_info":
                        cam.info = rosconv.camera_info(msg, cam.name)
                        yield from self._frames(cam, [])
                    elif route.role == "rgb":
                        conv = rosconv.compressed_image if conn.msgtype.endswith("CompressedImage") else rosconv.image
                        img = conv(msg, cam.name)
                        cam.pairer.add_colour(img.header.stamp_ns, (img, log_ns))
                        yield from self._frames(cam, cam.pairer.ready())
                    else:
                        img = rosconv.image(msg, cam.name)
                        if not img.is_depth:
                            raise rosconv.ConversionError(f"depth topic carries {img.encoding} images")
                        cam.pairer.add_depth(img.header.stamp_ns, (img, log_ns))
                        yield from self._frames(cam, cam.pairer.ready())
                except rosconv.ConversionError as exc:
                    self.problem(conn.topic, str(exc))
        except SourceError:
            raise
        except Exception as exc:  # rosbags' readers raise their own and OS errors on damaged files
            raise SourceError(self.path, f"damaged or truncated ({type(exc).__name__}: {exc})") from exc
        for c in cams.values():
            yield from self._frames(c, c.pairer.ready(final=True))
            if c.waiting:
                self.problem(c.name, f"{len(c.waiting)} frames dropped: no camera info received")
            if c.pairer.expect_depth and c.pairer.unpaired:
                self.problem(c.name, f"colour images without a depth image within "
                             f"{self.options.pair_tolerance_ns / 1e6:g} ms (published without depth)")

    def _frames(self, cam: _Camera, pairs: list[Pair[tuple[Image, int], tuple[Image, int]]]) -> Iterator[Item]:
        for pair in pairs:
            (rgb_img, rgb_log_ns), paired = pair.colour, pair.depth
            cam.waiting.append((pair.stamp_ns, rgb_img, paired[0] if paired else None, rgb_log_ns))
        if cam.info is None:
            while len(cam.waiting) > self.options.max_waiting_frames:
                cam.waiting.popleft()
                self.problem(cam.name, "frame dropped: no camera info yet")
            return
        while cam.waiting:
            stamp, rgb, depth, log_ns = cam.waiting.popleft()
            if depth is not None and depth.shape[:2] != rgb.shape[:2]:
                self.problem(cam.name, f"depth {depth.shape[:2]} is not registered to colour {rgb.shape[:2]}; depth left out")
                depth = None
            if (cam.info.height, cam.info.width) != rgb.shape[:2]:
                self.problem(cam.name, "camera info size differs from the colour image; frame dropped")
                continue
            header = rgb.header.model_copy(update={"seq": cam.seq, "source": cam.name})
            try:
                frame = RGBDFrame(header=header, rgb=rgb, depth=depth, camera_info=cam.info)
            except ValueError as exc:
                self.problem(cam.name, f"frame rejected: {exc}")
                continue
            cam.seq += 1
            yield Item(stamp, log_ns, self.options.keys.frames(cam.name), RGBDFrame, message=frame)

    def summary(self) -> Summary:
        r = self._reader
        streams = []
        for topic, info in sorted(r.topics.items()):
            route = self.plan.routes.get(topic)
            if route is None:
                note = f"skipped: {self.plan.skipped.get(topic, '')}"
            elif route.role == "scan":
                note = f"-> scans/{route.laser}"
            else:
                note = f"-> {route.role}" + (f" of camera {route.camera}" if route.camera else "")
            streams.append(StreamSummary(topic, info.msgtype or "?", info.msgcount, note))
        kind = "ROS 2 bag" if self.path.is_dir() or self.path.suffix == ".mcap" else "ROS 1 bag"
        return Summary(kind, streams, r.start_time, r.end_time)

    def close(self) -> None:
        self._reader.close()
