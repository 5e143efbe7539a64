"""The embedder service: pair frames with their detections, crop, describe, publish.

Frames arrive latest-only, detections reliably and a little later (the detector works on
the same frame first). A :class:`common.runtime.join.Joiner` keeps the last ``frame_buffer``
frames and pairs each Detections message with its frame on ``Header.join_key``; every
box is cropped (clamped to the image; empty boxes are skipped and counted) and the
backend describes all crops of the frame in one call. Work whose frame is more than
``max_lag_s`` older than the newest frame is dropped and counted instead of being
processed late, so a slow model never builds a queue.

When the frame carries depth, each crop is masked to the pixels near the person's depth
(``depth_mask``, :mod:`services.embedder.core.depth_mask`) before it is described; without
depth, or when a box has too little depth or its mask keeps nothing, the crop is
described unmasked. Bad inputs are counted: ``empty_boxes`` (nothing left inside the
image), ``tiny_crops`` (under ``min_crop_px``: not described), ``clipped_boxes`` (partly
outside the image: described as cut), ``depth_missing`` and ``mask_empty`` (described
unmasked), ``masked_crops`` (described with a depth mask).
"""

from __future__ import annotations

import logging
import math
import time

import numpy as np

from common.runtime.join import Dropped, Joiner
from common.messages.keys import FRAMES, RELIABLE, Keys
from common.runtime.node import Node
from common.runtime.service import Counters
from common.messages.schemas import AppearanceThresholds, Detections, Embeddings, ModelCard, RGBDFrame
from common.transport.base import Transport
from services.embedder.config import EmbedderConfig, build_backend
from services.embedder.core.backend import Backend, Card, EmbedderError, box_slices
from services.embedder.core.depth_mask import apply_mask, depth_masks
from services.embedder.core.orientation import OrientationClassifier

__all__ = ["EmbedderService", "model_card"]

log = logging.getLogger(__name__)

#: What the embedder calls each of the joiner's drop reasons (``dropped_<name>``).
_DROP_NAMES = {"stale": "stale", "overflow": "unpaired", "duplicate": "duplicate", "late": "duplicate"}


def model_card(card: Card) -> ModelCard:
    """The wire form of a backend's card."""
    thresholds = None
    if card.thresholds is not None:
        lo, hi, rec = card.thresholds
        thresholds = AppearanceThresholds(t_lower=lo, t_upper=hi, t_recover=rec)
    return ModelCard(name=card.name, dim=card.dim, metric=card.metric, input_size=card.input_size,
                     normalized=card.normalized, thresholds=thresholds)


class EmbedderService(Node):
    """Subscribes ``frames/{camera}`` and ``detections/{camera}``, publishes ``embeddings/{camera}``."""

    name = "embedder"

    def __init__(self, transport: Transport, keys: Keys, config: EmbedderConfig, counters: Counters | None = None,
                 backend: Backend | None = None, orientation: OrientationClassifier | None = None) -> None:
        super().__init__(transport, keys, counters)
        self.config = config
        self.backend = backend if backend is not None else build_backend(config)
        self.card = model_card(self.backend.card)
        params = config.orientation.params()
        if orientation is None and params is not None:
            orientation = OrientationClassifier(params)
        self.orientation = orientation
        self._mask_params = config.depth_mask.params()
        cam = config.camera
        self.frames_sub = self.io.subscribe(keys.frames(cam), RGBDFrame, FRAMES)
        self.dets_sub = self.io.subscribe(keys.detections(cam), Detections, RELIABLE)
        self.pub = self.io.publisher(keys.embeddings(cam), Embeddings, RELIABLE)
        # no wall-clock timeout: work waits for its frame until it is max_lag_s behind the camera
        self.join: Joiner[Detections] = Joiner(
            ("detections", "frame"), wait_s=math.inf, buffer=config.frame_buffer,
            max_waiting=4 * config.frame_buffer, max_lag_s=config.max_lag_s, clock_jump_s=5.0)

    def describe(self) -> str:
        c = self.card
        return f"{c.name} ({c.dim}-D {c.metric}) on {self.dets_sub.key}"

    # ------------------------------------------------------------------ inputs

    def add_frame(self, frame: RGBDFrame, now: float | None = None) -> None:
        """Remember a frame (the oldest falls out of the buffer)."""
        now = time.monotonic() if now is None else now
        self._count(self.join.add("frame", frame.header.join_key, frame, now))

    def _count(self, dropped: list[Dropped]) -> None:
        for d in dropped:
            if "detections" in d.slots:
                self.counters.drop(_DROP_NAMES.get(d.reason, d.reason))
            else:
                self.counters.count(f"frames_{d.reason}")

    def _drain_frames(self, now: float) -> None:
        while (got := self.frames_sub.try_recv()) is not None:
            self.add_frame(got.msg, now)

    def poll(self, now: float) -> list[Embeddings]:
        """Handle everything that has arrived; returns the Embeddings published."""
        self._drain_frames(now)
        while (got := self.dets_sub.try_recv()) is not None:
            self._count(self.join.add("detections", got.msg.header.join_key, got.msg, now))
        published = []
        while True:
            self._drain_frames(now)  # time passed in the model: see what is newest now
            joined, dropped = self.join.poll(now, limit=1)
            self._count(dropped)
            if self.join.clock_jumps != self.counters.extra.get("clock_jumps", 0):
                self.counters.gauge("clock_jumps", self.join.clock_jumps)  # a new clock: the join started over
            if not joined:
                break
            out = self.process(joined[0].items["frame"], joined[0].anchor)
            if out is not None:
                self.pub.put(out)
                published.append(out)
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
        slices, usable, clipped = box_slices(boxes, image.shape[1], image.shape[0])
        size = np.minimum(slices[:, 2] - slices[:, 0], slices[:, 3] - slices[:, 1])
        kept = np.flatnonzero(usable & (size >= self.config.min_crop_px))
        indices = np.array([dets.detections[i].index for i in kept], np.int32)
        if len(np.unique(indices)) != len(indices):
            self.counters.invalid += 1
            log.warning("frame %d: detections carry duplicate indices; not published", frame.header.seq)
            return None
        if (~usable).any():
            self.counters.count("empty_boxes", int((~usable).sum()))
        if (usable & (size < self.config.min_crop_px)).any():
            self.counters.count("tiny_crops", int((usable & (size < self.config.min_crop_px)).sum()))
        if clipped[kept].any():
            self.counters.count("clipped_boxes", int(clipped[kept].sum()))
        crops = [image[y0:y1, x0:x1] for x0, y0, x1, y1 in slices[kept]]
        masks = self._masks(frame, slices[kept]) if len(kept) else None
        t0 = time.perf_counter()
        try:
            if masks is None:
                vectors = self.backend.embed(crops)
            elif getattr(self.backend, "accepts_masks", False):
                vectors = self.backend.embed(crops, masks=masks)  # type: ignore[call-arg]
            else:
                vectors = self.backend.embed([apply_mask(c, m) for c, m in zip(crops, masks)])
        except EmbedderError as exc:
            self.counters.drop("backend_error")
            log.error("embedding frame %d failed: %s", frame.header.seq, exc)
            return None
        orientation = None
        if self.orientation is not None:
            try:
                orientation = self.orientation.classify(crops)
            except EmbedderError as exc:
                self.counters.count("orientation_errors")
                log.error("orientation of frame %d failed: %s", frame.header.seq, exc)
        ms = (time.perf_counter() - t0) * 1e3
        self.counters.gauge("embed_ms", round(ms, 3))
        self.counters.count("descriptors", len(kept))
        return Embeddings(header=frame.header.model_copy(), model=self.card, indices=indices,
                          vectors=vectors.astype(np.float32, copy=False).reshape(len(kept), self.card.dim),
                          orientation=orientation)

    def _masks(self, frame: RGBDFrame, slices: np.ndarray) -> list[np.ndarray | None] | None:
        """Depth masks of the crops at ``slices`` (K, 4), or None without depth (or when turned off)."""
        if not self.config.depth_mask.enabled or frame.depth is None:
            return None
        try:
            depth = frame.depth.to_array()
        except ValueError as exc:
            self.counters.count("depth_invalid")
            log.warning("frame %s/%d: cannot decode the depth image, crops unmasked: %s", frame.header.source,
                        frame.header.seq, exc)
            return None
        masks, reasons = depth_masks(depth.reshape(depth.shape[:2]), [tuple(int(v) for v in s) for s in slices],
                                     self._mask_params)
        for reason in reasons:
            self.counters.count(reason if reason is not None else "masked_crops")
        return masks
