"""The camera node: a camera, a video file or a folder of images in, ``frames/{camera}`` out.

Each frame carries the camera's intrinsics (from the device, a calibration file or, roughly, a
field of view) and is stamped by its capture time. A file's frame k (the first is 1) has
``header.seq`` k and the stamp ``start + (k - 1) / fps``, so that results can be judged frame
by frame; it plays in real time at its frame rate (times ``rate``), or, with ``pace: max``, each
frame once the detector has answered the previous one. A live stream that goes away (a USB cable
pulled, an RTSP server gone) is reported in the status (``connected`` 0, ``stream_lost``) and
reopened with backoff.
"""

from __future__ import annotations

import logging
import time
from typing import Any, Callable

import numpy as np

from common.messages.keys import FRAMES, RELIABLE, Keys
from common.messages.schemas import CameraInfo, Detections, Header, Image, RGBDFrame
from common.runtime.node import Node
from common.runtime.ratelog import RateLimitedLog
from common.runtime.service import Counters, Shutdown
from common.transport.base import Transport
from services.camera.config import CameraConfig
from services.camera.calibration_file import load_calibration
from services.camera.core.calibration import from_fov, scaled
from services.camera.core.sources import Capture, Intrinsics, Source, SourceError, StreamLost

__all__ = ["CameraService", "open_source"]

log = logging.getLogger(__name__)


def open_source(config: CameraConfig) -> Source:
    """The configured backend's source, opened; :class:`SourceError` names what is wrong."""
    if config.backend == "realsense":
        from services.camera.core.realsense import RealSenseSource

        return RealSenseSource(config.source, serial=config.serial, width=config.width, height=config.height,
                               fps=config.fps)
    from services.camera.core.opencv import OpenCvSource

    return OpenCvSource(config.source, fps=config.fps, width=config.width, height=config.height,
                        passthrough=config.passthrough)


class CameraService(Node):
    """Publishes ``frames/{camera}`` from a :class:`Source`; see the module's doc."""

    name = "camera"

    def __init__(self, transport: Transport, keys: Keys, config: CameraConfig, counters: Counters | None = None,
                 source: Source | None = None, opener: Callable[[], Source] | None = None,
                 wall_clock: Callable[[], int] = time.time_ns) -> None:
        super().__init__(transport, keys, counters)
        self.config = config
        self._opener = opener or (lambda: open_source(config))
        self.source: Source | None = source if source is not None else self._opener()
        self._log = RateLimitedLog(log)
        self.pub = self.io.publisher(keys.frames(config.camera), RGBDFrame, FRAMES)
        self.is_file = self.source.is_file
        self.fps = self.source.fps or config.fps
        self._max = config.pace == "max" and self.is_file
        self.detections = (self.io.subscribe(keys.detections(config.detections or config.camera), Detections, RELIABLE)
                           if self._max else None)
        self._intrinsics: dict[tuple[int, int], Intrinsics] = {}
        self._start_ns = config.start_ns if config.start_ns is not None else wall_clock()
        self._wall = wall_clock
        self._t0: float | None = None  # monotonic time of the file's first frame
        self._loops = 0
        self._frames_per_loop = 0
        self._last_index = 0  # a file's last frame number read (its length, at the end)
        self._published_in_run = 0  # frames published since the file started (real-time pacing)
        self._seq = 0
        self._waiting_since: float | None = None  # max: when the last frame went out unanswered
        self._last_stamp = 0
        self._retry_at: float | None = None
        self._backoff = config.retry_initial_s
        self.finished = False
        self.counters.gauge("connected", 1)

    # ---------------------------------------------------------------- the camera model
    def _camera_info(self, header: Header, width: int, height: int) -> CameraInfo:
        intr = self._intrinsics.get((width, height))
        if intr is None:
            if self.source is not None and self.source.intrinsics is not None:
                intr = scaled(self.source.intrinsics, width, height)
            elif self.config.camera_info is not None:
                intr = scaled(load_calibration(self.config.camera_info), width, height)
            else:
                intr = from_fov(width, height, self.config.hfov_deg)
                log.warning("no calibration: intrinsics from a %g degree horizontal field of view, so positions will "
                            "be rough; calibrate the camera and give --camera-info FILE.yaml", self.config.hfov_deg)
            self._intrinsics[(width, height)] = intr
        model = intr.distortion_model if intr.distortion_model in ("plumb_bob", "rational_polynomial", "equidistant") \
            else "none"
        return CameraInfo(header=header, width=width, height=height, K=intr.K, D=intr.D if model != "none" else np.zeros(0),
                          distortion_model=model)  # type: ignore[arg-type]

    def _frame(self, cap: Capture) -> RGBDFrame:
        if self.is_file:
            k = cap.index + self._loops * self._frames_per_loop
            seq = k
            stamp = (cap.stamp_ns if cap.stamp_ns is not None
                     else self._start_ns + round((k - 1) * 1e9 / self.fps))
        else:
            self._seq += 1
            seq = self._seq
            stamp = cap.stamp_ns if cap.stamp_ns is not None else self._wall()
        header = Header(stamp_ns=stamp, frame_id=self.config.optical_frame, seq=seq, source=self.config.camera)
        if cap.jpeg is not None and cap.size is not None:
            h, w = cap.size
            rgb = Image(header=header, encoding="jpeg", dtype="uint8", shape=(h, w, 3), data=cap.jpeg)
            return RGBDFrame(header=header, rgb=rgb, depth=None, camera_info=self._camera_info(header, w, h))
        assert cap.rgb is not None
        h, w = cap.rgb.shape[:2]
        if self.config.jpeg_quality:
            pixels = cap.rgb[..., ::-1] if cap.order == "bgr8" else cap.rgb
            rgb = Image.from_array(pixels, "jpeg", header, quality=self.config.jpeg_quality)
        else:
            rgb = Image.from_array(cap.rgb, "bgr8" if cap.order == "bgr8" else "rgb8", header)
        depth = None
        if cap.depth is not None:
            enc = "16UC1" if cap.depth.dtype == np.uint16 else "32FC1"
            depth = Image.from_array(cap.depth.astype(np.float32) if enc == "32FC1" else cap.depth, enc, header)
        return RGBDFrame(header=header, rgb=rgb, depth=depth, camera_info=self._camera_info(header, w, h))

    # ---------------------------------------------------------------- pacing
    def _due(self, now: float) -> bool:
        if not self.is_file:
            return True
        if self._max:
            if self._waiting_since is None:
                return True
            assert self.detections is not None
            while (got := self.detections.try_recv()) is not None:
                if got.msg.header.stamp_ns >= self._last_stamp:
                    self._waiting_since = None
            if self._waiting_since is not None and now - self._waiting_since >= self.config.max_wait_s:
                self.counters.count("detector_timeouts")
                self._waiting_since = None
            return self._waiting_since is None
        if self._t0 is None:
            return True
        return now >= self._next_time()

    def _next_time(self) -> float:
        assert self._t0 is not None
        return self._t0 + self._published_in_run / self.fps / self.config.rate

    # ---------------------------------------------------------------- the loop
    def _lost(self, now: float, why: str) -> None:
        self.counters.count("stream_lost")
        self.counters.gauge("connected", 0)
        self._log.warning("lost", "%s; reopening in %.1f s", why, self._backoff)
        if self.source is not None:
            self.source.close()
            self.source = None
        self._retry_at = now + self._backoff

    def _reopen(self, now: float) -> bool:
        try:
            self.source = self._opener()
        except SourceError as exc:
            self.counters.count("reopen_failed")
            self._backoff = min(self._backoff * 2, self.config.retry_max_s)
            self._retry_at = now + self._backoff
            self._log.warning("reopen", "cannot reopen the source: %s; next try in %.1f s", exc, self._backoff)
            return False
        self.counters.count("reconnects")
        self.counters.gauge("connected", 1)
        self._retry_at = None
        self._backoff = self.config.retry_initial_s
        log.info("reopened %s", self.source.name)
        return True

    def poll(self, now: float) -> list[Any]:
        if self.finished:
            return []
        if self.source is None:
            if self._retry_at is None or now < self._retry_at or not self._reopen(now):
                return []
        if not self._due(now):
            return []
        assert self.source is not None
        try:
            cap = self.source.read()
        except StreamLost as exc:
            self._lost(now, str(exc))
            return []
        except SourceError as exc:  # a bad image in a folder: skipped, counted
            self.counters.drop("unreadable")
            self._log.warning("unreadable", "%s", exc)
            return []
        if cap is None:  # the end of a file
            self._frames_per_loop = max(self._frames_per_loop, self._last_index)
            if self.config.loop:
                self._loops += 1
                self.source.close()
                self.source = self._opener()
                return []
            log.info("the end of %s after %d frames", self.source.name, self.pub.published)
            self.finished = True
            return []
        self._last_index = cap.index
        frame = self._frame(cap)
        self.pub.put(frame)
        if self._t0 is None:
            self._t0 = now
        self._published_in_run += 1
        self._last_stamp = frame.header.stamp_ns
        if self._max:
            self._waiting_since = now
        return [frame]

    def deadline(self, now: float) -> float | None:
        if self.finished:
            return 0.5
        if self.source is None and self._retry_at is not None:
            return max(0.0, self._retry_at - now)
        if not self.is_file:
            return 0.0  # read() waits for the camera's next frame
        if self._max:
            return 0.01 if self._waiting_since is not None else 0.0
        if self._t0 is None:
            return 0.0
        return max(0.0, self._next_time() - now)

    def run(self, shutdown: Shutdown, clock: Callable[[], float] = time.monotonic) -> None:
        """Poll until ``shutdown`` is set or a file has ended (without ``loop``)."""
        while not shutdown.is_set() and not self.finished:
            wait = self.deadline(clock())
            if wait:
                self.io.wait(min(0.2, wait))
            self.poll(clock())

    def describe(self) -> str:
        what = self.source.name if self.source is not None else self.config.source
        pace = ("live" if not self.is_file else "as fast as the detector" if self._max
                else f"{self.fps:g} fps x {self.config.rate:g}")
        return f"{what} ({pace}) -> {self.pub.key}"

    def close(self) -> None:
        if self.source is not None:
            self.source.close()
            self.source = None
        super().close()
