"""TrackerService: LocalizedDetections + Embeddings in, Tracks out, over any Transport.

* Inputs of one source frame are joined on ``Header.join_key`` by a
  :class:`common.runtime.join.Joiner`. Localized detections wait up to ``join_wait_s`` for their
  embeddings; then the frame runs position-only, and if its embeddings come later while it
  is within ``reorder_window_s`` it is applied again with them (a rewind:
  ``late_embeddings_applied``); later still they are dropped (``dropped_late_embeddings``). A frame without detections needs no
  embeddings and runs at once; embeddings of another model are rejected and do not
  make their frame wait.
* Joined frames go through a :class:`ReorderBuffer`: applied in sensor-time order,
  rewinding for late ones within ``reorder_window_s``, dropping (and counting) older ones.
* After every update the tracker's output is published: the Confirmed tracks, and
  with the robust profile tracks coasting through a short miss (status ``coasting``). ``keys.track_query()`` answers
  ``?id=K`` with a Tracks message holding that ID's last known state (empty if unknown).
* The ID memory is loaded at start and written atomically when it changes, and every
  ``memory_save_period_s`` with the galleries of the live tracks, so a restarted tracker
  keeps identities.
* Bad inputs are counted, logged at most once a second per reason, and survived:
  unusable covariances (``bad_covariances``), descriptors of another model or dimension
  (``dropped_wrong_model``, ``dropped_wrong_dimension``), and stamps that jump back by more
  than ``clock_jump_s`` (``clock_jumps``: every track ends, its ID stays remembered, and
  tracking starts over on the new clock).
"""

from __future__ import annotations

import logging
import threading
import time
from dataclasses import dataclass
from typing import Any, Callable, Mapping

import numpy as np

from common.runtime.join import Dropped, Joiner
from common.messages.keys import RELIABLE, Keys
from common.runtime.node import Node
from common.runtime.ratelog import RateLimitedLog
from common.runtime.service import Counters
from common.messages.schemas import (
    Embeddings,
    ForgetReply,
    Header,
    LocalizedDetections,
    ModelCard,
    Tracks,
    TrackState,
)
from common.transport.base import Transport
from services.tracker.config import AppearanceConfig, TrackerConfig
from services.tracker.convert import (
    descriptors_for,
    field_of_view,
    orientations_for,
    positions_of,
    track_state,
    tracks_message,
    usable_covariances,
)
from services.tracker.core import FrameResult, TrackStatus, TrackView
from services.tracker.core.view import FieldOfView, Views
from services.tracker.memory_file import (
    descriptor_dim,
    load_memory,
    read_classifiers,
    read_last_seen,
    save_memory,
)
from services.tracker.reorder import ClockJumps, InputKey, ReorderBuffer

__all__ = ["TrackerService", "load_memory"]

log = logging.getLogger(__name__)


#: What the tracker calls each of the joiner's drop reasons (``dropped_<name>``).
_DROP_NAMES = {"orphan": "unpaired_embeddings", "late": "late_embeddings", "duplicate": "duplicate",
               "overflow": "join_overflow"}
#: Added to every detection covariance: keeps R invertible for degenerate (zero) ones.
_R_EPS = np.eye(3) * 1e-6


#: The statuses the track query answers for.
_ANSWERED = (TrackStatus.CONFIRMED, TrackStatus.COASTING)


def _completion(no_embeddings: frozenset[str]) -> Callable[[Mapping[str, Any]], bool]:
    def complete(items: Mapping[str, Any]) -> bool:
        """A frame is ready with its embeddings (or their known absence), with no detections,
        or when its stream has no embedder."""
        loc = items["localized"]
        return "embeddings" in items or not loc.detections or loc.header.source in no_embeddings
    return complete


@dataclass
class _Frame:
    loc: LocalizedDetections
    emb: Embeddings | None


class TrackerService(Node):
    """The tracker on a transport: message translation and wiring around the core."""

    name = "tracker"

    def __init__(self, transport: Transport, keys: Keys, config: TrackerConfig, counters: Counters | None = None,
                 clock: Callable[[], float] = time.monotonic, wall_clock: Callable[[], float] = time.time) -> None:
        super().__init__(transport, keys, counters)
        self.config = config
        self.clock = clock
        self.wall_clock = wall_clock
        #: held while the tracker changes: frames in poll(), forget requests from query threads
        self._lock = threading.RLock()
        memory, stored_model = load_memory(config)
        self.model: str | None = config.embedding_model or stored_model
        #: the descriptors' dimension: the remembered ones', else the first accepted model card's
        self._dim = descriptor_dim(memory)
        self._dim_why = "" if self._dim is None else (f"the ID memory in {config.memory_path} holds dimension "
                                                      f"{self._dim} (move the file away if the model changed)")
        th = config.thresholds(self.model) if self.model else None
        self.tracker = config.build_tracker(th, memory)
        if config.memory_path is not None and config.memory_path.exists():
            # the remembered classifiers, for a profile that has them (a bad block costs them, not the memory)
            try:
                self.tracker.load_classifiers(read_classifiers(config.memory_path))
            except ValueError as exc:
                log.warning("%s; starting without remembered classifiers", exc)
        self._have_thresholds = th is not None
        self._card_applied = False
        self._epoch_ns: int | None = None
        self.join: Joiner[LocalizedDetections] = Joiner(
            ("localized", "embeddings"), wait_s=config.join_wait_s, on_timeout="release",
            orphan_s=config.join_wait_s + config.reorder_window_s, buffer=256, max_waiting=256, ordered=True,
            complete=_completion(frozenset(config.no_embeddings)))
        self._score_models = config.score_models()  # by Detections.detector
        #: each camera's newest view, (stamp_ns, view): a coasting track in any recent one is in view
        self._views: dict[str, tuple[int, FieldOfView]] = {}
        self._last_state: dict[int, TrackState] = {}
        self._ever_confirmed: set[int] = set()
        self._state_lock = threading.Lock()
        self._saved_version = memory.version
        self._last_save = clock()
        self._dirty = False
        self._log = RateLimitedLog(log, clock=clock)
        self._clock_jumps = ClockJumps(int(config.clock_jump_s * 1e9))
        self.buffer: ReorderBuffer[_Frame, object, FrameResult] = ReorderBuffer(
            apply=self._update, snapshot=self.tracker.snapshot, restore=self.tracker.restore,
            window_ns=int(config.reorder_window_s * 1e9))
        self.loc_sub = self.io.subscribe(keys.localized(config.camera), LocalizedDetections, RELIABLE)
        self.emb_sub = self.io.subscribe(keys.embeddings(config.camera), Embeddings, RELIABLE)
        self.publisher = self.io.publisher(keys.tracks(), Tracks, RELIABLE)
        self.io.serve(keys.track_query(), self._answer_query)
        self.io.serve(keys.forget_query(), self._answer_forget)
        #: wall-clock time each remembered or tracked ID was last seen (retention_s forgets the others)
        self._seen: dict[int, float] = {}
        if config.memory_path is not None and config.memory_path.exists():
            try:
                self._seen = read_last_seen(config.memory_path)
            except ValueError as exc:
                log.warning("%s; the remembered IDs count as seen now", exc)
        start = wall_clock()
        for track_id in memory.entries:
            self._seen.setdefault(track_id, start)
        self._forgotten: set[int] = set()  # forgotten IDs of tracks still live: the query answers "not found"
        # the fixed output rate (TU Ilmenau): None publishes once per input frame
        self._period = 1.0 / config.output_rate_hz if config.output_rate_hz > 0 else None
        self._next_pub: float | None = None
        self._latest: tuple[_Frame, FrameResult] | None = None
        self._published_key: InputKey | None = None  # once per frame: the newest frame published
        self._offset_ns: int | None = None  # sensor clock - this clock, at the newest frame
        self._last_expiry = -1e18

    def describe(self) -> str:
        return (f"tracking camera {self.config.camera!r} in frame {self.config.frame_id!r}, "
                f"memory {self.config.memory_path or 'off'}")

    # ---------------------------------------------------------------- inputs

    def _refusal(self, card: ModelCard) -> str | None:
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
                self.config.apply_thresholds(self.tracker, th, card.metric)
                self._have_thresholds = True
        return None

    def _drain(self, now: float) -> list[Tracks]:
        """Take what has arrived; returns what a clock jump made publish first."""
        published: list[Tracks] = []
        while (got := self.loc_sub.try_recv()) is not None:
            loc = got.msg
            if loc.header.frame_id and loc.header.frame_id != self.config.frame_id:
                self.counters.drop("wrong_frame")
                self._log.warning("wrong_frame", "dropping localized detections in frame %r; the tracker works in %r",
                                  loc.header.frame_id, self.config.frame_id)
                continue
            self._check_covariances(loc)
            if back_ns := self._clock_jumps.check(loc.header.source, loc.header.stamp_ns):
                published += self._restart_clock(loc.header.source, back_ns, now)
            self._count(self.join.add("localized", loc.header.join_key, loc, now))
        while (got_emb := self.emb_sub.try_recv()) is not None:
            emb = got_emb.msg
            if reason := self._refusal(emb.model):
                self.counters.drop(reason)
                emb = None  # known not to come: its frame need not wait
            key = got_emb.msg.header.join_key
            dropped = self.join.add("embeddings", key, emb, now)
            if emb is not None and any(d.reason == "late" for d in dropped):
                # a frame without detections ran at once (it needs no embeddings): the empty
                # embeddings the embedder sends for it after all are no loss
                late = [] if not len(emb.indices) else self._apply_late(key, emb, now)
                if late is not None:
                    published += late
                    dropped = [d for d in dropped if d.reason != "late"]
            self._count(dropped)
        return published

    def _apply_late(self, key: InputKey, emb: Embeddings, now: float) -> list[Tracks] | None:
        """Embeddings of a frame already tracked by position alone (they came after
        ``join_wait_s``): the frame is applied again with them, and every frame after it
        (a rewind), while it is within ``reorder_window_s``. None when it is not (they
        are then dropped as late, as before)."""
        logged = self.buffer.get(key)
        if logged is None or logged.emb is not None:
            return None
        try:
            results = self.buffer.push(key, _Frame(logged.loc, emb), replace=True)
        except (ValueError, np.linalg.LinAlgError) as exc:
            self.counters.count("update_errors")
            self._log.error("update_error", "frame %s could not be tracked again: %s", key, exc)
            return None
        if not results:
            return None
        self.counters.count("late_embeddings_applied")
        self.counters.count("rewinds")
        return self._after_push(results, now)

    def _check_covariances(self, loc: LocalizedDetections) -> None:
        """Count (and log) detections whose covariance is not symmetric positive definite.

        Non-finite ones never get here: decoding refuses them (the subscription's ``invalid``).
        """
        bad = len(loc.detections) - int(usable_covariances(positions_of(loc)[1] + _R_EPS).sum())
        if bad:
            self.counters.count("bad_covariances", bad)
            self._log.warning("bad_covariance", "%d of %d detections of frame %s carry a covariance that is not "
                              "symmetric positive definite; sigma_r stands for it", bad, len(loc.detections),
                              loc.header.join_key)

    def _restart_clock(self, source: str, back_ns: int, now: float) -> list[Tracks]:
        """Stamps went back by more than ``clock_jump_s``: apply what waits from the old clock,
        end every track (their galleries go to the ID memory) and start over."""
        published = self._apply_ready(now + self.config.join_wait_s)  # the old clock's frames, without waiting
        ended = self.tracker.restart_clock()
        self.buffer.reset()
        self._published_key = None
        self.join.forget_released()  # a looping replay sends the same keys again
        self._epoch_ns = None
        self._views.clear()
        with self._state_lock:
            for track_id in ended:
                if track_id not in self._last_state:
                    continue
                if self._confirmed_before(track_id):
                    self._last_state[track_id] = self._last_state[track_id].model_copy(update={"status": "deleted"})
                else:
                    del self._last_state[track_id]
        self._dirty = True
        self.counters.count("clock_jumps")
        self._log.warning("clock_jump", "stamps of %r went back %.1f s, more than clock_jump_s (%.1f s): a new clock "
                          "(a replay that loops?); ended tracks %s, their IDs are remembered", source, back_ns / 1e9,
                          self.config.clock_jump_s, ended)
        return published

    def _count(self, dropped: list[Dropped]) -> None:
        for d in dropped:
            self.counters.drop(_DROP_NAMES.get(d.reason, d.reason))

    def _ready(self, now: float) -> list[tuple[InputKey, _Frame]]:
        joined, dropped = self.join.poll(now)
        self._count(dropped)
        out = []
        for j in joined:
            if j.timed_out:
                self.counters.count("position_only_timeout")
            out.append((j.key, _Frame(j.anchor, j.get("embeddings"))))
        return out

    # ---------------------------------------------------------------- update
    def _view(self, loc: LocalizedDetections) -> FieldOfView | Views | None:
        """What the cameras could see at this frame: its own camera's view at this frame, and
        with several cameras the union with each other camera's newest view within
        ``view_age_s``. Two detectors' streams of one camera (one ``camera_frame``) are one
        camera: its view at another time is not what it sees now (it may have turned)."""
        view = field_of_view(loc)
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

    def _update(self, frame: _Frame) -> FrameResult:
        loc = frame.loc
        if self._epoch_ns is None:
            self._epoch_ns = loc.header.stamp_ns
        positions, covs = positions_of(loc)
        covs = covs + _R_EPS
        descriptors = None
        if frame.emb is not None and self._have_thresholds:
            descriptors = descriptors_for(loc, frame.emb)
        elif not loc.detections and self._have_thresholds:
            descriptors = np.zeros((0, 1), np.float32)
        elif loc.detections and frame.emb is not None:
            self.counters.count("no_thresholds")
        stamp = (loc.header.stamp_ns - self._epoch_ns) / 1e9
        covs_used = None
        if self.config.uses_detection_covariance:  # unusable ones: the profile's fixed R (counted on arrival)
            covs_used = np.where(usable_covariances(covs)[:, None, None], covs, self.config.covariance_fallback + _R_EPS)
        scores = np.array([d.score for d in loc.detections], np.float64)
        boxes = np.array([d.bbox_xyxy for d in loc.detections], np.float64).reshape(-1, 4)
        aspects = (boxes[:, 3] - boxes[:, 1]) / np.maximum(boxes[:, 2] - boxes[:, 0], 1e-6)  # for posture
        result = self.tracker.update(stamp, positions, descriptors, covs_used, scores, view=self._view(loc),
                                     aspects=aspects, orientations=orientations_for(loc, frame.emb),
                                     score_model=self._score_models.get(loc.detector), camera=loc.camera_frame)
        self._ever_confirmed.update(v.id for v in result.confirmed)
        self.counters.count("updates")
        if not result.appearance_available and loc.detections:
            self.counters.count("position_only_frames")
        if result.recovered_ids:
            self.counters.count("ids_recovered", len(result.recovered_ids))
        wall = self.wall_clock()
        with self._state_lock:
            # the query answers for confirmed and coasting tracks (and the last state of one that
            # ended after being confirmed), never for a tentative one
            for view in result.tracks:
                if view.id and view.status in _ANSWERED and view.id not in self._forgotten:
                    self._last_state[view.id] = track_state(view, result.appearance_available, self._epoch_ns)
                    self._seen[view.id] = wall
            for view in result.deleted:
                if view.id in self._last_state:
                    self._last_state[view.id] = track_state(view, result.appearance_available, self._epoch_ns)
                self._forgotten.discard(view.id)
        self._dirty = True
        return result

    def _confirmed_before(self, track_id: int) -> bool:
        """Whether an earlier track with this ID was ever Confirmed (its ID was recovered)."""
        return track_id in self._ever_confirmed

    def _publish(self, frame: _Frame, result: FrameResult, views: list[TrackView] | None = None,
                 stamp_ns: int | None = None) -> Tracks:
        """Publish ``result``'s output (``views``: predicted to ``stamp_ns`` at the fixed rate).
        The header names the newest input frame (seq, source, ``input_stamp_ns``)."""
        assert self._epoch_ns is not None
        h = frame.loc.header
        header = Header(stamp_ns=h.stamp_ns if stamp_ns is None else max(stamp_ns, h.stamp_ns),
                        frame_id=self.config.frame_id, seq=h.seq, source=h.source)
        reported = self.tracker.reported(result) if views is None else views
        msg = tracks_message(result, reported, header, self.model or "", self._epoch_ns)
        msg.input_stamp_ns = h.stamp_ns
        self.publisher.put(msg)
        self.counters.gauge("tracks_confirmed", len(result.confirmed))
        self.counters.gauge("tracks_live", len(result.tracks))
        self.counters.gauge("ids_remembered", len(self.tracker.memory))
        self.counters.gauge("ids_evicted", self.tracker.memory.evicted)
        return msg

    def poll(self, now: float) -> list[Tracks]:
        """Take what has arrived, apply every frame that is ready; returns the Tracks published."""
        with self._lock:
            published = self._drain(now)
            published += self._apply_ready(now)
            if self._period is not None:
                published += self._tick(now)
            self._expire(now)
            self._persist(now)
        return published

    def _apply_ready(self, now: float) -> list[Tracks]:
        published = []
        for key, frame in self._ready(now):
            old, dup = self.buffer.dropped_old, self.buffer.dropped_duplicate
            try:
                results = self.buffer.push(key, frame)
            except (ValueError, np.linalg.LinAlgError) as exc:
                self.counters.count("update_errors")
                self._log.error("update_error", "frame %s could not be tracked: %s", key, exc)
                continue
            if self.buffer.dropped_old > old:
                self.counters.drop("too_old")
                self._log.warning("too_old", "dropping frame %s: more than %.3f s older than the newest frame (%d so far)",
                                  key, self.config.reorder_window_s, self.buffer.dropped_old)
            if self.buffer.dropped_duplicate > dup:
                self.counters.drop("duplicate")
            if not results:
                continue
            if len(results) > 1:
                self.counters.count("rewinds")
            published += self._after_push(results, now)
        return published

    def _after_push(self, results: list[FrameResult], now: float) -> list[Tracks]:
        """Publish (or keep for the fixed rate) the newest frame's result after a push. Once
        per frame (no fixed rate), a frame is published once: a late frame applied behind the
        newest one changes the state the next frame's output will show, not a second output."""
        newest = self.buffer.latest()
        assert newest is not None
        if self._period is None:
            if newest[0] == self._published_key:
                return []
            self._published_key = newest[0]
            return [self._publish(newest[1], results[-1])]
        self._latest = (newest[1], results[-1])  # published at the fixed rate, predicted to the publish time (_tick)
        self._offset_ns = newest[1].loc.header.stamp_ns - int(now * 1e9)
        return []

    def _tick(self, now: float) -> list[Tracks]:
        """At the fixed output rate: the latest tracks predicted to now in the sensor's clock
        (the newest frame's stamp plus the time since it was applied), whatever arrived."""
        assert self._period is not None
        if self._latest is None or self._offset_ns is None or self._epoch_ns is None:
            return []
        if self._next_pub is None:
            self._next_pub = now
        if now < self._next_pub:
            return []
        self._next_pub += self._period
        if self._next_pub <= now:  # fell behind (a long frame): no burst, the next tick a period on
            self._next_pub = now + self._period
        frame, result = self._latest
        stamp_ns = int(now * 1e9) + self._offset_ns
        dt = max(0.0, (stamp_ns - self._epoch_ns) / 1e9 - result.stamp)
        views = self.tracker.predict_views(self.tracker.reported(result), dt)
        return [self._publish(frame, result, views, stamp_ns)]

    def deadline(self, now: float) -> float | None:
        """Seconds until the earliest pending frame stops waiting for its embeddings, or the
        next fixed-rate output is due."""
        waits = [w for w in (self.join.next_deadline(now),) if w is not None]
        if self._period is not None and self._next_pub is not None and self._latest is not None:
            waits.append(max(0.0, self._next_pub - now))
        return min(waits) if waits else None

    # ------------------------------------------------------------- persistence
    def _persist(self, now: float, force: bool = False) -> None:
        path = self.config.memory_path
        if path is None:
            return
        changed = self.tracker.memory.version != self._saved_version
        periodic = self._dirty and now - self._last_save >= self.config.memory_save_period_s
        if not (changed or periodic or (force and self._dirty)):
            return
        try:
            save_memory(path, self.tracker.memory, self.model or "", extra=self.tracker.live_galleries(),
                        classifiers=self.tracker.kept_classifiers(), last_seen=self._seen)
        except (OSError, ValueError) as exc:
            self.counters.count("memory_save_errors")
            log.error("could not write the ID memory to %s: %s", path, exc)
            return
        self._saved_version = self.tracker.memory.version
        self._last_save, self._dirty = now, False
        self.counters.count("memory_saves")

    # ------------------------------------------------------------- forgetting
    def forget(self, track_id: int | None) -> ForgetReply:
        """Forget one person (``track_id``) or everyone (None): their remembered descriptors
        and classifiers, and the appearance of a live track with that ID (which keeps its
        ID); the ID memory file is rewritten at once. Safe to call from a query thread."""
        with self._lock:
            if track_id is None:
                ids = sorted(set(self.tracker.memory.entries) | self.tracker.live_ids() | set(self._seen))
            else:
                ids = [track_id]
            reply = ForgetReply(header=Header(stamp_ns=time.time_ns(), frame_id=self.config.frame_id, source="tracker"))
            live = self.tracker.live_ids()
            for i in ids:
                known = i in self.tracker.memory or i in live or i in self._seen
                if not known or (i in self._forgotten and i not in self.tracker.memory):
                    continue
                done = self.tracker.forget(i)
                reply.forgotten_ids.append(i)
                reply.descriptors_removed += int(done["descriptors"])
                reply.classifiers_removed += int(bool(done["classifier"]))
                if done["live_track"]:
                    reply.live_tracks_cleared.append(i)
                    self._forgotten.add(i)
                self._unlist(i)
            if track_id is not None and not reply.forgotten_ids:
                reply.error = f"not found: the tracker knows no ID {track_id} (never seen, or already forgotten)"
                return reply
            self.buffer.rebase()  # no rewind may bring the forgotten appearance back
            self.counters.count("ids_forgotten", len(reply.forgotten_ids))
            log.info("forgot IDs %s: %d descriptors, %d classifiers; live tracks kept without appearance: %s",
                     reply.forgotten_ids, reply.descriptors_removed, reply.classifiers_removed,
                     reply.live_tracks_cleared)
            self._dirty = True
            self._saved_version = -1  # rewrite the file now
            self._persist(self.clock(), force=True)
            return reply

    def _unlist(self, track_id: int) -> None:
        """A forgotten ID leaves the last-seen times and the query table."""
        self._seen.pop(track_id, None)
        with self._state_lock:
            self._last_state.pop(track_id, None)

    def _expire(self, now: float) -> None:
        """Forget the remembered IDs not seen for ``retention_s`` (checked about once a minute)."""
        if now - self._last_expiry < 60.0:
            return
        self._last_expiry = now
        limit = self.wall_clock() - self.config.retention_s
        live = self.tracker.live_ids()
        old = [i for i, seen in self._seen.items() if seen < limit and i not in live]
        old += [i for i in self.tracker.memory.entries if i not in self._seen and i not in live]
        for i in sorted(set(old)):
            self.tracker.forget(i)
            self._unlist(i)
        if old:
            self.counters.count("ids_expired", len(set(old)))
            log.info("forgot IDs %s: not seen for %.0f s (retention_s)", sorted(set(old)), self.config.retention_s)
            self.buffer.rebase()
            self._dirty = True

    def _answer_forget(self, _key: str, params: dict[str, str]) -> list[ForgetReply]:
        header = Header(stamp_ns=time.time_ns(), frame_id=self.config.frame_id, source="tracker")
        if params.get("all", "").lower() in ("1", "true", "yes"):
            return [self.forget(None)]
        raw = params.get("id")
        try:
            track_id = int(raw) if raw is not None else None
        except ValueError:
            track_id = None
        if track_id is None or track_id < 1:
            self._log.warning("bad_forget", "forget request with a malformed id %r", raw)
            return [ForgetReply(header=header, error=f"malformed request: need ?id=K (a positive integer) or ?all=1, "
                                                     f"got {_key.split('?')[-1] if '?' in _key else params!r}")]
        return [self.forget(track_id)]

    # ------------------------------------------------------------------ query
    def _answer_query(self, _key: str, params: dict[str, str]) -> list[Tracks]:
        header = Header(stamp_ns=time.time_ns(), frame_id=self.config.frame_id, source="tracker")
        note = ""
        with self._state_lock:
            if "id" not in params:
                states = list(self._last_state.values())
            else:
                try:
                    state = self._last_state.get(int(params["id"]))
                    if state is None:
                        note = (f"not found: no confirmed or coasting track has ID {params['id']} "
                                "(unknown, tentative, or forgotten)")
                except ValueError:
                    self._log.warning("bad_query", "track query with a non-integer id %r", params["id"])
                    state, note = None, f"malformed request: id must be an integer, got {params['id']!r}"
                states = [state] if state is not None else []
        return [Tracks(header=header, tracks=states, embedding_model=self.model or "", note=note)]

    # -------------------------------------------------------------------- end
    def close(self) -> None:
        """Write the ID memory with the live tracks' galleries, then undeclare (call once at shutdown)."""
        try:
            self._persist(self.clock(), force=True)
        finally:
            super().close()
