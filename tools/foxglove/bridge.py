"""The pipeline's messages in Foxglove's well-known schemas, live or into an MCAP file.

One :class:`FoxgloveBridge` owns a Foxglove SDK context and these channels:

* ``/camera/image`` CompressedImage (JPEG) of the colour frames;
* ``/camera/annotations`` ImageAnnotations: the detections' boxes, labelled and coloured
  by the track each shows (the page's colours);
* ``/people`` SceneUpdate in the tracks' frame: per person a body-sized cylinder, the ID
  as text, a velocity arrow and the 2-sigma covariance ellipse on the ground;
* ``/tf`` FrameTransforms of ``tf`` and ``tf_static``;
* ``/scans/{laser}`` LaserScan of each 2-D laser's scans (``scans/{laser}``), in the scanner's
  frame; beams without a return (NaN, inf, outside the scanner's range limits) are NaN, which
  Foxglove draws nothing for (its LaserScan has no range limits of its own);
* ``/map`` Grid: the robot's static map (``static_map``), its occupancy in percent (-1 unknown)
  in one ``int8`` field, when it changes and again every :data:`MAP_PERIOD_S` (a live client
  that connects later gets it);
* ``/perception/{tracks,detections,localized,status}`` as JSON.

A live server (:func:`start_live_server`) and an MCAP file (:class:`FoxgloveMcap`, for
``perception export-foxglove`` and ``perception record --foxglove``) are sinks of the same
context. The SDK (``foxglove-sdk``, the ``view`` extra) is imported only here.
"""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any

import numpy as np

from common.messages.schemas import (Detections, LaserScan, LocalizedDetections, Message, RGBDFrame, ServiceStatus,
                                     StaticMap, Tracks, TransformBatch)
from tools.drawing.tracks import colour_rgb, label_boxes, project_to_image

__all__ = ["SCAN_TOPIC", "FoxgloveBridge", "FoxgloveMcap", "FoxgloveUnavailable", "TOPICS", "require_sdk", "scan_fields",
           "scan_topic", "start_live_server"]

#: Topic -> Foxglove schema name, as the MCAP file and the live server advertise them.
TOPICS = {
    "/camera/image": "foxglove.CompressedImage",
    "/camera/annotations": "foxglove.ImageAnnotations",
    "/people": "foxglove.SceneUpdate",
    "/tf": "foxglove.FrameTransforms",
    "/map": "foxglove.Grid",
}
#: Each laser's scans, one channel a laser (``{laser}``: the scan's ``header.source``), ``foxglove.LaserScan``.
SCAN_TOPIC = "/scans/{laser}"
_JSON = {Tracks: "/perception/tracks", Detections: "/perception/detections",
         LocalizedDetections: "/perception/localized", ServiceStatus: "/perception/status"}
_BODY_HEIGHT_M, _BODY_DIAMETER_M = 1.7, 0.45
#: An unchanged map is logged again after this many seconds of its stamps.
MAP_PERIOD_S = 5.0


class FoxgloveUnavailable(RuntimeError):
    """foxglove-sdk is not installed."""


def _sdk() -> Any:
    try:
        import foxglove
    except ImportError as exc:
        raise FoxgloveUnavailable("Foxglove needs the foxglove-sdk package: pip install 'people-perception[view]'") from exc
    return foxglove


def require_sdk() -> None:
    """Raise :class:`FoxgloveUnavailable` unless foxglove-sdk is installed (check before connecting)."""
    _sdk()


def _jsonable(value: Any) -> Any:
    if isinstance(value, dict):
        return {k: _jsonable(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [_jsonable(v) for v in value]
    if isinstance(value, np.ndarray):
        return value.tolist()
    if isinstance(value, (np.floating, np.integer)):
        return value.item()
    if isinstance(value, float) and not math.isfinite(value):
        return None
    if isinstance(value, bytes):
        return f"<{len(value)} bytes>"
    return value


def scan_topic(scan: LaserScan) -> str:
    """The Foxglove topic of a laser's scans: ``/scans/{laser}`` (``/scans/laser`` for a scan naming no source)."""
    return SCAN_TOPIC.format(laser=scan.header.source or "laser")


def scan_fields(scan: LaserScan) -> dict[str, Any]:
    """The fields of Foxglove's ``foxglove.LaserScan`` for one scan, as plain Python values.

    Foxglove places beam ``i`` of ``n`` at ``start_angle + i * (end_angle - start_angle) / (n - 1)``
    and has no range limits, so ``end_angle`` is where the last beam points
    (``angle_min + (n - 1) * angle_increment``, not ``angle_max``, which a scanner may round) and
    every range that is no return (NaN, inf, at or outside ``range_min`` .. ``range_max``, as the
    laser node reads them) is NaN, which it does not draw. ``pose`` is the identity: the points
    are in the scanner's frame (``header.frame_id``), placed by ``/tf``. ``timestamp_ns`` is the
    first beam's time; ``intensities`` is empty when the scanner sends none.
    """
    ranges = np.asarray(scan.ranges, np.float64)
    with np.errstate(invalid="ignore"):
        valid = np.isfinite(ranges) & (ranges > scan.range_min) & (ranges < scan.range_max)
    intensities = scan.intensities if scan.intensities is not None else np.zeros(0, np.float32)
    n = len(ranges)
    return {
        "timestamp_ns": scan.header.stamp_ns,
        "frame_id": scan.header.frame_id or "laser",
        "start_angle": float(scan.angle_min),
        "end_angle": float(scan.angle_min + (n - 1) * scan.angle_increment),
        "ranges": np.where(valid, ranges, np.nan).tolist(),
        "intensities": np.asarray(intensities, np.float64).tolist(),
    }


class FoxgloveBridge:
    """Translates messages to Foxglove's schemas and logs them on its own context's channels."""

    def __init__(self, jpeg_quality: int = 75) -> None:
        fg = _sdk()
        from foxglove import channels as ch

        self.fg, self._channels = fg, ch
        self.context = fg.Context()
        self.jpeg_quality = jpeg_quality
        ctx = self.context
        self.image = ch.CompressedImageChannel("/camera/image", context=ctx)
        self.annotations = ch.ImageAnnotationsChannel("/camera/annotations", context=ctx)
        self.people = ch.SceneUpdateChannel("/people", context=ctx)
        self.tf = ch.FrameTransformsChannel("/tf", context=ctx)
        self.map = ch.GridChannel("/map", context=ctx)
        self.scans: dict[str, Any] = {}  # Foxglove topic -> its LaserScan channel, made at a laser's first scan
        self._map_seen: tuple[Any, ...] | None = None
        self._map_at = 0
        self.json = {model: fg.Channel(topic, message_encoding="json", context=ctx) for model, topic in _JSON.items()}
        self._tracks: Tracks | None = None
        self._view: LocalizedDetections | None = None
        self.counts: dict[str, int] = {}

    def _count(self, topic: str) -> None:
        self.counts[topic] = self.counts.get(topic, 0) + 1

    def on_message(self, stream: str, msg: Message) -> None:
        t = msg.header.stamp_ns
        if isinstance(msg, RGBDFrame):
            from tools.drawing.images import jpeg_of

            self.image.log(self.fg.messages.CompressedImage(
                timestamp=self._stamp(t), frame_id=msg.camera_info.header.frame_id or msg.header.frame_id or "camera",
                data=jpeg_of(msg, self.jpeg_quality), format="jpeg"), log_time=t)
            self._count("/camera/image")
        elif isinstance(msg, Detections):
            self.annotations.log(self._annotations(msg), log_time=t)
            self._count("/camera/annotations")
        elif isinstance(msg, LocalizedDetections):
            if msg.view is not None:  # a camera's, to label its boxes; not a laser's (no image)
                self._view = msg
        elif isinstance(msg, LaserScan):
            topic = scan_topic(msg)
            if topic not in self.scans:
                self.scans[topic] = self._channels.LaserScanChannel(topic, context=self.context)
            self.scans[topic].log(self._laser_scan(msg), log_time=t)
            self._count(topic)
        elif isinstance(msg, Tracks):
            self._tracks = msg
            self.people.log(self._scene(msg), log_time=t)
            self._count("/people")
        elif isinstance(msg, TransformBatch):
            self.tf.log(self._transforms(msg), log_time=t)
            self._count("/tf")
        elif isinstance(msg, StaticMap):
            if msg.content() != self._map_seen or t - self._map_at >= MAP_PERIOD_S * 1e9:  # not each of the ros2 node's
                self._map_seen, self._map_at = msg.content(), t
                self.map.log(self._grid(msg), log_time=t)
                self._count("/map")
        model = type(msg)
        if model in self.json:
            self.json[model].log(_jsonable(msg.model_dump()), log_time=t)
            self._count(_JSON[model])

    # ------------------------------------------------------------------ conversions

    def _grid(self, grid: StaticMap) -> Any:
        m = self.fg.messages
        x, y, yaw = grid.origin
        pose = m.Pose(position=m.Vector3(x=x, y=y, z=0.0),
                      orientation=m.Quaternion(x=0.0, y=0.0, z=math.sin(yaw / 2), w=math.cos(yaw / 2)))
        field = m.PackedElementField(name="occupancy", offset=0, type=m.PackedElementFieldNumericType.Int8)
        return m.Grid(timestamp=self._stamp(grid.header.stamp_ns), frame_id=grid.header.frame_id or "map", pose=pose,
                      column_count=grid.width, cell_size=m.Vector2(x=grid.resolution, y=grid.resolution),
                      row_stride=grid.width, cell_stride=1, fields=[field], data=grid.data)

    def _laser_scan(self, scan: LaserScan) -> Any:
        m, f = self.fg.messages, scan_fields(scan)
        return m.LaserScan(timestamp=self._stamp(f["timestamp_ns"]), frame_id=f["frame_id"],
                           pose=m.Pose(position=m.Vector3(x=0.0, y=0.0, z=0.0),
                                       orientation=m.Quaternion(x=0.0, y=0.0, z=0.0, w=1.0)),
                           start_angle=f["start_angle"], end_angle=f["end_angle"], ranges=f["ranges"],
                           intensities=f["intensities"])

    def _stamp(self, stamp_ns: int) -> Any:
        return self.fg.messages.Timestamp(stamp_ns // 10**9, stamp_ns % 10**9)

    def _colour(self, track_id: int | None, alpha: float = 1.0) -> Any:
        r, g, b = colour_rgb(track_id) if track_id is not None else (200, 200, 200)
        return self.fg.messages.Color(r=r / 255, g=g / 255, b=b / 255, a=alpha)

    def _annotations(self, dets: Detections) -> Any:
        m = self.fg.messages
        boxes = np.array([d.bbox_xyxy for d in dets.detections], np.float64).reshape(-1, 4)
        labels: list[int | None] = [None] * len(boxes)
        tracks, loc = self._tracks, self._view
        if tracks is not None and tracks.tracks and loc is not None and loc.view is not None:
            v = loc.view
            px = project_to_image(np.array([t.position for t in tracks.tracks]), v.camera_to_frame, v.K, v.width, v.height)
            labels = label_boxes(boxes, px, np.array([t.id for t in tracks.tracks]))
        stamp = self._stamp(dets.header.stamp_ns)
        points, texts = [], []
        for (x1, y1, x2, y2), label in zip(boxes.tolist(), labels):
            colour = self._colour(label)
            points.append(m.PointsAnnotation(
                timestamp=stamp, type=m.PointsAnnotationType.LineLoop, thickness=2.0, outline_color=colour,
                points=[m.Point2(x=x1, y=y1), m.Point2(x=x2, y=y1), m.Point2(x=x2, y=y2), m.Point2(x=x1, y=y2)]))
            if label is not None:
                texts.append(m.TextAnnotation(timestamp=stamp, position=m.Point2(x=x1, y=max(0.0, y1 - 4)),
                                              text=f"ID {label}", font_size=14.0, text_color=colour,
                                              background_color=m.Color(r=0, g=0, b=0, a=0.5)))
        return m.ImageAnnotations(points=points, texts=texts)

    def _scene(self, tracks: Tracks) -> Any:
        m = self.fg.messages
        stamp, frame = self._stamp(tracks.header.stamp_ns), tracks.header.frame_id or "map"
        upright = m.Quaternion(x=0, y=0, z=0, w=1)
        entities = []
        for t in tracks.tracks:
            x, y = float(t.position[0]), float(t.position[1])
            colour = self._colour(t.id, 0.8)
            body = m.CylinderPrimitive(pose=m.Pose(position=m.Vector3(x=x, y=y, z=_BODY_HEIGHT_M / 2), orientation=upright),
                                       size=m.Vector3(x=_BODY_DIAMETER_M, y=_BODY_DIAMETER_M, z=_BODY_HEIGHT_M),
                                       bottom_scale=1.0, top_scale=1.0, color=colour)
            text = m.TextPrimitive(pose=m.Pose(position=m.Vector3(x=x, y=y, z=_BODY_HEIGHT_M + 0.25), orientation=upright),
                                   billboard=True, font_size=14.0, scale_invariant=True, color=self._colour(t.id),
                                   text=f"ID {t.id}")
            vx, vy = float(t.velocity[0]), float(t.velocity[1])
            speed, yaw = math.hypot(vx, vy), math.atan2(vy, vx)
            arrows = []
            if speed > 0.05:
                arrows.append(m.ArrowPrimitive(
                    pose=m.Pose(position=m.Vector3(x=x, y=y, z=0.05),
                                orientation=m.Quaternion(x=0, y=0, z=math.sin(yaw / 2), w=math.cos(yaw / 2))),
                    shaft_length=speed, shaft_diameter=0.05, head_length=0.15, head_diameter=0.12,
                    color=self._colour(t.id)))
            ellipse = self._ellipse(np.asarray(t.covariance)[:2, :2], x, y)
            entities.append(m.SceneEntity(
                timestamp=stamp, frame_id=frame, id=f"person-{t.id}", lifetime=m.Duration(1, 0),
                metadata=[m.KeyValuePair(key="status", value=t.status)] if hasattr(m, "KeyValuePair") else None,
                cylinders=[body], texts=[text], arrows=arrows,
                lines=[m.LinePrimitive(type=m.LinePrimitiveLineType.LineLoop, thickness=0.03,
                                       points=[m.Point3(x=px, y=py, z=0.02) for px, py in ellipse],
                                       color=self._colour(t.id))]))
        return m.SceneUpdate(entities=entities)

    @staticmethod
    def _ellipse(cov: np.ndarray, x: float, y: float, sigmas: float = 2.0, n: int = 24) -> list[tuple[float, float]]:
        """Points of the ``sigmas`` ellipse of a (2, 2) covariance around (x, y)."""
        vals, vecs = np.linalg.eigh(0.5 * (cov + cov.T))
        radii = sigmas * np.sqrt(np.clip(vals, 0.0, None))
        a = np.linspace(0, 2 * np.pi, n, endpoint=False)
        pts = (vecs @ (radii[:, None] * np.stack([np.cos(a), np.sin(a)]))).T + [x, y]
        return [(float(p[0]), float(p[1])) for p in pts]

    def _transforms(self, batch: TransformBatch) -> Any:
        m = self.fg.messages
        return m.FrameTransforms(transforms=[m.FrameTransform(
            timestamp=self._stamp(tf.stamp_ns), parent_frame_id=tf.parent_frame, child_frame_id=tf.child_frame,
            translation=m.Vector3(x=float(tf.translation[0]), y=float(tf.translation[1]), z=float(tf.translation[2])),
            rotation=m.Quaternion(x=float(tf.rotation_xyzw[0]), y=float(tf.rotation_xyzw[1]),
                                  z=float(tf.rotation_xyzw[2]), w=float(tf.rotation_xyzw[3])))
            for tf in batch.transforms])

    def close(self) -> None:
        """Nothing to flush here; the sinks (server, MCAP writer) are closed by their owners."""


class FoxgloveMcap:
    """An MCAP file in Foxglove's well-known schemas, written message by message; ``close`` finishes it.

    Raises :class:`FoxgloveUnavailable` without the SDK, and OSError when ``path`` cannot be
    written (a missing folder, a folder in its place). An existing file is overwritten: the
    commands check for one first.
    """

    def __init__(self, path: Path, jpeg_quality: int = 75) -> None:
        self.path = path
        self.bridge = FoxgloveBridge(jpeg_quality)
        self._writer = self.bridge.fg.open_mcap(str(path), allow_overwrite=True, context=self.bridge.context)
        self.closed = False

    @property
    def counts(self) -> dict[str, int]:
        """Messages written per Foxglove topic."""
        return self.bridge.counts

    def write(self, key: str, msg: Message) -> None:
        """Translate ``msg`` (received on ``key``) and write it; types with no Foxglove topic are skipped."""
        self.bridge.on_message(key, msg)

    def close(self) -> None:
        """Write the summary and close the file (idempotent)."""
        if not self.closed:
            self.closed = True
            self._writer.close()

    def __enter__(self) -> FoxgloveMcap:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


class _LiveBridge(FoxgloveBridge):
    """A bridge with a Foxglove WebSocket server on its context; ``close`` stops the server."""

    def __init__(self, host: str, port: int, jpeg_quality: int) -> None:
        super().__init__(jpeg_quality)
        try:
            self.server = self.fg.start_server(name="people-perception", host=host, port=port, context=self.context)
        except Exception as exc:  # the SDK raises its own error types for a busy port
            raise ValueError(f"cannot serve Foxglove on {host}:{port}: {exc}") from exc

    @property
    def port(self) -> int:
        return int(self.server.port)

    def close(self) -> None:
        self.server.stop()


def start_live_server(host: str, port: int, jpeg_quality: int = 75) -> _LiveBridge:
    """A bridge serving Foxglove's WebSocket protocol on ``host:port`` (0: a free port)."""
    return _LiveBridge(host, port, jpeg_quality)
