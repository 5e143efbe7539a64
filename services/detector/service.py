"""DetectorService: RGB-D frames in, ``Detections`` out, never queueing behind a slow model.

Frames arrive on a latest-only subscription (a ring of one): while the model runs,
newer frames overwrite older ones, and each overwritten frame is counted as dropped
stale. Each published ``Detections`` carries the source frame's header (stamp, seq,
source, frame_id) so downstream services can join on it.
"""

from __future__ import annotations

import logging
import time

import cv2
import numpy as np

from common.keys import FRAMES, RELIABLE, Keys
from common.runtime import Counters, Shutdown
from common.schemas import Detection, Detections, RGBDFrame
from common.transport import Transport
from services.detector.config import DetectorConfig, build_detector
from services.detector.core import Detector
from services.detector.core.boxes import DetectorError

__all__ = ["DetectorService"]

log = logging.getLogger(__name__)


class DetectorService:
    """Runs one detector on one camera's frames.

    ``detector`` defaults to the one ``config`` names (built here, so model errors
    surface at start-up); tests may pass their own.
    """

    def __init__(self, transport: Transport, keys: Keys, config: DetectorConfig, counters: Counters | None = None,
                 detector: Detector | None = None) -> None:
        self.config = config
        self.counters = counters if counters is not None else Counters()
        self.detector = detector if detector is not None else build_detector(config)
        self.frames = transport.subscribe(keys.frames(config.camera), RGBDFrame, FRAMES)
        self.publisher = transport.publisher(keys.detections(config.camera), Detections, RELIABLE)
        self.processed = 0
        self._total_ms = 0.0
        self._last_log: dict[str, float] = {}

    def _warn(self, reason: str, message: str, *args: object) -> None:
        """Log at most once a second per reason."""
        now = time.monotonic()
        if now - self._last_log.get(reason, -1e9) >= 1.0:
            self._last_log[reason] = now
            log.warning(message, *args)

    def step(self, timeout: float) -> Detections | None:
        """Wait up to ``timeout`` s for the newest frame and process it; the published message or None."""
        got = self.frames.recv(timeout)
        self.counters.gauge("dropped_stale", self.frames.stats.dropped)
        if got is None:
            return None
        return self.process(got.msg)

    def process(self, frame: RGBDFrame) -> Detections | None:
        """Detect people in ``frame`` and publish them; None (counted, logged) if the frame is unusable."""
        try:
            rgb = frame.rgb.to_array()
            # Only the backends that use depth pay for decoding it.
            depth = frame.depth.depth_m() if frame.depth is not None and self.detector.needs_depth else None
        except ValueError as exc:
            self.counters.drop("bad_image")
            self._warn("bad_image", "frame %d from %s: cannot decode image: %s", frame.header.seq, frame.header.source, exc)
            return None
        if self.detector.needs_depth and depth is None:
            self.counters.drop("no_depth")
            self._warn("no_depth", "frame %d from %s has no depth; the %s backend needs it (dropped %d so far)",
                       frame.header.seq, frame.header.source, self.detector.name,
                       int(self.counters.extra.get("dropped_no_depth", 0)))
            return None
        start = time.perf_counter()
        try:
            boxes, scores = self.detector.detect(rgb, depth, np.asarray(frame.camera_info.K))
        except (DetectorError, cv2.error) as exc:
            self.counters.drop("detector_error")
            self._warn("detector_error", "frame %d from %s: detection failed: %s", frame.header.seq, frame.header.source, exc)
            return None
        ms = (time.perf_counter() - start) * 1000.0
        self.processed += 1
        self._total_ms += ms
        self.counters.gauge("inference_ms", round(ms, 3))
        self.counters.gauge("inference_ms_mean", round(self._total_ms / self.processed, 3))
        self.counters.count("frames_processed")
        msg = Detections(
            header=frame.header.model_copy(),
            detections=[Detection(index=i, bbox_xyxy=tuple(float(v) for v in b), score=float(s))
                        for i, (b, s) in enumerate(zip(boxes, scores))],
            image_width=int(rgb.shape[1]),
            image_height=int(rgb.shape[0]),
            detector=self.detector.name,
            inference_ms=ms,
        )
        self.publisher.put(msg)
        return msg

    def run(self, shutdown: Shutdown) -> None:
        """Process frames until ``shutdown`` is set."""
        log.info("detector %s on %s", self.detector.name, self.frames.key)
        while not shutdown.is_set():
            self.step(self.config.recv_timeout_s)

    def close(self) -> None:
        self.frames.close()
        self.publisher.close()
