"""The IDs the tracker service knows: the track query's table (confirmed and coasting tracks, and
the last state of one that ended after being confirmed; never a tentative or a forgotten one),
when each ID was last seen (``retention_s``), forgetting a person, and the ID memory's file
(written when the memory changes, every ``memory_save_period_s`` while tracking, on a forget and at
shutdown).
"""

from __future__ import annotations

import logging
import threading
import time
from typing import Callable

import numpy as np

from common.messages.schemas import ForgetReply, Header, Tracks, TrackState
from common.runtime.ratelog import RateLimitedLog
from common.runtime.service import Counters
from services.tracker.config import TrackerConfig
from services.tracker.convert import track_state
from services.tracker.core import FrameResult, TrackerCore, TrackStatus
from services.tracker.memory_file import read_last_seen, save_memory, shift_recovery

__all__ = ["IdLedger"]

log = logging.getLogger("services.tracker.service")

#: The statuses the track query answers for.
_ANSWERED = (TrackStatus.CONFIRMED, TrackStatus.COASTING)


class IdLedger:
    """The query table, last-seen times, forgetting and persistence around ``tracker``: ``lock`` held
    while the tracker changes, ``rebase()`` makes its state now the only one a rewind may go back to,
    ``model()`` the embedding model's name for the memory file."""

    def __init__(self, config: TrackerConfig, tracker: TrackerCore, counters: Counters, ratelog: RateLimitedLog,
                 lock: threading.RLock, rebase: Callable[[], None], model: Callable[[], str],
                 clock: Callable[[], float], wall_clock: Callable[[], float]) -> None:
        self.config = config
        self.tracker = tracker
        self.counters = counters
        self._log = ratelog
        self._lock = lock
        self._rebase = rebase
        self._model = model
        self.clock = clock
        self.wall_clock = wall_clock
        self._last_state: dict[int, TrackState] = {}
        self._ever_confirmed: set[int] = set()
        self._state_lock = threading.Lock()
        self._saved_version = tracker.memory.version
        self._last_save = clock()
        self._dirty = False
        self._epoch_ns: int | None = None  # the sensors' stamp of the tracker's time 0 (record() says)
        #: wall-clock time each remembered or tracked ID was last seen (retention_s forgets the others)
        self._seen: dict[int, float] = {}
        path = config.memory_path
        if path is not None and path.exists():
            try:
                self._seen = read_last_seen(path)
            except ValueError as exc:
                log.warning("%s; the remembered IDs count as seen now", exc)
        start = wall_clock()
        for track_id in tracker.memory.entries:
            self._seen.setdefault(track_id, start)
        self._forgotten: set[int] = set()  # forgotten IDs of tracks still live: the query answers "not found"
        self._last_expiry = -1e18

    # ------------------------------------------------------------- updates
    def record(self, result: FrameResult, epoch_ns: int) -> None:
        """The tracks of an update: the query's table and the last-seen times."""
        self._ever_confirmed.update(v.id for v in result.confirmed)
        self._epoch_ns = epoch_ns
        wall = self.wall_clock()
        with self._state_lock:
            # the query answers for confirmed and coasting tracks (and the last state of one that
            # ended after being confirmed), never for a tentative one
            for view in result.tracks:
                if view.id and view.status in _ANSWERED and view.id not in self._forgotten:
                    self._last_state[view.id] = track_state(view, result.appearance_available, epoch_ns)
                    self._seen[view.id] = wall
            for view in result.deleted:
                if view.id in self._last_state:
                    self._last_state[view.id] = track_state(view, result.appearance_available, epoch_ns)
                self._forgotten.discard(view.id)
            for old, _ in result.recovery_undone:  # a recovery taken back: that ID is no longer live
                if old in self._last_state:
                    self._last_state[old] = self._last_state[old].model_copy(update={"status": "deleted"})
        self._dirty = True

    def _on_sensor_clock(self, recovery: dict[str, np.ndarray]) -> dict[str, np.ndarray]:
        """The recovery's departures from the tracker's clock (from its first frame) to the
        sensors' (before the first frame they still are on the sensors' clock, from the file)."""
        return recovery if self._epoch_ns is None else shift_recovery(recovery, self._epoch_ns / 1e9)

    def ended(self, track_ids: list[int]) -> None:
        """Tracks ended by a clock jump: shown deleted if they were ever confirmed, else dropped."""
        with self._state_lock:
            for track_id in track_ids:
                if track_id not in self._last_state:
                    continue
                if track_id in self._ever_confirmed:
                    self._last_state[track_id] = self._last_state[track_id].model_copy(update={"status": "deleted"})
                else:
                    del self._last_state[track_id]
        self._dirty = True

    # ---------------------------------------------------------- persistence
    def persist(self, now: float, force: bool = False) -> None:
        path = self.config.memory_path
        if path is None:
            return
        memory = self.tracker.memory
        changed = memory.version != self._saved_version
        periodic = self._dirty and now - self._last_save >= self.config.memory_save_period_s
        if not (changed or periodic or (force and self._dirty)):
            return
        try:
            kept = self.tracker.export_memory()
            save_memory(path, memory, self._model(), extra=kept.live_galleries, classifiers=kept.classifiers,
                        last_seen=self._seen, recovery=self._on_sensor_clock(kept.recovery or {}))
        except (OSError, ValueError) as exc:
            self.counters.count("memory_save_errors")
            log.error("could not write the ID memory to %s: %s", path, exc)
            return
        self._saved_version = memory.version
        self._last_save, self._dirty = now, False
        self.counters.count("memory_saves")

    # ----------------------------------------------------------- forgetting
    def forget(self, track_id: int | None) -> ForgetReply:
        """Forget one person (``track_id``) or everyone (None): their remembered descriptors
        and classifiers, and the appearance of a live track with that ID (which keeps its
        ID); the ID memory file is rewritten at once. Safe to call from a query thread."""
        with self._lock:
            memory, live = self.tracker.memory, self.tracker.live_ids()
            ids = sorted(set(memory.entries) | live | set(self._seen)) if track_id is None else [track_id]
            reply = ForgetReply(header=Header(stamp_ns=time.time_ns(), frame_id=self.config.frame_id, source="tracker"))
            for i in ids:
                known = i in memory or i in live or i in self._seen
                if not known or (i in self._forgotten and i not in memory):
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
            self._rebase()  # no rewind may bring the forgotten appearance back
            self.counters.count("ids_forgotten", len(reply.forgotten_ids))
            log.info("forgot IDs %s: %d descriptors, %d classifiers; live tracks kept without appearance: %s",
                     reply.forgotten_ids, reply.descriptors_removed, reply.classifiers_removed,
                     reply.live_tracks_cleared)
            self._dirty = True
            self._saved_version = -1  # rewrite the file now
            self.persist(self.clock(), force=True)
            return reply

    def _unlist(self, track_id: int) -> None:
        """A forgotten ID leaves the last-seen times and the query table."""
        self._seen.pop(track_id, None)
        with self._state_lock:
            self._last_state.pop(track_id, None)

    def expire(self, now: float) -> None:
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
            self._rebase()
            self._dirty = True

    # -------------------------------------------------------------- queries
    def answer_forget(self, _key: str, params: dict[str, str]) -> list[ForgetReply]:
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

    def answer_query(self, _key: str, params: dict[str, str]) -> list[Tracks]:
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
        return [Tracks(header=header, tracks=states, embedding_model=self._model(), note=note)]
