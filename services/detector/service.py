"""DetectorService: RGB-D frames in, ``Detections`` out, never queueing behind a slow model.

Frames arrive on a latest-only subscription (a ring of one): while the model runs,
newer frames overwrite older ones, and each overwritten frame is counted as dropped
stale. Each published ``Detections`` carries the source frame's header (stamp, seq,
source, frame_id) so downstream services can join on it.

The depth backend also reads ``tf`` and ``tf_static`` when ``floor_frame`` is set: the
floor's plane in the camera frame at each frame's stamp, from the robot's own transforms
(``floor_from_transforms``); without one it tracks the floor alone (``floor_estimated``).
"""

from __future__ import annotations

import logging
import time
from collections.abc import Sequence
from typing import Any

import cv2
import numpy as np

from common.geometry.transforms import TransformBuffer, TransformError
from common.geometry.messages import take_transforms
from common.messages.keys import FRAMES, RELIABLE, Keys
from common.runtime.node import Node
from common.runtime.ratelog import RateLimitedLog
from common.runtime.service import Counters
from common.messages.schemas import Detection, Detections, RGBDFrame, TransformBatch
from common.transport.base import Transport
from services.detector.config import DetectorConfig, build_detector
from services.detector.core import Detector
from services.detector.core.boxes import DetectorError
from services.detector.core.ground import Plane

__all__ = ["DetectorService"]

log = logging.getLogger(__name__)


class DetectorService(Node):
    """Runs one detector on one camera's frames.

    ``detector`` defaults to the one ``config`` names (built here, so model errors
    surface at start-up); tests may pass their own.
    """

    name = "detector"

    def __init__(self, transport: Transport, keys: Keys, config: DetectorConfig, counters: Counters | None = None,
                 detector: Detector | None = None) -> None:
        super().__init__(transport, keys, counters)
        self.config = config
        self.detector = detector if detector is not None else build_detector(config)
        self.frames = self.io.subscribe(keys.frames(config.camera), RGBDFrame, FRAMES)
        self.buffer: TransformBuffer | None = None
        if config.floor_frame and getattr(self.detector, "uses_floor", False):
            self.buffer = TransformBuffer(history_s=max(2.0, 4 * config.floor_tolerance_s),
                                          tolerance_s=config.floor_tolerance_s)
            self.sub_tf_static = self.io.subscribe(keys.tf_static(), TransformBatch, RELIABLE)
            self.sub_tf = self.io.subscribe(keys.tf(), TransformBatch, RELIABLE)
        self.publisher = self.io.publisher(keys.detections(config.output), Detections, RELIABLE)
        self.processed = 0
        self._total_ms = 0.0
        #: max_rate_hz as the least sensor time between two processed frames (ns), less 1 ms so
        #: that stamp jitter does not skip a frame that is due
        self._min_gap_ns = None if config.max_rate_hz is None else int(1e9 / config.max_rate_hz) - 1_000_000
        self._last_ns: int | None = None
        self._log = RateLimitedLog(log)

    def describe(self) -> str:
        floor = f", floor from {self.config.floor_frame} (tf)" if self.buffer is not None else ""
        return f"detector {self.detector.name} on {self.frames.key}{floor}"

    def floor(self, frame: RGBDFrame) -> Plane | None:
        """The floor's plane in ``frame``'s camera frame from the transforms (taken in by
        :meth:`poll` before the frame), or None (counted)."""
        if self.buffer is None:
            return None
        camera = frame.header.frame_id or frame.camera_info.header.frame_id
        try:
            cam_from_floor = self.buffer.lookup(camera, self.config.floor_frame, frame.header.stamp_ns)
        except TransformError as exc:
            self.counters.count("floor_estimated")
            self._log.warning("no_floor", "no transform %s -> %s for frame %d: the detector tracks the floor alone "
                              "(%s)", self.config.floor_frame, camera, frame.header.seq, exc)
            return None
        self.counters.count("floor_from_transforms")
        normal = cam_from_floor.matrix[:3, 2].copy()
        return Plane(normal, float(-normal @ cam_from_floor.translation - self.config.floor_height_m))

    def _postures(self, n: int) -> list[str | None]:
        """The posture of each of the ``n`` last detections, None where the backend cannot tell."""
        postures = list(self.detector.postures)
        return postures if len(postures) == n else [None] * n  # type: ignore[return-value]

    @staticmethod
    def _measured(values: Sequence[float], n: int) -> list[float | None]:
        """One of the backend's measures of its ``n`` last detections (their own depth, their
        stature; m), None where it did not measure it (NaN, or no values from this backend)."""
        out = [float(v) for v in values]
        return [v if np.isfinite(v) and v > 0 else None for v in out] if len(out) == n else [None] * n

    def _floor_agreement(self, floor: Plane | None) -> None:
        """Count frames whose depth shows no floor where the transforms put it, with the camera's
        height and tilt above each floor (for perception doctor: a wrong camera mount)."""
        if floor is None or getattr(self.detector, "plane_inliers", 1) != 0:
            return
        self.counters.count("floor_disagrees")
        self.counters.gauge("floor_transforms_height_m", round(floor.offset, 3))
        self.counters.gauge("floor_transforms_tilt_deg", round(_tilt_deg(floor), 1))
        seen = getattr(self.detector, "depth_floor", None)
        if seen is not None:
            self.counters.gauge("floor_depth_height_m", round(seen.offset, 3))
            self.counters.gauge("floor_depth_tilt_deg", round(_tilt_deg(seen), 1))

    def poll(self, now: float) -> list[Any]:
        """Process the newest frame, if one arrived; returns what was published."""
        if self.buffer is not None:
            take_transforms(self.buffer, ((self.sub_tf_static, True), (self.sub_tf, False)), self.counters, self._log)
        got = self.frames.try_recv()
        self.counters.gauge("dropped_stale", self.frames.stats.dropped)
        if got is None:
            return []
        if self._min_gap_ns is not None and self._last_ns is not None:
            gap = got.msg.header.stamp_ns - self._last_ns
            if 0 <= gap < self._min_gap_ns:  # (a stamp that went back: a new clock, processed)
                self.counters.count("skipped_rate")
                return []
        self._last_ns = got.msg.header.stamp_ns
        msg = self.process(got.msg)
        return [] if msg is None else [msg]

    def process(self, frame: RGBDFrame) -> Detections | None:
        """Detect people in ``frame`` and publish them; None (counted, logged) if the frame is unusable."""
        try:
            rgb = frame.rgb.to_array()
            # Only the backends that use depth pay for decoding it.
            depth = frame.depth.depth_m() if frame.depth is not None and self.detector.needs_depth else None
        except ValueError as exc:
            self.counters.drop("bad_image")
            self._log.warning("bad_image", "frame %d from %s: cannot decode image: %s", frame.header.seq,
                              frame.header.source, exc)
            return None
        if self.detector.needs_depth and depth is None:
            self.counters.drop("no_depth")
            self._log.warning("no_depth", "frame %d from %s has no depth; the %s backend needs it (dropped %d so far)",
                              frame.header.seq, frame.header.source, self.detector.name,
                              int(self.counters.extra.get("dropped_no_depth", 0)))
            return None
        start = time.perf_counter()
        try:
            K = np.asarray(frame.camera_info.K)
            if self.buffer is not None:
                floor = self.floor(frame)
                boxes, scores = self.detector.detect(rgb, depth, K, floor=floor)  # type: ignore[call-arg]
                self._floor_agreement(floor)
            else:
                boxes, scores = self.detector.detect(rgb, depth, K)
        except (DetectorError, cv2.error) as exc:
            self.counters.drop("detector_error")
            self._log.warning("detector_error", "frame %d from %s: detection failed: %s", frame.header.seq,
                              frame.header.source, exc)
            return None
        ms = (time.perf_counter() - start) * 1000.0
        self.processed += 1
        self._total_ms += ms
        self.counters.gauge("inference_ms", round(ms, 3))
        self.counters.gauge("inference_ms_mean", round(self._total_ms / self.processed, 3))
        self.counters.count("frames_processed")
        msg = Detections(
            header=frame.header.model_copy(),
            detections=[Detection(index=i, bbox_xyxy=tuple(float(v) for v in b), score=float(s), posture=posture,
                                  depth_m=z, stature_m=h)
                        for i, (b, s, posture, z, h) in enumerate(zip(boxes, scores, self._postures(len(boxes)),
                                                                      self._measured(self.detector.depths, len(boxes)),
                                                                      self._measured(self.detector.statures,
                                                                                     len(boxes))))],
            image_width=int(rgb.shape[1]),
            image_height=int(rgb.shape[0]),
            detector=self.detector.name,
            inference_ms=ms,
        )
        self.publisher.put(msg)
        return msg


def _tilt_deg(plane: Plane) -> float:
    """How far the optical axis points below the horizontal, above the floor ``plane`` (camera frame)."""
    return float(np.degrees(-np.arcsin(np.clip(plane.normal[2], -1.0, 1.0))))
