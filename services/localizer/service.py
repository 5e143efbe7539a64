"""LocalizerService: Detections + depth frames + transforms -> LocalizedDetections in the map frame.

Inputs (``keys`` of one robot, one camera):

* ``frames/{camera}`` RGBDFrame. Subscribed with a small FIFO instead of the usual
  latest-only ring: the Detections of a frame arrive after the detector has worked on
  it, by which time newer frames have come in, so a latest-only subscription would
  almost never still hold the matching frame. Only the depth image and camera info are
  kept, the last ``frame_buffer`` of them.
* ``detections/{camera}`` Detections, joined with their frame on ``Header.join_key`` by
  a :class:`common.runtime.join.Joiner`.
* ``tf`` and ``tf_static`` TransformBatch, into a :class:`TransformBuffer`.

Detections wait (in stamp order) up to ``frame_wait_s`` for a frame not yet seen (a
frame of the same source that is already past their stamp will not come: dropped at
once), then up to ``transform_wait_s`` for the transform at their stamp, both counted
from their arrival; then they are dropped and counted (``dropped_no_depth_frame``,
``dropped_no_transform``), and the missing edge is logged at most once per second.
Positions are only ever published in ``target_frame``.
"""

from __future__ import annotations

import dataclasses
import logging
from collections import deque
from dataclasses import dataclass

import numpy as np

from common.geometry.transforms import (
    ExtrapolationError,
    MissingTransformError,
    PinholeCamera,
    RigidTransform,
    TransformBuffer,
)
from common.geometry.messages import camera_from_info, take_transforms
from common.runtime.join import Dropped, Joined, Joiner
from common.messages.keys import FRAMES, RELIABLE, Keys
from common.runtime.node import Node
from common.runtime.ratelog import RateLimitedLog
from common.runtime.service import Counters
from common.messages.schemas import (
    CameraView,
    Detections,
    Header,
    Image,
    LocalizedDetection,
    LocalizedDetections,
    RGBDFrame,
    TransformBatch,
)
from common.transport.base import Transport
from services.localizer.config import LocalizerConfig
from services.localizer.core import localize

__all__ = ["LocalizerService"]

log = logging.getLogger(__name__)


@dataclass
class _DepthFrame:
    depth: Image | None
    camera: PinholeCamera
    camera_frame: str


#: What the localizer calls each of the joiner's drop reasons (``dropped_<name>``).
_DROP_NAMES = {"overflow": "pending_overflow", "duplicate": "duplicate", "late": "duplicate"}


class LocalizerService(Node):
    """The localizer on a transport it is handed (Zenoh or in-memory)."""

    name = "localizer"

    def __init__(
        self, transport: Transport, keys: Keys, config: LocalizerConfig, counters: Counters | None = None
    ) -> None:
        super().__init__(transport, keys, counters)
        self.config = config
        self.params = config.params()
        self.buffer = TransformBuffer(history_s=config.tf_history_s, tolerance_s=config.tf_tolerance_s)
        for st in config.static_transforms:
            self.buffer.set_transform(
                st.parent_frame,
                st.child_frame,
                0,
                RigidTransform.from_quat(np.array(st.translation), np.array(st.rotation_xyzw)),
                static=True,
            )
        self.join: Joiner[Detections] = Joiner(
            ("detections", "frame"), wait_s=config.frame_wait_s, buffer=config.frame_buffer,
            max_waiting=config.max_pending, on_timeout="drop", in_order=("frame",), ordered=True, clock_jump_s=5.0)
        self.waiting_tf: deque[Joined[Detections]] = deque()  # joined, waiting for their transform
        self._log = RateLimitedLog(log)
        # the tf subscriptions first, so a frame's transform is taken before its detections
        self.sub_tf_static = self.io.subscribe(keys.tf_static(), TransformBatch, RELIABLE)
        self.sub_tf = self.io.subscribe(keys.tf(), TransformBatch, RELIABLE)
        frame_fifo = dataclasses.replace(FRAMES, latest=False, queue=max(4, config.frame_buffer))
        self.sub_frames = self.io.subscribe(keys.frames(config.camera), RGBDFrame, frame_fifo)
        self.sub_detections = self.io.subscribe(keys.detections(config.output), Detections, RELIABLE)
        self.pub = self.io.publisher(keys.localized(config.output), LocalizedDetections, RELIABLE)

    @property
    def pending(self) -> int:
        """Detections messages not yet localized or dropped."""
        return self.join.waiting + len(self.waiting_tf)

    def describe(self) -> str:
        return f"localizing {self.sub_detections.key} into {self.config.target_frame!r}"

    # ------------------------------------------------------------------ inputs

    def _take_transforms(self) -> None:
        take_transforms(self.buffer, ((self.sub_tf_static, True), (self.sub_tf, False)), self.counters, self._log)

    def _take_frames(self, now: float) -> None:
        while (got := self.sub_frames.try_recv()) is not None:
            f = got.msg
            camera_frame = f.camera_info.header.frame_id or f.header.frame_id or self.config.camera_frame
            frame = _DepthFrame(f.depth, camera_from_info(f.camera_info), camera_frame)
            self._dropped(self.join.add("frame", f.header.join_key, frame, now))

    def _take_detections(self, now: float) -> None:
        while (got := self.sub_detections.try_recv()) is not None:
            self._dropped(self.join.add("detections", got.msg.header.join_key, got.msg, now))

    # ---------------------------------------------------------------- pairing

    def _dropped(self, dropped: list[Dropped]) -> None:
        for d in dropped:
            if d.reason in ("timeout", "lost"):
                self._drop("no_depth_frame", "no depth frame %s (lost, or evicted from the last %d)",
                           d.key, self.config.frame_buffer)
            elif "detections" in d.slots:
                self._drop(_DROP_NAMES.get(d.reason, d.reason), "%s detections %s", d.reason, d.key)
            else:
                self.counters.count(f"frames_{d.reason}")

    def _drop(self, reason: str, fmt: str, *args: object) -> None:
        self.counters.drop(reason)
        self._log.warning(reason, "dropping detections (%s): " + fmt, reason, *args)

    def _try(self, item: Joined[Detections], now: float) -> tuple[bool, LocalizedDetections | None]:
        """(done, message to publish). Not done means: wait for the transform."""
        h = item.anchor.header
        frame: _DepthFrame = item.items["frame"]
        key = h.join_key
        if frame.depth is None:
            self._drop("frame_without_depth", "frame %s has no depth image", key)
            return True, None
        if not frame.camera_frame:
            self._drop("no_camera_frame", "frame %s names no camera frame id (set camera_frame)", key)
            return True, None
        try:
            tf = self.buffer.lookup(self.config.target_frame, frame.camera_frame, h.stamp_ns)
        except (MissingTransformError, ExtrapolationError) as exc:
            never = isinstance(exc, ExtrapolationError) and not exc.future
            if not never and now - item.arrived < self.config.transform_wait_s:
                return False, None
            self._drop("no_transform", "missing transform %s: %s", exc.edge, exc)
            return True, None
        return True, self._localize(item.anchor, frame, tf)

    def _localize(self, msg: Detections, frame: _DepthFrame, tf: RigidTransform) -> LocalizedDetections | None:
        assert frame.depth is not None
        try:
            depth = frame.depth.to_array()
        except ValueError as exc:
            self._drop("bad_depth", "depth image of seq %d cannot be decoded: %s", msg.header.seq, exc)
            return None
        w, h = msg.image_width, msg.image_height
        if (w and w != depth.shape[1]) or (h and h != depth.shape[0]):
            self._drop(
                "size_mismatch",
                "detections are for a %dx%d image, depth is %dx%d",
                w,
                h,
                depth.shape[1],
                depth.shape[0],
            )
            return None
        dets = msg.detections
        boxes = np.array([d.bbox_xyxy for d in dets], dtype=np.float64).reshape(-1, 4)
        loc = localize(depth, frame.camera, boxes, self.params, indices=np.arange(len(dets)), frame=frame.camera_frame)
        out = loc.transformed(tf, self.config.target_frame)
        entries = []
        for k, i in enumerate(out.indices):
            d = dets[int(i)]
            entries.append(
                LocalizedDetection(
                    index=d.index,
                    bbox_xyxy=d.bbox_xyxy,
                    score=d.score,
                    position=out.positions[k],
                    cov=out.covs[k],
                    depth_m=float(out.depth_m[k]),
                    valid_pixels=int(out.valid_pixels[k]),
                )
            )
        rejected = loc.rejected_counts()
        for reason, n in rejected.items():
            self.counters.count(f"rejected_{reason}", n)
        self.counters.count("boxes_localized", len(entries))
        header = Header(
            stamp_ns=msg.header.stamp_ns,
            frame_id=self.config.target_frame,
            seq=msg.header.seq,
            # a second detector's stream is a source of its own: its frames must not share the
            # camera's join keys downstream (the tracker fuses both)
            source=self.config.stream or msg.header.source,
        )
        cam = frame.camera
        view = CameraView(camera_to_frame=tf.matrix, K=cam.K, width=cam.width, height=cam.height,
                          max_range_m=self.params.max_depth_m)
        return LocalizedDetections(
            header=header, camera_frame=frame.camera_frame, detections=entries, rejected=rejected, view=view,
            detector=msg.detector,
        )

    # ------------------------------------------------------------------- loop

    def poll(self, now: float) -> list[LocalizedDetections]:
        """Take every waiting input, then localize the detections that can be; returns what was published."""
        self._take_transforms()
        self._take_frames(now)
        self._take_detections(now)
        joined, dropped = self.join.poll(now)
        self._dropped(dropped)
        if self.join.clock_jumps != self.counters.extra.get("clock_jumps", 0):
            self.counters.gauge("clock_jumps", self.join.clock_jumps)
            self._log.warning("clock_jump", "stamps went back more than 5 s: a new clock (a replay that loops?); "
                              "the pairing of detections and frames starts over")
        self.waiting_tf.extend(joined)
        published = []
        while self.waiting_tf:
            done, out = self._try(self.waiting_tf[0], now)
            if not done:
                break
            self.waiting_tf.popleft()
            if out is not None:
                self.pub.put(out)
                published.append(out)
        self.counters.gauge("pending", self.pending)
        return published

    def deadline(self, now: float) -> float | None:
        # while something waits, poll often enough to honour its deadline
        return 0.02 if self.pending else None
