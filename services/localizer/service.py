"""LocalizerService: Detections + depth frames + transforms -> LocalizedDetections in the map frame.

Inputs (``keys`` of one robot, one camera):

* ``frames/{camera}`` RGBDFrame. Subscribed with a small FIFO instead of the usual
  latest-only ring, and kept in a :class:`FrameRing` of the last ``frame_buffer`` depth
  frames: the Detections of a frame arrive after the detector has worked on it, by
  which time newer frames have come in, so a latest-only subscription would almost
  never still hold the matching frame. Only the depth image and camera info are kept.
* ``detections/{camera}`` Detections, paired with their frame on (source, stamp, seq).
* ``tf`` and ``tf_static`` TransformBatch, into a :class:`TransformBuffer`.

Detections wait (in arrival order) up to ``frame_wait_s`` for a frame not yet seen and
up to ``transform_wait_s`` for the transform at their stamp, both counted from their
arrival; then they are dropped and
counted (``dropped_no_depth_frame``, ``dropped_no_transform``), and the missing edge is
logged at most once per second. Positions are only ever published in ``target_frame``.
"""

from __future__ import annotations

import dataclasses
import logging
import time
from collections import deque
from dataclasses import dataclass
from typing import Any

import numpy as np

from common.geometry import (
    ExtrapolationError,
    FrameTreeError,
    MissingTransformError,
    PinholeCamera,
    RigidTransform,
    TransformBuffer,
)
from common.geometry_messages import add_transform, camera_from_info
from common.keys import FRAMES, RELIABLE, Keys
from common.runtime import Counters, Shutdown
from common.schemas import (
    Detections,
    Header,
    Image,
    LocalizedDetection,
    LocalizedDetections,
    RGBDFrame,
    TransformBatch,
)
from common.transport import Subscription, Transport, wait_any
from services.localizer.config import LocalizerConfig
from services.localizer.core import localize
from services.localizer.pairing import FrameKey, FrameRing

__all__ = ["LocalizerService"]

log = logging.getLogger(__name__)


@dataclass
class _DepthFrame:
    depth: Image | None
    camera: PinholeCamera
    camera_frame: str


@dataclass
class _Pending:
    msg: Detections
    arrived: float


class _RateLimited:
    """Logs one warning per reason per ``period_s``, saying how many were not logged."""

    def __init__(self, period_s: float = 1.0) -> None:
        self.period_s = period_s
        self._last: dict[str, float] = {}
        self._skipped: dict[str, int] = {}

    def warning(self, reason: str, fmt: str, *args: object) -> None:
        now = time.monotonic()
        if now - self._last.get(reason, -1e18) < self.period_s:
            self._skipped[reason] = self._skipped.get(reason, 0) + 1
            return
        skipped = self._skipped.pop(reason, 0)
        self._last[reason] = now
        log.warning(fmt + (f" ({skipped} more since the last report)" if skipped else ""), *args)


class LocalizerService:
    """The localizer on a transport it is handed (Zenoh or in-memory)."""

    def __init__(
        self, transport: Transport, keys: Keys, config: LocalizerConfig, counters: Counters | None = None
    ) -> None:
        self.transport = transport
        self.keys = keys
        self.config = config
        self.counters = counters if counters is not None else Counters()
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
        self.frames_ring: FrameRing[_DepthFrame] = FrameRing(config.frame_buffer)
        self.pending: deque[_Pending] = deque()
        self._log = _RateLimited()
        frame_fifo = dataclasses.replace(FRAMES, latest=False, queue=max(4, config.frame_buffer))
        self.sub_frames = transport.subscribe(keys.frames(config.camera), RGBDFrame, frame_fifo)
        self.sub_detections = transport.subscribe(keys.detections(config.camera), Detections, RELIABLE)
        self.sub_tf = transport.subscribe(keys.tf(), TransformBatch, RELIABLE)
        self.sub_tf_static = transport.subscribe(keys.tf_static(), TransformBatch, RELIABLE)
        self.pub = transport.publisher(keys.localized(config.camera), LocalizedDetections, RELIABLE)
        self.subscriptions: list[Subscription[Any]] = [
            self.sub_tf_static,
            self.sub_tf,
            self.sub_frames,
            self.sub_detections,
        ]

    # ------------------------------------------------------------------ inputs

    def _take_transforms(self) -> None:
        for sub, static in ((self.sub_tf_static, True), (self.sub_tf, False)):
            while (got := sub.try_recv()) is not None:
                for msg in got.msg.transforms:  # one bad edge must not cost the others of its batch
                    try:
                        add_transform(self.buffer, msg, static=static)
                    except FrameTreeError as exc:
                        self.counters.count("transforms_rejected")
                        self._log.warning("tf_tree", "rejected transform from %s: %s", got.key, exc)

    def _take_frames(self) -> None:
        while (got := self.sub_frames.try_recv()) is not None:
            f = got.msg
            camera_frame = f.camera_info.header.frame_id or f.header.frame_id or self.config.camera_frame
            key: FrameKey = (f.header.source, f.header.stamp_ns, f.header.seq)
            self.frames_ring.add(key, _DepthFrame(f.depth, camera_from_info(f.camera_info), camera_frame))

    def _take_detections(self, now: float) -> None:
        while (got := self.sub_detections.try_recv()) is not None:
            if len(self.pending) >= self.config.max_pending:
                old = self.pending.popleft()
                self._drop("pending_overflow", "too many detections waiting; dropped seq %d", old.msg.header.seq)
            self.pending.append(_Pending(got.msg, now))

    # ---------------------------------------------------------------- pairing

    def _drop(self, reason: str, fmt: str, *args: object) -> None:
        self.counters.drop(reason)
        self._log.warning(reason, "dropping detections (%s): " + fmt, reason, *args)

    def _try(self, item: _Pending, now: float) -> tuple[bool, LocalizedDetections | None]:
        """(done, message to publish). Not done means: wait for more input."""
        h = item.msg.header
        key: FrameKey = (h.source, h.stamp_ns, h.seq)
        frame = self.frames_ring.get(key)
        if frame is None:
            if self.frames_ring.passed(key) or now - item.arrived >= self.config.frame_wait_s:
                self._drop(
                    "no_depth_frame",
                    "no depth frame %s (lost, or evicted from the last %d)",
                    key,
                    self.config.frame_buffer,
                )
                return True, None
            return False, None
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
        return True, self._localize(item.msg, frame, tf)

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
            source=msg.header.source,
        )
        return LocalizedDetections(
            header=header, camera_frame=frame.camera_frame, detections=entries, rejected=rejected
        )

    # ------------------------------------------------------------------- loop

    def step(self, now: float | None = None) -> list[LocalizedDetections]:
        """Take every waiting input, then localize the detections that can be; returns what was published."""
        now = time.monotonic() if now is None else now
        self._take_transforms()
        self._take_frames()
        self._take_detections(now)
        published = []
        while self.pending:
            done, out = self._try(self.pending[0], now)
            if not done:
                break
            self.pending.popleft()
            if out is not None:
                self.pub.put(out)
                published.append(out)
        self.counters.gauge("pending", len(self.pending))
        return published

    def run(self, shutdown: Shutdown) -> None:
        """Serve until ``shutdown`` is set."""
        log.info("localizing %s into %r", self.keys.detections(self.config.camera), self.config.target_frame)
        while not shutdown.is_set():
            # while something waits, poll often enough to honour its deadline
            wait_any(self.subscriptions, self.transport.notify, 0.02 if self.pending else 0.2)
            self.step()
