"""The tracker service's inputs: localized detections and embeddings joined per source frame, the
embedding model checked, stamps watched for clock jumps, and each frame converted once into the
core's input (:class:`~services.tracker.core.types.FrameInput`): a localized detections message
when it arrives (:class:`Arrival`), its joined frame with the descriptors, orientations, view,
score model and camera (:class:`Frame`, what the reorder buffer keeps, so a rewind replays it as it
is). Descriptors of another model or dimension than the tracked one are refused; the first
accepted model card gives its thresholds when the settings have none.
"""

from __future__ import annotations

import logging
from dataclasses import dataclass
from typing import Any, Callable, Mapping

import numpy as np

from common.messages.schemas import Embeddings, LocalizedDetections, ModelCard
from common.runtime.join import Dropped, Joiner
from common.runtime.ratelog import RateLimitedLog
from common.runtime.service import Counters
from services.tracker.config import AppearanceConfig, TrackerConfig
from services.tracker.convert import descriptors_for, field_of_view, orientations_for, positions_of
from services.tracker.core import FrameInput
from services.tracker.core.cues import usable_covariances
from services.tracker.core.cues.posture import codes as posture_codes
from services.tracker.core.view import FieldOfView, FloorView, ScanView, View, Views
from services.tracker.reorder import ClockJumps, InputKey

__all__ = ["Arrival", "Frame", "Intake"]

log = logging.getLogger("services.tracker.service")

#: What the tracker calls each of the joiner's drop reasons (``dropped_<name>``).
_DROP_NAMES = {"orphan": "unpaired_embeddings", "late": "late_embeddings", "duplicate": "duplicate",
               "overflow": "join_overflow"}
#: Added to every detection covariance: keeps R invertible for degenerate (zero) ones.
R_EPS = np.eye(3) * 1e-6


@dataclass(frozen=True)
class Arrival:
    """A localized detections message converted on arrival, as :class:`FrameInput` takes it (``covs``
    plus :data:`R_EPS`, ``usable`` their check's verdicts)."""

    loc: LocalizedDetections
    positions: np.ndarray
    covs: np.ndarray
    usable: np.ndarray
    scores: np.ndarray
    aspects: np.ndarray | None
    postures: np.ndarray | None
    statures: np.ndarray | None

    @classmethod
    def of(cls, loc: LocalizedDetections) -> Arrival:
        positions, covs = positions_of(loc)
        covs = covs + R_EPS
        scores = np.array([d.score for d in loc.detections], np.float64)
        boxes = np.array([d.bbox_xyxy for d in loc.detections], np.float64).reshape(-1, 4)
        aspects: np.ndarray | None = (boxes[:, 3] - boxes[:, 1]) / np.maximum(boxes[:, 2] - boxes[:, 0], 1e-6)
        if len(boxes) and not boxes.any():  # no image boxes (a laser's): no posture evidence, not even the height
            aspects = None
        statures = np.array([np.nan if d.stature_m is None else d.stature_m for d in loc.detections], np.float64)
        return cls(loc, positions, covs, usable_covariances(covs), scores, aspects,
                   posture_codes([d.posture for d in loc.detections]), statures if np.isfinite(statures).any() else None)


@dataclass(frozen=True)
class Frame:
    """A joined frame as the reorder buffer keeps it: its arrival, whether its embeddings
    came (``with_embeddings``) and the core's input."""

    arrival: Arrival
    with_embeddings: bool
    input: FrameInput

    @property
    def loc(self) -> LocalizedDetections:
        return self.arrival.loc


def _completion(no_embeddings: frozenset[str]) -> Callable[[Mapping[str, Any]], bool]:
    def complete(items: Mapping[str, Any]) -> bool:
        """A frame is ready with its embeddings (or their known absence), with no detections,
        when its stream has no embedder, or when it is a laser's (no image to describe)."""
        loc = items["localized"].loc
        return ("embeddings" in items or not loc.detections or loc.header.source in no_embeddings
                or loc.scan_view is not None)
    return complete


class Intake:
    """Joins, model checks, clock jumps and the conversion of frames for the tracker service:
    ``model`` the embedding model to track (None: the first whose card is accepted), ``dim``/``dim_why``
    the descriptors' dimension and where it comes from, ``on_thresholds(thresholds, metric)`` called
    with the first accepted card's thresholds."""

    def __init__(self, config: TrackerConfig, counters: Counters, ratelog: RateLimitedLog, model: str | None,
                 dim: int | None, dim_why: str, on_thresholds: Callable[[AppearanceConfig, str | None], None]) -> None:
        self.config = config
        self.counters = counters
        self._log = ratelog
        self.model = model
        self._dim, self._dim_why = dim, dim_why
        self._on_thresholds = on_thresholds
        self.have_thresholds = model is not None and config.thresholds(model) is not None
        self._card_applied = False
        self.join: Joiner[Arrival] = Joiner(
            ("localized", "embeddings"), wait_s=config.join_wait_s, on_timeout="release",
            orphan_s=config.join_wait_s + config.reorder_window_s, buffer=256, max_waiting=256, ordered=True,
            complete=_completion(frozenset(config.no_embeddings) | frozenset(config.lasers)))
        self.clock_jumps = ClockJumps(int(config.clock_jump_s * 1e9))
        self._score_models = config.score_models()  # by Detections.detector
        #: each camera's newest view, (stamp_ns, view): a coasting track in any recent one is in view
        self._views: dict[str, tuple[int, FieldOfView | FloorView | ScanView]] = {}

    # ------------------------------------------------------------- arrival
    def localized(self, loc: LocalizedDetections) -> tuple[Arrival | None, int]:
        """A localized detections message: its :class:`Arrival` (None: dropped, in another frame)
        and how far (ns) its stamp jumped back (0: no clock jump)."""
        if loc.header.frame_id and loc.header.frame_id != self.config.frame_id:
            self.counters.drop("wrong_frame")
            self._log.warning("wrong_frame", "dropping localized detections in frame %r; the tracker works in %r",
                              loc.header.frame_id, self.config.frame_id)
            return None, 0
        arrival = Arrival.of(loc)
        self._count_covariances(arrival)
        return arrival, self.clock_jumps.check(loc.header.source, loc.header.stamp_ns)

    def _count_covariances(self, arrival: Arrival) -> None:
        """Count (and log) detections whose covariance is not symmetric positive definite (non-finite
        ones never get here: decoding refuses them, the subscription's ``invalid``)."""
        bad = int((~arrival.usable).sum())
        if bad:
            self.counters.count("bad_covariances", bad)
            self._log.warning("bad_covariance", "%d of %d detections of frame %s carry a covariance that is not "
                              "symmetric positive definite; sigma_r stands for it", bad, len(arrival.usable),
                              arrival.loc.header.join_key)

    def refusal(self, card: ModelCard) -> str | None:
        """Why descriptors of ``card`` cannot be used (None: they can). Locks onto one
        embedding model and dimension, and resolves the model's thresholds."""
        if self.model is None:
            self.model = card.name
            log.info("tracking with descriptors of embedding model %r", card.name)
        if card.name != self.model:
            self._log.warning("wrong_model", "dropping descriptors of embedding model %r: the tracker uses %r; "
                              "their frames run position-only", card.name, self.model)
            return "wrong_model"
        if self._dim is not None and card.dim != self._dim:
            self._log.warning("wrong_dimension", "dropping descriptors of embedding model %r of dimension %d: %s; "
                              "their frames run position-only", card.name, card.dim, self._dim_why)
            return "wrong_dimension"
        if self._dim is None:
            self._dim, self._dim_why = card.dim, f"its first descriptors had dimension {card.dim}"
        if not self._card_applied:  # the first card: its thresholds if needed, and its metric
            self._card_applied = True
            th = self.config.thresholds(card.name)
            if th is None and card.thresholds is not None:
                log.warning("no thresholds for embedding model %r in the tracker config; using the model card's %s",
                            card.name, card.thresholds.model_dump())
                th = AppearanceConfig(**card.thresholds.model_dump())
            if th is not None:
                self._on_thresholds(th, card.metric)
                self.have_thresholds = True
        return None

    def embeddings(self, emb: Embeddings, now: float) -> tuple[Embeddings | None, list[Dropped]]:
        """Join ``emb`` to its frame; None (and the frame need not wait) when refused."""
        accepted: Embeddings | None = emb
        if reason := self.refusal(emb.model):
            self.counters.drop(reason)
            accepted = None  # known not to come: its frame need not wait
        return accepted, self.join.add("embeddings", emb.header.join_key, accepted, now)

    def count(self, dropped: list[Dropped]) -> None:
        for d in dropped:
            self.counters.drop(_DROP_NAMES.get(d.reason, d.reason))

    # ------------------------------------------------------------ conversion
    def ready(self, now: float) -> list[tuple[InputKey, Frame]]:
        """The joined frames ready to track, converted."""
        joined, dropped = self.join.poll(now)
        self.count(dropped)
        out = []
        for j in joined:
            if j.timed_out:
                self.counters.count("position_only_timeout")
            out.append((j.key, self.convert(j.anchor, j.get("embeddings"))))
        return out

    def convert(self, arrival: Arrival, emb: Embeddings | None, view: View | None = None) -> Frame:
        """The core's input for ``arrival`` with its embeddings ``emb`` (None: none came);
        ``view``: the cameras' view when known (a frame converted again), else from the frame."""
        loc = arrival.loc
        descriptors = None
        if emb is not None and self.have_thresholds:
            descriptors = descriptors_for(loc, emb)
        elif not loc.detections and self.have_thresholds:
            descriptors = np.zeros((0, 1), np.float32)
        elif loc.detections and emb is not None:
            self.counters.count("no_thresholds")
        use_cov = self.config.uses_detection_covariance  # unusable ones: the profile's fixed R (counted on arrival)
        frame = FrameInput(arrival.positions, descriptors, arrival.covs if use_cov else None,
                           arrival.usable if use_cov else None, arrival.scores,
                           self.view(loc) if view is None else view, arrival.aspects, orientations_for(loc, emb),
                           self._score_models.get(loc.detector), loc.camera_frame, arrival.postures, arrival.statures,
                           detector=loc.detector)
        return Frame(arrival, emb is not None, frame)

    def view(self, loc: LocalizedDetections) -> View | None:
        """What the cameras could see at this frame: its own camera's view at this frame, and
        with several cameras the union with each other camera's newest view within
        ``view_age_s``. Two detectors' streams of one camera (one ``camera_frame``) are one
        camera: its view at another time is not what it sees now (it may have turned)."""
        try:
            view = field_of_view(loc)
        except ValueError as exc:  # e.g. a zero focal length or a singular homography: tracked without it
            view = None
            self.counters.count("bad_view")
            self._log.warning("bad_view", "the camera's view of frame %s is unusable (%s): tracking it without one",
                              loc.header.seq, exc)
        stamp = loc.header.stamp_ns
        camera = loc.camera_frame or loc.header.source
        if view is not None:
            known = self._views.get(camera)
            if known is None or known[0] <= stamp:
                self._views[camera] = (stamp, view)
        if len(self._views) < 2:
            return view
        age_ns = int(self.config.view_age_s * 1e9)
        others = tuple(v for c, (s, v) in self._views.items() if c != camera and abs(stamp - s) <= age_ns)
        if view is None:
            return Views(others) if len(others) > 1 else (others[0] if others else None)
        return Views((view, *others)) if others else view

    def restart(self) -> None:
        """A new clock: the joiner's memory of released keys and the cameras' views start over."""
        self.join.forget_released()  # a looping replay sends the same keys again
        self._views.clear()
