"""LocalizerService: Detections + frames + transforms -> LocalizedDetections in the map frame.

A frame with a depth image places each box at its depth (:func:`~services.localizer.core.localize`);
a frame without one (an RGB-only camera) puts each person on the floor from the box's foot
point, through the camera's pose in the target frame or, for a fixed camera, through the
``floor_homography`` (:mod:`services.localizer.core.floor`, :mod:`~services.localizer.core.homography`).

Inputs (``keys`` of one robot, one camera):

* ``frames/{camera}`` RGBDFrame. Subscribed with a small FIFO instead of the usual
  latest-only ring: the Detections of a frame arrive after the detector has worked on
  it, by which time newer frames have come in, so a latest-only subscription would
  almost never still hold the matching frame. Only the depth image and camera info are
  kept (the depth image may be absent), the last ``frame_buffer`` of them.
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
    FloorCameraView,
    Header,
    Image,
    LocalizedDetection,
    LocalizedDetections,
    RGBDFrame,
    TransformBatch,
)
from common.transport.base import Transport
from services.localizer.config import LocalizerConfig
from services.localizer.core import (
    MISMATCH_TOLERANCE,
    FloorHomography,
    Localization,
    camera_pose_from_homography,
    homography_in_frame,
    localize,
    localize_on_floor,
    localize_on_floor_homography,
)
from services.localizer.files import read_floor_homography

__all__ = ["LocalizerService"]

log = logging.getLogger(__name__)


@dataclass
class _Frame:
    depth: Image | None
    camera: PinholeCamera
    camera_frame: str


#: What the localizer calls each of the joiner's drop reasons (``dropped_<name>``).
_DROP_NAMES = {"overflow": "pending_overflow", "duplicate": "duplicate", "late": "duplicate"}


class LocalizerService(Node):
    """The localizer on a transport it is handed (Zenoh or in-memory)."""

    name = "localizer"

    def __init__(
        self, transport: Transport, keys: Keys, config: LocalizerConfig, counters: Counters | None = None,
        floor_homography: FloorHomography | None = None,
    ) -> None:
        super().__init__(transport, keys, counters)
        self.config = config
        self.params = config.params()
        self.floor = config.floor_params()  # boxes of a detector without a foot bias
        self._floor_of = {name: config.floor_params(name) for name in config.foot_bias}
        if floor_homography is None and config.floor_homography is not None:
            floor_homography = read_floor_homography(config.floor_homography)
        self.homography = floor_homography
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
            frame = _Frame(f.depth, camera_from_info(f.camera_info), camera_frame)
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
        frame: _Frame = item.items["frame"]
        key = h.join_key
        on_floor = frame.depth is None
        if on_floor and not self.config.floor_without_depth:
            self._drop("frame_without_depth", "frame %s has no depth image (floor_without_depth is off)", key)
            return True, None
        # a homography's floor is in its own frame, any other position comes from the camera's
        source = self.config.floor_frame if on_floor and self.homography is not None else frame.camera_frame
        if not source:
            self._drop("no_camera_frame", "frame %s names no camera frame id (set camera_frame)", key)
            return True, None
        try:
            tf = self.buffer.lookup(self.config.target_frame, source, h.stamp_ns)
        except (MissingTransformError, ExtrapolationError) as exc:
            never = isinstance(exc, ExtrapolationError) and not exc.future
            if not never and now - item.arrived < self.config.transform_wait_s:
                return False, None
            self._drop("no_transform", "missing transform %s: %s", exc.edge, exc)
            return True, None
        return True, self._localize(item.anchor, frame, tf)

    def _size_mismatch(self, msg: Detections, width: int, height: int, what: str) -> bool:
        """Whether the detections are for another image size than ``width`` x ``height`` (dropped and counted)."""
        w, h = msg.image_width, msg.image_height
        if (w and w != width) or (h and h != height):
            self._drop("size_mismatch", "detections are for a %dx%d image, %s is %dx%d", w, h, what, width, height)
            return True
        return False

    def _on_depth(self, msg: Detections, frame: _Frame, boxes: np.ndarray, tf: RigidTransform
                  ) -> tuple[Localization, CameraView | None, None] | None:
        """The boxes at their depth, in the target frame, and the camera's view; None when dropped."""
        assert frame.depth is not None
        try:
            depth = frame.depth.to_array()
        except ValueError as exc:
            self._drop("bad_depth", "depth image of seq %d cannot be decoded: %s", msg.header.seq, exc)
            return None
        if self._size_mismatch(msg, depth.shape[1], depth.shape[0], "depth"):
            return None
        own = np.array([np.nan if d.depth_m is None else d.depth_m for d in msg.detections], dtype=np.float64)
        loc = localize(depth, frame.camera, boxes, self.params, frame=frame.camera_frame,
                       depths=own if np.isfinite(own).any() else None)
        if loc.measured.any():  # the detector's own depth of the person, not the box's (an occluder may fill it)
            self.counters.count("depth_from_detector", int(loc.measured.sum()))
        return loc.transformed(tf, self.config.target_frame), self._view(frame.camera, tf, self.params.max_depth_m), None

    def _on_floor(self, msg: Detections, frame: _Frame, boxes: np.ndarray, tf: RigidTransform
                  ) -> tuple[Localization, CameraView | None, FloorCameraView | None] | None:
        """The boxes on the floor (no depth image), in the target frame, and the camera's view; None when
        dropped. ``tf`` maps the camera frame (without a homography) or the homography's frame into the target."""
        cam, target, p = frame.camera, self.config.target_frame, self._floor_of.get(msg.detector, self.floor)
        floor: FloorCameraView | None = None
        if self._size_mismatch(msg, cam.width, cam.height, "the camera"):
            return None
        if self.homography is None:
            loc, cam_to_target = localize_on_floor(cam, tf, boxes, p, frame=target), tf
        else:
            try:
                hom = self.homography.for_image(cam.width, cam.height)
            except ValueError as exc:
                self._drop("homography_size_mismatch", "frame seq %d: %s", msg.header.seq, exc)
                return None
            pose = camera_pose_from_homography(hom, cam.K, p.floor_z_m)
            loc = localize_on_floor_homography(hom, boxes, p, cam.width, cam.height, pose, frame=self.config.floor_frame)
            loc, cam_to_target = loc.transformed(tf, target), tf @ pose.camera_to_floor
            h = homography_in_frame(hom, tf)
            if h is not None:
                floor = FloorCameraView(image_to_frame=h, width=cam.width, height=cam.height)
            if not pose.mismatch <= MISMATCH_TOLERANCE:
                # the positions come from the homography alone; the camera's pose (range, depth, view) is unsure
                self.counters.count("homography_intrinsics_mismatch")
                self._log.warning("homography_intrinsics_mismatch", "the camera's K does not fit the floor homography "
                                  "(mismatch %.2f > %.2f): ranges and depths are rough and only the floor view is "
                                  "sent (give the camera's calibration, --camera-info, for the full view)",
                                  pose.mismatch, MISMATCH_TOLERANCE)
                return loc, None, floor
        height = float(cam_to_target.translation[2]) - p.floor_z_m - p.centre_height_m
        return loc, self._view(cam, cam_to_target, float(np.hypot(p.max_floor_range_m, height))), floor

    @staticmethod
    def _view(cam: PinholeCamera, cam_to_target: RigidTransform, max_range_m: float) -> CameraView:
        return CameraView(camera_to_frame=cam_to_target.matrix, K=cam.K, width=cam.width, height=cam.height,
                          max_range_m=max_range_m)

    def _localize(self, msg: Detections, frame: _Frame, tf: RigidTransform) -> LocalizedDetections | None:
        dets = msg.detections
        boxes = np.array([d.bbox_xyxy for d in dets], dtype=np.float64).reshape(-1, 4)
        got = self._on_depth(msg, frame, boxes, tf) if frame.depth is not None else self._on_floor(msg, frame, boxes, tf)
        if got is None:
            return None
        out, view, floor = got
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
                    posture=d.posture,
                    stature_m=d.stature_m,
                )
            )
        rejected = out.rejected_counts()
        for reason, n in rejected.items():
            self.counters.count(f"rejected_{reason}", n)
        self.counters.count("boxes_localized", len(entries))
        if frame.depth is None:
            self.counters.count("boxes_on_floor", len(entries))
        header = Header(
            stamp_ns=msg.header.stamp_ns,
            frame_id=self.config.target_frame,
            seq=msg.header.seq,
            # a second detector's stream is a source of its own: its frames must not share the
            # camera's join keys downstream (the tracker fuses both)
            source=self.config.stream or msg.header.source,
        )
        return LocalizedDetections(
            header=header, camera_frame=frame.camera_frame, detections=entries, rejected=rejected, view=view, floor_view=floor,
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
