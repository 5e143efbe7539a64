"""The embedder service: pair frames with their detections, crop, describe, publish.

Frames arrive latest-only, detections reliably and a little later (the detector works on
the same frame first). Recent frames are kept in a small buffer keyed by
``(source, stamp_ns, seq)``; each Detections message is paired with its frame, every
box is cropped (clamped to the image; empty boxes are skipped and counted) and the
backend describes all crops of the frame in one call. Work whose frame is more than
``max_lag_s`` older than the newest frame is dropped and counted instead of being
processed late, so a slow model never builds a queue.
"""

from __future__ import annotations

import logging
import time
from collections import OrderedDict

import numpy as np

from common.keys import FRAMES, RELIABLE, Keys
from common.runtime import Counters, Shutdown
from common.schemas import AppearanceThresholds, Detections, Embeddings, Header, ModelCard, RGBDFrame
from common.transport import Transport, wait_any
from services.embedder.config import EmbedderConfig
from services.embedder.core.backend import Backend, Card, EmbedderError, crop_boxes

__all__ = ["EmbedderService", "model_card"]

log = logging.getLogger(__name__)

FrameKey = tuple[str, int, int]


def model_card(card: Card) -> ModelCard:
    """The wire form of a backend's card."""
    thresholds = None
    if card.thresholds is not None:
        lo, hi, rec = card.thresholds
        thresholds = AppearanceThresholds(t_lower=lo, t_upper=hi, t_recover=rec)
    return ModelCard(name=card.name, dim=card.dim, metric=card.metric, input_size=card.input_size,
                     normalized=card.normalized, thresholds=thresholds)


def _key(header: Header) -> FrameKey:
    return (header.source, header.stamp_ns, header.seq)


class EmbedderService:
    """Subscribes ``frames/{camera}`` and ``detections/{camera}``, publishes ``embeddings/{camera}``."""

    def __init__(self, transport: Transport, keys: Keys, config: EmbedderConfig, backend: Backend,
                 counters: Counters | None = None) -> None:
        self.transport = transport
        self.config = config
        self.backend = backend
        self.counters = counters if counters is not None else Counters()
        self.card = model_card(backend.card)
        cam = config.camera
        self.frames_sub = transport.subscribe(keys.frames(cam), RGBDFrame, FRAMES)
        self.dets_sub = transport.subscribe(keys.detections(cam), Detections, RELIABLE)
        self.pub = transport.publisher(keys.embeddings(cam), Embeddings, RELIABLE)
        self._frames: OrderedDict[FrameKey, RGBDFrame] = OrderedDict()
        self._waiting: OrderedDict[FrameKey, Detections] = OrderedDict()
        self._newest_ns = 0
        self._lag_ns = int(config.max_lag_s * 1e9)

    # ------------------------------------------------------------------ inputs

    def add_frame(self, frame: RGBDFrame) -> None:
        """Remember a frame (the oldest falls out of the buffer)."""
        key = _key(frame.header)
        self._frames[key] = frame
        self._frames.move_to_end(key)
        while len(self._frames) > self.config.frame_buffer:
            self._frames.popitem(last=False)
        self._newest_ns = max(self._newest_ns, frame.header.stamp_ns)

    def _stale(self, header: Header) -> bool:
        return header.stamp_ns + self._lag_ns < self._newest_ns

    def _drain_frames(self) -> None:
        while (got := self.frames_sub.try_recv()) is not None:
            self.add_frame(got.msg)

    def poll(self) -> int:
        """Handle everything that has arrived; returns the number of Embeddings published."""
        self._drain_frames()
        while (got := self.dets_sub.try_recv()) is not None:
            self._waiting[_key(got.msg.header)] = got.msg
        published = 0
        for key in list(self._waiting):
            self._drain_frames()  # time passed in the model: see what is newest now
            dets = self._waiting[key]
            if self._stale(dets.header):
                del self._waiting[key]
                self.counters.drop("stale")
                continue
            frame = self._frames.get(key)
            if frame is None:
                continue  # its frame may still be on the way; it goes stale otherwise
            del self._waiting[key]
            out = self.process(frame, dets)
            if out is not None:
                self.pub.put(out)
                published += 1
        while len(self._waiting) > 4 * self.config.frame_buffer:
            self._waiting.popitem(last=False)
            self.counters.drop("unpaired")
        return published

    # ------------------------------------------------------------------ work

    def process(self, frame: RGBDFrame, dets: Detections) -> Embeddings | None:
        """Embeddings of one frame's detections, or None if the image is unusable."""
        try:
            image = frame.rgb.to_array()
        except ValueError as exc:
            self.counters.invalid += 1
            log.warning("frame %s/%d: cannot decode the image: %s", frame.header.source, frame.header.seq, exc)
            return None
        if image.ndim == 2:
            image = np.repeat(image[..., None], 3, axis=2)
        elif image.shape[2] == 4:
            image = image[..., :3]
        boxes = np.array([d.bbox_xyxy for d in dets.detections], np.float64).reshape(-1, 4)
        if dets.image_width and dets.image_height and (dets.image_width, dets.image_height) != image.shape[1::-1]:
            boxes *= np.array([image.shape[1] / dets.image_width, image.shape[0] / dets.image_height] * 2)
            self.counters.count("rescaled_frames")
        crops, kept = crop_boxes(image, boxes)
        indices = np.array([dets.detections[i].index for i in kept], np.int32)
        if len(np.unique(indices)) != len(indices):
            self.counters.invalid += 1
            log.warning("frame %d: detections carry duplicate indices; not published", frame.header.seq)
            return None
        if len(kept) < len(boxes):
            self.counters.count("empty_boxes", len(boxes) - len(kept))
        t0 = time.perf_counter()
        try:
            vectors = self.backend.embed(crops)
        except EmbedderError as exc:
            self.counters.drop("backend_error")
            log.error("embedding frame %d failed: %s", frame.header.seq, exc)
            return None
        ms = (time.perf_counter() - t0) * 1e3
        self.counters.gauge("embed_ms", round(ms, 3))
        self.counters.count("descriptors", len(kept))
        return Embeddings(header=frame.header.model_copy(), model=self.card, indices=indices,
                          vectors=vectors.astype(np.float32, copy=False).reshape(len(kept), self.card.dim))

    def run(self, shutdown: Shutdown) -> None:
        """Serve until ``shutdown`` is set, then close the subscriptions."""
        try:
            while not shutdown.is_set():
                wait_any([self.frames_sub, self.dets_sub], self.transport.notify, 0.2)
                self.poll()
        finally:
            self.close()

    def close(self) -> None:
        self.frames_sub.close()
        self.dets_sub.close()
        self.pub.close()
