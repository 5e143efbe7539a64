"""TrackerService: LocalizedDetections + Embeddings in, Tracks out, over any Transport
(services/tracker/README.md, *Inputs and outputs*). It wires four parts around the core
(:class:`~services.tracker.core.TrackerCore`):

* **Intake** (:mod:`services.tracker.intake`): inputs joined per source frame, checked and
  converted once; a frame whose embeddings come after ``join_wait_s`` runs position-only, and is
  applied again with them while within ``reorder_window_s`` (a rewind: ``late_embeddings_applied``).
* **Order**: a :class:`ReorderBuffer` applies frames in sensor-time order, rewinding for late ones.
* **Pacing** (:mod:`services.tracker.pacing`): the output once per frame or at a fixed rate.
* **The ID ledger** (:mod:`services.tracker.ledger`): the track query, forgetting, retention and
  the ID memory's file.

Bad inputs are counted, logged at most once a second per reason, and survived; stamps that jump
back by more than ``clock_jump_s`` end every track (their IDs stay remembered), and tracking starts
over on the new clock.
"""

from __future__ import annotations

import logging
import threading
import time
from typing import Callable

import numpy as np

from common.geometry.messages import obstacles_from_map
from common.geometry.occupancy import ObstacleMap
from common.messages.keys import MAPS, RELIABLE, Keys
from common.messages.schemas import Embeddings, ForgetReply, Header, IdDecisions, LocalizedDetections, StaticMap, Tracks
from common.runtime.node import Node
from common.runtime.ratelog import RateLimitedLog
from common.runtime.service import Counters
from common.transport.base import Transport
from services.tracker.config import AppearanceConfig, TrackerConfig
from services.tracker.convert import id_decisions_message, tracks_message
from services.tracker.core import FrameResult, TrackReport
from services.tracker.core.types import KeptMemory
from services.tracker.core.view import FieldOfView, Views
from services.tracker.intake import Frame, Intake
from services.tracker.memory_file import descriptor_dim, load_memory, read_classifiers, read_recovery, shift_recovery
from services.tracker.pacing import Pacing
from services.tracker.ledger import IdLedger
from services.tracker.reorder import InputKey, ReorderBuffer

__all__ = ["TrackerService", "load_memory"]

log = logging.getLogger(__name__)


class TrackerService(Node):
    """The tracker on a transport: message translation and wiring around the core."""

    name = "tracker"

    def __init__(self, transport: Transport, keys: Keys, config: TrackerConfig, counters: Counters | None = None,
                 clock: Callable[[], float] = time.monotonic, wall_clock: Callable[[], float] = time.time) -> None:
        super().__init__(transport, keys, counters)
        self.config = config
        self.clock = clock
        #: held while the tracker changes: frames in poll(), forget requests from query threads
        self._lock = threading.RLock()
        memory, stored_model = load_memory(config)
        model = config.embedding_model or stored_model
        #: the descriptors' dimension: the remembered ones', else the first accepted model card's
        dim = descriptor_dim(memory)
        dim_why = "" if dim is None else (f"the ID memory in {config.memory_path} holds dimension {dim} "
                                          "(move the file away if the model changed)")
        self.tracker = config.build_tracker(config.thresholds(model) if model else None, memory)
        self._recovery_file: dict[str, np.ndarray] = {}  # the file's recovery state, until the first frame
        if config.memory_path is not None and config.memory_path.exists():
            # the remembered classifiers, for a profile that has them (a bad block costs them, not the memory)
            try:
                self.tracker.import_memory(KeptMemory(classifiers=read_classifiers(config.memory_path)))
            except ValueError as exc:
                log.warning("%s; starting without remembered classifiers", exc)
            try:  # where and when each person was last seen, who with whom (the open-set recovery)
                recovery = read_recovery(config.memory_path)
                self.tracker.import_memory(KeptMemory(recovery=recovery))  # checked now, on its clock at the first frame
                self._recovery_file = recovery
            except ValueError as exc:
                log.warning("%s: %s; starting without the recovery's state", config.memory_path, exc)
        self._log = RateLimitedLog(log, clock=clock)
        self.intake = Intake(config, self.counters, self._log, model, dim, dim_why, self._thresholds)
        self._epoch_ns: int | None = None
        self._decisions_logged: dict[tuple[float, float, float, bool], str] = {}  # the last ones, by when and where
        self.buffer: ReorderBuffer[Frame, object, FrameResult] = ReorderBuffer(
            apply=self._update, snapshot=self.tracker.snapshot, restore=self.tracker.restore,
            window_ns=int(config.reorder_window_s * 1e9))
        self.pacing: Pacing[Frame] = Pacing(config.output_rate_hz)
        self.ledger = IdLedger(config, self.tracker, self.counters, self._log, self._lock, self.buffer.rebase,
                                   lambda: self.model or "", clock, wall_clock)
        sm = config.robust.static_map
        self.map_sub = self.io.subscribe(keys.static_map(), StaticMap, MAPS) if sm.path is None and sm.topic else None
        self._map_seen: tuple[object, ...] | None = None
        self._obstacles: ObstacleMap | None = None  # the static_map stream's, once one came
        self.loc_sub = self.io.subscribe(keys.localized(config.camera), LocalizedDetections, RELIABLE)
        self.emb_sub = self.io.subscribe(keys.embeddings(config.camera), Embeddings, RELIABLE)
        self.laser_subs = [] if config.camera == "*" or config.profile != "robust" else [  # the thesis: one camera
            self.io.subscribe(keys.localized(laser), LocalizedDetections, RELIABLE)
            for laser in dict.fromkeys(config.lasers) if laser != config.camera]
        self.publisher = self.io.publisher(keys.tracks(), Tracks, RELIABLE)
        self.decisions_pub = self.io.publisher(keys.id_decisions(), IdDecisions, RELIABLE)
        self.io.serve(keys.track_query(), self.ledger.answer_query)
        self.io.serve(keys.forget_query(), self._answer_forget)

    @property
    def wall_clock(self) -> Callable[[], float]:
        """The wall clock of the last-seen times (retention)."""
        return self.ledger.wall_clock

    @wall_clock.setter
    def wall_clock(self, clock: Callable[[], float]) -> None:
        self.ledger.wall_clock = clock

    @property
    def model(self) -> str | None:
        """The embedding model tracked (None: none seen yet)."""
        return self.intake.model

    def describe(self) -> str:
        sm = self.config.robust.static_map
        where = (", the static map from the static_map stream (the ros2 node's /map)" if self.map_sub is not None
                 else "") if sm.path is None else (
            f", static map {sm.path} (no birth within {sm.birth_clearance_m:g} m of its obstacles)"
            if self.config.profile == "robust" else f", static map {sm.path} unused (the thesis profile has none)")
        lasers = f" and laser{'s' * (len(self.laser_subs) > 1)} " + ", ".join(
            repr(s.key.rsplit("/", 1)[-1]) for s in self.laser_subs) if self.laser_subs else ""
        return (f"tracking camera {self.config.camera!r}{lasers} in frame {self.config.frame_id!r}, "
                f"memory {self.config.memory_path or 'off'}{where}")

    def _thresholds(self, thresholds: AppearanceConfig, metric: str | None) -> None:
        self.config.apply_thresholds(self.tracker, thresholds, metric)

    def _view(self, loc: LocalizedDetections) -> FieldOfView | Views | None:
        return self.intake.view(loc)

    # ---------------------------------------------------------------- inputs
    def _take_map(self) -> None:
        """The newest map on ``static_map`` (the ros2 node re-sends it): used when it changed and is
        in the tracking frame, its obstacles then keep tracks from being born on them."""
        grid = None
        while (got := self.map_sub.try_recv()) is not None:  # type: ignore[union-attr]
            grid = got.msg
        if grid is None or grid.content() == self._map_seen:
            return
        self._map_seen = grid.content()
        if grid.header.frame_id != self.config.frame_id:
            self.counters.count("static_map_wrong_frame")
            self._log.warning("static_map_frame", "the static map is in frame %r, the tracking frame is %r: not used "
                              "(publish the map in the tracking frame, or set frame_id)", grid.header.frame_id,
                              self.config.frame_id)
            return
        self._obstacles = obstacles_from_map(grid, self.config.robust.static_map.min_obstacle_m)  # with every frame
        self.counters.count("static_maps")
        log.info("static map from %s: %d x %d cells of %g m; no track is born on its obstacles", grid.header.source,
                 grid.width, grid.height, grid.resolution)

    def _drain(self, now: float) -> list[Tracks]:
        """Take what has arrived; returns what a clock jump made publish first."""
        published: list[Tracks] = []
        if self.map_sub is not None:
            self._take_map()
        for sub in (self.loc_sub, *self.laser_subs):
            while (got := sub.try_recv()) is not None:
                arrival, back_ns = self.intake.localized(got.msg)
                if arrival is None:
                    continue
                if back_ns:
                    published += self._restart_clock(arrival.loc.header.source, back_ns, now)
                self.intake.count(self.intake.join.add("localized", arrival.loc.header.join_key, arrival, now))
        while (got_emb := self.emb_sub.try_recv()) is not None:
            emb, dropped = self.intake.embeddings(got_emb.msg, now)
            if emb is not None and any(d.reason == "late" for d in dropped):
                # a frame without detections ran at once (it needs no embeddings): the empty
                # embeddings the embedder sends for it after all are no loss
                late = [] if not len(emb.indices) else self._apply_late(emb.header.join_key, emb, now)
                if late is not None:
                    published += late
                    dropped = [d for d in dropped if d.reason != "late"]
            self.intake.count(dropped)
        return published

    def _apply_late(self, key: InputKey, emb: Embeddings, now: float) -> list[Tracks] | None:
        """Embeddings that came after ``join_wait_s``: their frame, tracked by position alone, is
        applied again with them (a rewind) while within ``reorder_window_s``; None when it is not."""
        logged = self.buffer.get(key)
        if logged is None or logged.with_embeddings:
            return None
        try:
            frame = self.intake.convert(logged.arrival, emb, logged.input.view)
            results = self.buffer.push(key, frame, replace=True)
        except (ValueError, np.linalg.LinAlgError) as exc:
            self.counters.count("update_errors")
            self._log.error("update_error", "frame %s could not be tracked again: %s", key, exc)
            return None
        if not results:
            return None
        self.counters.count("late_embeddings_applied")
        self.counters.count("rewinds")
        return self._after_push(key, frame, results, now)

    def _restart_clock(self, source: str, back_ns: int, now: float) -> list[Tracks]:
        """Stamps went back by more than ``clock_jump_s``: apply what waits from the old clock,
        end every track (their galleries go to the ID memory) and start over."""
        published = self._apply_ready(now + self.config.join_wait_s)  # the old clock's frames, without waiting
        ended = self.tracker.restart_clock()
        self.buffer.reset()
        self.pacing.restart()
        self.intake.restart()
        self._epoch_ns = None
        self.ledger.ended(ended)
        self.counters.count("clock_jumps")
        self._log.warning("clock_jump", "stamps of %r went back %.1f s, more than clock_jump_s (%.1f s): a new clock "
                          "(a replay that loops?); ended tracks %s, their IDs are remembered", source, back_ns / 1e9,
                          self.config.clock_jump_s, ended)
        return published

    # ---------------------------------------------------------------- update
    def _update(self, frame: Frame) -> FrameResult:
        stamp_ns = frame.loc.header.stamp_ns
        if self._epoch_ns is None:
            self._epoch_ns = stamp_ns
            if self._recovery_file:  # the file's departures, from the sensors' clock to the tracker's
                self.tracker.import_memory(KeptMemory(recovery=shift_recovery(self._recovery_file, -stamp_ns / 1e9)))
                self._recovery_file = {}
        given = frame.input if self._obstacles is None else frame.input._replace(obstacles=self._obstacles)
        result = self.tracker.step((stamp_ns - self._epoch_ns) / 1e9, given)
        self.counters.count("updates")
        if not result.appearance_available and frame.loc.detections:
            self.counters.count("position_only_frames")
        if result.recovered_ids:
            self.counters.count("ids_recovered", len(result.recovered_ids))
        if result.recovery_undone:  # a recovery taken back (robust profile's ID memory)
            self.counters.count("ids_recovery_undone", len(result.recovery_undone))
        if result.births_blocked:  # confident detections on the static map's obstacles: no track born
            self.counters.count("births_on_obstacles", result.births_blocked)
        self._report_decisions(result, frame.loc.header)
        self.ledger.record(result, self._epoch_ns)
        return result

    def _report_decisions(self, result: FrameResult, header: Header) -> None:
        """Why a new person got their ID: one log line each (rare events), and the frame's decisions
        on ``keys.id_decisions()``. A rewind applies frames again: a decision made again the same
        is not reported twice, a different one is (logged as revised)."""
        fresh = []
        for d in result.id_decisions:
            key, text = (d.stamp, round(d.x, 2), round(d.y, 2), d.outcome == "undone"), d.summary()
            before = self._decisions_logged.get(key)
            if before != text:
                log.info("ID decision%s: %s", "" if before is None else " (revised by late inputs)", text)
                fresh.append(d)
            self._decisions_logged[key] = text
            while len(self._decisions_logged) > 256:  # far more than a reorder window holds
                del self._decisions_logged[next(iter(self._decisions_logged))]
        if fresh:
            in_frame = header.model_copy(update={"frame_id": self.config.frame_id})
            self.decisions_pub.put(id_decisions_message(fresh, in_frame))

    def _publish(self, frame: Frame, result: FrameResult, reports: list[TrackReport] | None = None,
                 stamp_ns: int | None = None) -> Tracks:
        """Publish ``result``'s output (``reports``: predicted to ``stamp_ns`` at the fixed rate).
        The header names the newest input frame (seq, source, ``input_stamp_ns``)."""
        assert self._epoch_ns is not None
        h = frame.loc.header
        header = Header(stamp_ns=h.stamp_ns if stamp_ns is None else max(stamp_ns, h.stamp_ns),
                        frame_id=self.config.frame_id, seq=h.seq, source=h.source)
        reported = self.tracker.reported(result) if reports is None else reports
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
            published += self._tick(now)
            self.ledger.expire(now)
            self.ledger.persist(now)
        return published

    def _apply_ready(self, now: float) -> list[Tracks]:
        published = []
        for key, frame in self.intake.ready(now):
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
            published += self._after_push(key, frame, results, now)
        return published

    def _after_push(self, key: InputKey, frame: Frame, results: list[FrameResult], now: float) -> list[Tracks]:
        """Publish (or keep for the fixed rate) the newest result after the push of ``frame``: as that
        frame's output when it is of the newest instant (another stream's frame of that stamp, a slow
        detector's, may have been applied first), else as the newest frame's (:class:`Pacing`)."""
        newest = self.buffer.latest()
        assert newest is not None
        if key[0] < newest[0][0]:
            key, frame = newest
        due = self.pacing.pushed(key, frame, frame.loc.header.stamp_ns, results[-1], now)
        return [] if due is None else [self._publish(*due)]

    def _tick(self, now: float) -> list[Tracks]:
        """At the fixed output rate: the latest tracks predicted to now in the sensor's clock."""
        due = self.pacing.tick(now) if self._epoch_ns is not None else None
        if due is None:
            return []
        frame, result, stamp_ns = due
        assert self._epoch_ns is not None
        dt = max(0.0, (stamp_ns - self._epoch_ns) / 1e9 - result.stamp)
        reports = self.tracker.predict_reports(self.tracker.reported(result), dt)
        return [self._publish(frame, result, reports, stamp_ns)]

    def deadline(self, now: float) -> float | None:
        """Seconds until the earliest pending frame stops waiting for its embeddings, or the
        next fixed-rate output is due."""
        waits = [w for w in (self.intake.join.next_deadline(now), self.pacing.deadline(now)) if w is not None]
        return min(waits) if waits else None

    # ------------------------------------------------------------- forgetting
    def forget(self, track_id: int | None) -> ForgetReply:
        """Forget one person (``track_id``) or everyone (None) (:meth:`IdLedger.forget`)."""
        return self.ledger.forget(track_id)

    def _answer_forget(self, key: str, params: dict[str, str]) -> list[ForgetReply]:
        return self.ledger.answer_forget(key, params)

    # -------------------------------------------------------------------- end
    def close(self) -> None:
        """Write the ID memory with the live tracks' galleries, then undeclare (call once at shutdown)."""
        try:
            self.ledger.persist(self.clock(), force=True)
        finally:
            super().close()
