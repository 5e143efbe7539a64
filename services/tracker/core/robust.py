"""The ``robust`` tracker profile: the thesis's tracker rebuilt from four papers' ideas (Pinto's
thesis, the TU Ilmenau framework, Basso/Munaro's RGB-D tracker, Ban et al.'s robotic head), in
time (seconds), not nominal frames, so the same settings hold at 5, 10 or 30 Hz.

One :meth:`RobustTracker.step` per frame: predict, score every (detection, track) pair by the
cues' summed log-odds, match in stages, update, learn, then the life cycle
(services/tracker/README.md, *How it works*, explains each step). Its parts: ``robust_params``
(the settings), ``cues`` (each cue's log-odds, the measurement covariance), ``lifecycle`` and
``tracks`` (the tracks as rows of arrays, their galleries in one array); this module runs them in
order. Nothing of a frame stays but the state. Pure numpy and scipy; no I/O.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from services.tracker.core.cues import classifier as clf
from services.tracker.core import cues, is_person, kalman, lifecycle
from services.tracker.core.cues import Cue, Pairing
from services.tracker.core.cues.classifier import trained
from services.tracker.core.association import match_log_odds
from services.tracker.core.identity import IdentityMemory
from services.tracker.core.protocol import TrackerCore
from services.tracker.core.robust_params import RobustParams
from services.tracker.core.bank import GalleryBank
from services.tracker.core.reports import TrackRow, track_report, track_reports, track_rows
from services.tracker.core.tracks import RobustTrackerState, TrackTable
from services.tracker.core.types import AppearanceModel, FrameInput, FrameResult, KeptMemory, ScoreModel, TrackStatus
from services.tracker.core.types import TrackReport
from services.tracker.core.view import View

__all__ = ["AppearanceModel", "RobustParams", "RobustTracker", "RobustTrackerState", "ScoreModel"]


class RobustTracker(TrackerCore[RobustTrackerState]):
    """The robust profile (:class:`~services.tracker.core.protocol.TrackerCore`)."""

    def __init__(self, params: RobustParams, memory: IdentityMemory | None = None) -> None:
        self.params = params
        self._set_cues()
        columns = {c.name: cols for c in self.cues if (cols := c.columns()) is not None}
        self.state = RobustTrackerState(TrackTable.empty(6, columns),
                                        GalleryBank(params.gallery_size),
                                        memory if memory is not None else IdentityMemory(params.memory_size))
        self._r = np.diag(np.asarray(params.sigma_r, float) ** 2)
        self._p0 = np.diag([params.sigma0_position ** 2] * 3 + [params.sigma0_velocity ** 2] * 2 + [0.0])
        self.bad_covariances = 0  #: detections whose covariance was unusable
        self._q_of: dict[float, np.ndarray] = {}  # process noise by step: a stream's steps take a few values
        self._r_n: dict[int, np.ndarray] = {}  # the fixed R broadcast to n detections
        self._taus: dict[str, float] = {}  # IsPerson's time constant of the detectors that have their own

    def _set_cues(self) -> None:
        """The cues of the settings, and which of them use each hook (a hook a cue leaves as
        :class:`Cue`'s is not called)."""
        self.cues = cues.build(self.params)
        self._predicting = [c for c in self.cues if type(c).predict is not Cue.predict]
        self._scoring = [c for c in self.cues if type(c).log_odds is not Cue.log_odds]
        self._learning = [c for c in self.cues if type(c).learn is not Cue.learn]
        self._born = [c for c in self.cues if type(c).born is not Cue.born]

    # ------------------------------------------------------------ the state
    @property
    def memory(self) -> IdentityMemory:
        return self.state.memory

    @property
    def classifiers(self) -> dict[int, np.ndarray]:
        """The trained classifiers of remembered (deleted) people, by ID."""
        return self.state.classifiers

    @property
    def tracks(self) -> list[TrackRow]:
        """Every live track, tentative ones included (a picture, for inspection)."""
        return track_rows(self.state.tracks, self.state.bank)

    def live_ids(self) -> set[int]:
        return self.state.live_ids()

    def set_appearance(self, model: AppearanceModel | None) -> None:
        """Set the embedding model's calibration (e.g. once its model card is known)."""
        self.params = replace(self.params, appearance=model)
        self._set_cues()

    def _q(self, dt: float) -> np.ndarray:
        q = self._q_of.get(dt)
        if q is None:
            if len(self._q_of) >= 64:  # a clock with jitter: keep the latest steps only
                self._q_of.clear()
            q = self._q_of[dt] = kalman.white_acceleration(dt, self.params.q_accel, self.params.q_z)
        return q

    # ------------------------------------------------------------------ update
    def step(self, stamp: float, frame: FrameInput) -> FrameResult:
        """Process one frame (``stamp`` in seconds; :class:`FrameInput` says what each of its parts is
        for). Without ``frame.aspects`` posture is not estimated: z need not be a height then."""
        state = self.state
        if state.last_stamp is None and state.recovery.departures:
            state.recovery.settle(stamp)  # departures from the memory's file, or of the clock before
        if not len(frame.positions) and not len(state.tracks) and (state.last_stamp is None
                                                                   or stamp >= state.last_stamp):
            state.last_stamp = stamp  # nothing to track, nothing to predict
            return FrameResult(stamp, self._appearance(frame))
        pairing = self._pairing(stamp, frame)
        pairing.moved = self._predict(stamp)  # new state arrays: the reports of the last frame keep theirs
        previous, state.last_stamp = state.last_stamp, stamp
        matches = self._associate(self._log_odds(pairing), pairing.confident)
        rows = np.array(matches, np.int64).T if matches else np.zeros((2, 0), np.int64)  # (detections, tracks)
        self._update_matched(pairing, rows)
        for cue in self._learning:  # galleries, classifiers, statures, postures, where each was seen
            cue.learn(pairing, state, rows)
        result = FrameResult(stamp=stamp, appearance_available=pairing.descriptors is not None)
        self._age(stamp, result, frame.view, previous, frame.camera)
        self._births(pairing, set(rows[0].tolist()), result)
        self._remove(lifecycle.confirm(state, self.params, result))
        lifecycle.probation(state, self.params, stamp, result)  # recent recoveries checked again
        result.matches = len(matches)
        result.tracks = track_reports(state, stamp, frame.view is not None)
        return result

    def _appearance(self, frame: FrameInput) -> bool:
        """Whether ``frame``'s descriptors can be compared (there are some, and a calibration)."""
        d = frame.descriptors
        return d is not None and self.params.appearance is not None and d.shape[1] > 0

    def _pairing(self, stamp: float, frame: FrameInput) -> Pairing:
        """The frame's evidence as the cues read it (ValueError: a stamp older than the last
        frame's, descriptors of another size than the galleries')."""
        state, n = self.state, len(frame.positions)
        if state.last_stamp is not None and stamp < state.last_stamp:
            raise ValueError(f"stamp {stamp} is older than the last update {state.last_stamp}; apply frames in order")
        appearance, descriptors = self._appearance(frame), frame.descriptors
        has_desc = np.isfinite(descriptors).all(axis=1) if appearance else np.zeros(n, bool)  # type: ignore[union-attr]
        any_desc = appearance and bool(has_desc.any())
        if any_desc:
            state.bank.check_dim(descriptors.shape[1])  # type: ignore[union-attr]
        scores = np.zeros(n) if frame.scores is None else frame.scores
        if frame.measurement_cov is None:  # the fixed R for every detection, one array per frame size
            r, bad = self._r_n.get(n), 0
            if r is None:
                r = self._r_n[n] = cues.measurement_covariance(None, None, self._r, n)[0]
        else:
            r, bad = cues.measurement_covariance(frame.measurement_cov, frame.cov_usable, self._r, n)
        self.bad_covariances += bad
        score_model = self.params.scores if frame.score_model is None else frame.score_model
        if score_model.is_person_tau_s is not None:
            self._taus[frame.detector] = score_model.is_person_tau_s
        return Pairing(stamp, frame, frame.positions, r, descriptors if appearance else None, has_desc,
                       clf.normalise(descriptors[has_desc]) if any_desc else None,  # type: ignore[index]
                       score_model.probability(scores), score_model.confident(scores))

    def _predict(self, stamp: float) -> bool:
        """Move every track to ``stamp``; whether their state is in new arrays."""
        t = self.state.tracks
        if not len(t) or self.state.last_stamp is None:
            return False
        dt = stamp - self.state.last_stamp
        if dt <= 0:
            return False
        t.mean, t.cov = kalman.predict(t.mean, t.cov, dt, self._q(dt))
        is_person.fade(t, dt, self.params.is_person_tau_s, self._taus)  # IsPerson drifts back to "unknown"
        for cue in self._predicting:  # posture and orientation drift
            cue.predict(self.state, dt)
        return True

    def _log_odds(self, pairing: Pairing) -> np.ndarray:
        """(N, T) the cues' log-odds added, in the cues' order, that detection d is track t
        (``-inf`` outside the position cue's gate)."""
        n, nt = len(pairing.positions), len(self.state.tracks)
        if n == 0 or nt == 0:
            return np.zeros((n, nt))
        total: np.ndarray | None = None
        for cue in self._scoring:
            lo = cue.log_odds(pairing, self.state)
            if lo is not None:
                total = lo if total is None else total + lo
        return np.where(pairing.gated, total, -np.inf)  # type: ignore[arg-type]

    def _associate(self, log_odds: np.ndarray, confident: np.ndarray) -> list[tuple[int, int]]:
        """Stages: confident detections x established tracks, low-score detections x the
        established tracks left, remaining confident detections x tentative tracks."""
        if not log_odds.size:
            return []
        birth, established = _split([s is TrackStatus.TENTATIVE for s in self.state.tracks.status])
        high, low = _split(confident.tolist())
        matches = match_log_odds(log_odds, high, established)
        taken_d, taken_t = {d for d, _ in matches}, {j for _, j in matches}
        matches += match_log_odds(log_odds, low, [j for j in established if j not in taken_t])
        matches += match_log_odds(log_odds, [d for d in high if d not in taken_d], birth)
        return matches

    def _update_matched(self, pairing: Pairing, rows: np.ndarray) -> None:
        """The Kalman update of the matched tracks (each detection's own R) and their
        bookkeeping: seen now, by this camera, one hit more, IsPerson (the TU Ilmenau
        framework's binary Bayes filter over the detections' confidences)."""
        if not rows.shape[1]:
            return
        t = self.state.tracks
        d_idx, t_idx = rows
        new_means, new_covs = kalman.update(t.mean[t_idx], t.cov[t_idx], pairing.positions[d_idx], pairing.r[d_idx])
        if not pairing.moved:  # a report of the last frame keeps its arrays
            t.mean, t.cov = t.mean.copy(), t.cov.copy()
        t.mean[t_idx], t.cov[t_idx] = new_means, new_covs
        sure, stamp, camera = pairing.confident.tolist(), pairing.stamp, pairing.frame.camera
        last, unseen, cams, hits = t.last_update, t.unseen_s, t.camera, t.total_hits
        status, confident_hits = t.status, t.confident_hits
        coasting, confirmed = TrackStatus.COASTING, TrackStatus.CONFIRMED
        pairs = list(zip(*rows.tolist()))
        for d, j in pairs:
            last[j], unseen[j], cams[j] = stamp, 0.0, camera
            hits[j] += 1
            confident_hits[j] += sure[d]
            if status[j] is coasting:
                status[j] = confirmed
        is_person.update(t, pairs, pairing.p_det.tolist(), pairing.frame.detector, self._cap(pairing.frame))

    def _births(self, pairing: Pairing, matched: set[int], result: FrameResult) -> None:
        """A tentative track for each confident detection nobody explains (Ban et al.'s birth
        candidates), none on the static map's obstacles (a wall end, a door jamb)."""
        p = self.params
        free = [d for d, c in enumerate(pairing.confident.tolist()) if c and d not in matched]
        obstacles = pairing.frame.obstacles if pairing.frame.obstacles is not None else p.obstacles
        if obstacles is not None and free:
            on = obstacles.blocked(pairing.positions[free, :2], p.birth_clearance_m).tolist()
            result.births_blocked, free = sum(on), [d for d, b in zip(free, on) if not b]
        born = lifecycle.births(free, matched, pairing.positions, pairing.p_det, p.birth_separation_m)
        lifecycle.birth(self.state, pairing, born, self._born, self._p0, self._cap(pairing.frame))

    def _cap(self, frame: FrameInput) -> float:
        """The most IsPerson belief ``frame``'s detector can give (core/is_person.py)."""
        return (self.params.scores if frame.score_model is None else frame.score_model).max_is_person

    def _age(self, stamp: float, result: FrameResult, view: View | None, previous: float | None,
             camera: str = "") -> None:
        """Coasting and deletion (:func:`lifecycle.age`); a deleted track's appearance is archived."""
        ended, keep = lifecycle.age(self.state, self.params, stamp, previous, view, camera)
        for j in ended:
            result.deleted.append(track_report(self.state, j, stamp, TrackStatus.DELETED, None))
            lifecycle.archive(self.state, j, view, self.params.recovery.exit_horizon_s)
        self._remove({j for j, k in enumerate(keep) if not k})

    def _remove(self, rows: set[int]) -> None:
        """Drop the tracks ``rows``, freeing their galleries."""
        if not rows:
            return
        t = self.state.tracks
        for j in rows:
            if t.slot[j] >= 0:
                self.state.bank.release(t.slot[j])
        t.drop(rows)

    def forget(self, track_id: int) -> dict[str, int | bool]:
        """:meth:`TrackerCore.forget`: the descriptors, the classifier and the recovery's state of the
        person go, and what each cue learnt of a live track's (they get a new ID when they come back)."""
        state, t = self.state, self.state.tracks
        removed = state.memory.forget(track_id)
        had_classifier = state.classifiers.pop(track_id, None) is not None
        state.recovery.forget(drop=track_id)
        rows = [j for j, i in enumerate(t.id) if i == track_id]
        for j in rows:
            removed += state.bank.size(t.slot[j])
            if t.slot[j] >= 0:
                state.bank.release(t.slot[j])
            had_classifier = had_classifier or trained(t, j) is not None
            for cols in t.extra.values():  # what each cue learnt of the person
                cols.clear(j)
            t.slot[j], t.forgotten[j] = -1, True
        return {"descriptors": removed, "classifier": had_classifier, "live_track": bool(rows)}

    def predict_reports(self, reports: list[TrackReport], dt: float) -> list[TrackReport]:
        """:meth:`TrackerCore.predict_reports` by the constant-velocity model."""
        if not reports or dt <= 0:
            return list(reports)
        means, covs = kalman.predict(np.stack([v.mean for v in reports]), np.stack([v.cov for v in reports]), dt,
                                     self._q(dt))
        return [replace(v, mean=m, cov=c) for v, m, c in zip(reports, means, covs)]

    def restart_clock(self) -> list[int]:
        """:meth:`TrackerCore.restart_clock`; tentative tracks have no ID and are dropped."""
        t = self.state.tracks
        ended = [j for j, i in enumerate(t.id) if i]
        for j in ended:
            lifecycle.archive(self.state, j)
        ids = [t.id[j] for j in ended]
        self._remove(set(range(len(t))))
        self.state.last_stamp = None
        self.state.recovery.departures.clear()  # their stamps are of the old clock
        return ids

    def reported(self, result: FrameResult) -> list[TrackReport]:
        """What to output: confirmed tracks, and coasting ones missed for at most
        ``report_coast_s`` unless known to be out of the camera's view."""
        limit = self.params.report_coast_s
        return [v for v in result.tracks if v.status is TrackStatus.CONFIRMED or
                (v.status is TrackStatus.COASTING and result.stamp - v.last_update <= limit and v.in_view is not False)]

    # ---------------------------------------------------------------- snapshots
    def snapshot(self) -> RobustTrackerState:
        return self.state.copy()

    def restore(self, state: RobustTrackerState) -> None:
        self.state = state.copy()

    def export_memory(self) -> KeptMemory:
        """The live tracks' galleries, the classifiers (the remembered people's and the live tracks')
        and the recovery's state (:func:`lifecycle.kept_recovery`)."""
        t, bank = self.state.tracks, self.state.bank
        live = {i: w for j, i in enumerate(t.id) if i and (w := trained(t, j)) is not None}
        return KeptMemory([(i, bank.descriptors(t.slot[j])) for j, i in enumerate(t.id) if i and bank.size(t.slot[j])],
                          {**self.classifiers, **live}, lifecycle.kept_recovery(self.state))

    def import_memory(self, kept: KeptMemory) -> None:
        """The remembered people's classifiers and the recovery's state (:func:`lifecycle.load_recovery`)."""
        if kept.classifiers is not None:
            self.state.classifiers = dict(kept.classifiers)
        if kept.recovery is not None:
            lifecycle.load_recovery(self.state, kept.recovery)


def _split(flags: list[bool]) -> tuple[list[int], list[int]]:
    """The indices where ``flags`` hold, and the others."""
    yes = [k for k, f in enumerate(flags) if f]
    no = [k for k, f in enumerate(flags) if not f]
    return yes, no
