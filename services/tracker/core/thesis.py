"""The multi-person tracker of Pinto's thesis (III-C to III-E): Kalman filters, Algorithm 1, the
Tentative/Confirmed/Deleted life cycle and Algorithm 2 over an ID memory (services/tracker/README.md,
*The thesis profile*). Only Confirmed tracks are its output (:attr:`FrameResult.confirmed`).

Time step (``ThesisParams.time_step``): ``"frame"`` is the thesis exactly (``dt = 1`` per call,
``Q = diag(sigma_q**2)``, gaps ignored); ``"time"`` (default) takes ``dt`` from the stamps and
scales ``Q`` by the nominal frames elapsed, ``dt / frame_period_s``, as a random walk's variance
grows linearly with time: a step over three dropped frames adds the uncertainty of three steps. A
missed update adds ``max(1, round(dt / frame_period_s))`` misses, so ``max_misses`` keeps meaning
frames of the nominal stream without an association (5 = 167 ms at 30 Hz) whether frames came
empty or never arrived; confirmation counts associated updates, each of them real evidence.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from services.tracker.core import kalman
from services.tracker.core.association import (
    AppearanceGate,
    appearance_cost,
    chi2_gate,
    gate_appearance,
    gate_position,
    innovation_distance,
    match,
    spatial_distance,
)
from services.tracker.core.cues import usable_covariances
from services.tracker.core.gallery import Gallery
from services.tracker.core.id_decisions import nearest
from services.tracker.core.identity import IdentityMemory
from services.tracker.core.protocol import TrackerCore
from services.tracker.core.thesis_params import ThesisParams
from services.tracker.core.types import AppearanceModel, FrameInput, FrameResult, IdDecision, KeptMemory, TrackStatus
from services.tracker.core.types import TrackReport

__all__ = ["FrameResult", "ThesisTrack", "TrackStatus", "TrackReport", "ThesisTracker", "ThesisParams", "ThesisState"]


@dataclass
class ThesisTrack:
    """One track; ``mean`` (6,) and ``cov`` (6, 6) are the Kalman state."""

    id: int
    mean: np.ndarray
    cov: np.ndarray
    gallery: Gallery | None
    first_stamp: float
    last_update: float
    status: TrackStatus = TrackStatus.TENTATIVE
    hits: int = 1  # consecutive associated frames (the creating detection is the first)
    misses: int = 0  # nominal frames since the last association
    total_hits: int = 1
    ever_confirmed: bool = False
    decision: IdDecision | None = None  # why Algorithm 2 gave its ID, told when it is confirmed

    def copy(self) -> ThesisTrack:
        return replace(self, mean=self.mean.copy(), cov=self.cov.copy(),
                       gallery=self.gallery.copy() if self.gallery else None)


@dataclass
class ThesisState:
    """A snapshot for rewinding (see :meth:`ThesisTracker.snapshot`)."""

    tracks: list[ThesisTrack]
    memory: IdentityMemory
    pending: list[tuple[int, Gallery]]
    last_stamp: float | None


class ThesisTracker(TrackerCore[ThesisState]):
    """The thesis's tracker. ``params.gate`` None means there are no appearance thresholds:
    every frame is then associated position-only."""

    def __init__(self, params: ThesisParams, memory: IdentityMemory | None = None) -> None:
        self.params = params
        self.memory = memory if memory is not None else IdentityMemory(params.memory_size)
        self.tracks: list[ThesisTrack] = []
        self.last_stamp: float | None = None
        self._pending: list[tuple[int, Gallery]] = []  # galleries of tracks deleted in position-only frames
        self._forgotten: set[int] = set()  # IDs of live tracks whose person was forgotten
        self._r = np.diag(np.asarray(params.sigma_r, dtype=np.float64) ** 2)
        self._position_gate = chi2_gate(params.position_gate_probability, 2)

    # ----------------------------------------------------------------- helpers
    def _step(self, stamp: float) -> tuple[float, float, int]:
        """(dt for the motion model, Q scale, nominal frames elapsed) for this frame."""
        if self.last_stamp is None:
            return 0.0, 0.0, 1
        if stamp < self.last_stamp:
            raise ValueError(f"stamp {stamp} is older than the last update {self.last_stamp}; apply frames in order")
        if self.params.time_step == "frame":
            return 1.0, 1.0, 1
        dt = stamp - self.last_stamp
        frames = dt / self.params.frame_period_s
        return dt, frames, max(1, int(round(frames)))

    def live_ids(self) -> set[int]:
        return {t.id for t in self.tracks}

    def set_appearance(self, model: AppearanceModel | None) -> None:
        """Algorithm 1's and 2's thresholds from the embedding model's (e.g. once it is known);
        None: position-only. The thesis compares Euclidean distances whatever the metric."""
        if model is None:
            self.params = replace(self.params, gate=None, t_recover=0.0)
            return
        s_max = self.params.s_max if model.s_max is None else model.s_max
        gate = AppearanceGate(model.t_lower, model.t_upper, s_max, self.params.inf)
        self.params = replace(self.params, gate=gate, t_recover=model.t_recover)

    # ------------------------------------------------------------------ update
    def step(self, stamp: float, frame: FrameInput) -> FrameResult:
        """Process one frame (``stamp`` in seconds): its positions, descriptors and each detection's
        usable covariance as ``R`` (an unusable one: the fixed ``R``); the rest is the robust profile's."""
        positions, descriptors = frame.positions, frame.descriptors
        appearance = descriptors is not None and self.params.gate is not None
        used = descriptors if appearance else None  # descriptors without thresholds are ignored
        measurement_cov = frame.measurement_cov
        if measurement_cov is not None:  # an unusable covariance: the fixed R
            usable = usable_covariances(measurement_cov) if frame.cov_usable is None else frame.cov_usable
            if not usable.all():
                measurement_cov = np.where(usable[:, None, None], measurement_cov, self._r)
        dt, q_scale, frames = self._step(stamp)
        self.last_stamp = stamp
        if appearance:
            self._flush_pending()

        means, covs = self._predict(dt, q_scale)
        matches, unmatched_d, unmatched_t = self._associate(positions, used, means, covs)
        result = FrameResult(stamp=stamp, appearance_available=appearance, matches=len(matches))
        has_desc = _with_descriptor(used, len(positions))
        self._update_matched(matches, means, covs, positions, used, has_desc, measurement_cov, stamp)
        result.deleted = self._age_missed(unmatched_t, frames, appearance, stamp)
        result.new_ids, result.recovered_ids = self._birth(unmatched_d, positions, used, has_desc, stamp)
        result.tracks = [_view(t, stamp) for t in self.tracks]
        told = [t for t in self.tracks if t.decision is not None and t.status is TrackStatus.CONFIRMED]
        for t in told:  # an ID becomes visible with its track's confirmation: so does why it was given
            result.id_decisions.append(t.decision)  # type: ignore[arg-type]
            t.decision = None
        return result

    def _predict(self, dt: float, q_scale: float) -> tuple[np.ndarray, np.ndarray]:
        """Move every track to this frame; returns the means (T, 6) and covariances (T, 6, 6)."""
        if self.tracks and q_scale > 0:
            means, covs = self._states()
            means, covs = kalman.predict(means, covs, dt, kalman.process_noise(self.params.sigma_q, q_scale))
            for t, m, c in zip(self.tracks, means, covs):
                t.mean, t.cov = m, c
        return self._states()

    def _states(self) -> tuple[np.ndarray, np.ndarray]:
        """Every track's mean (T, 6) and covariance (T, 6, 6), stacked."""
        if not self.tracks:
            return np.zeros((0, 6)), np.zeros((0, 6, 6))
        return np.stack([t.mean for t in self.tracks]), np.stack([t.cov for t in self.tracks])

    def _associate(self, positions: np.ndarray, descriptors: np.ndarray | None, means: np.ndarray,
                   covs: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Algorithm 1 with ``descriptors``, else position-only: (matches (K, 2) of (detection,
        track)), unmatched detections, unmatched tracks)."""
        if descriptors is not None:
            cost = self._appearance_cost(positions, descriptors, means, covs)
        else:
            distance = innovation_distance(positions, means, covs, self._r)
            cost = gate_position(distance, self._position_gate, self.params.inf)
        return match(cost, self.params.inf)

    def _appearance_cost(self, positions: np.ndarray, descriptors: np.ndarray, means: np.ndarray,
                         covs: np.ndarray) -> np.ndarray:
        """Appearance distances to the track galleries, gated by the (x, y) Mahalanobis distance."""
        gate = self.params.gate
        assert gate is not None
        empty = Gallery(max(1, descriptors.shape[1]), 1)
        galleries = [t.gallery if t.gallery is not None else empty for t in self.tracks]
        cost = appearance_cost(descriptors, galleries)
        spatial = spatial_distance(positions[:, :2], means[:, :2], covs[:, :2, :2])
        return gate_appearance(cost, spatial, gate)

    def _update_matched(self, matches: np.ndarray, means: np.ndarray, covs: np.ndarray, positions: np.ndarray,
                        descriptors: np.ndarray | None, has_desc: np.ndarray, measurement_cov: np.ndarray | None,
                        stamp: float) -> None:
        """Kalman-update the matched tracks at once; add their detections' descriptors."""
        if not len(matches):
            return
        d_idx, t_idx = matches[:, 0], matches[:, 1]
        r = measurement_cov[d_idx] if measurement_cov is not None else self._r
        new_means, new_covs = kalman.update(means[t_idx], covs[t_idx], positions[d_idx], r)
        for k, (d, ti) in enumerate(matches.tolist()):
            self._hit(self.tracks[ti], new_means[k], new_covs[k], stamp)
            if has_desc[d]:
                self._add_descriptor(self.tracks[ti], descriptors[d])  # type: ignore[index]

    def _age_missed(self, unmatched_t: np.ndarray, frames: int, appearance: bool, stamp: float) -> list[TrackReport]:
        """Count a miss for every unmatched track; delete (and archive) those at ``max_misses``.

        Returns the deleted tracks.
        """
        deleted: list[TrackReport] = []
        deleted_idx = set()
        for ti in unmatched_t.tolist():
            t = self.tracks[ti]
            self._miss(t, frames)
            if t.status is TrackStatus.DELETED:
                deleted_idx.add(ti)
                deleted.append(_view(t, stamp))
                self._archive(t, appearance)
        if deleted_idx:
            self.tracks = [t for i, t in enumerate(self.tracks) if i not in deleted_idx]
        return deleted

    def _miss(self, t: ThesisTrack, frames: int) -> None:
        t.hits = 0
        t.misses += frames
        t.status = TrackStatus.TENTATIVE
        if t.misses >= self.params.max_misses:
            t.status = TrackStatus.DELETED

    def _archive(self, t: ThesisTrack, appearance: bool) -> None:
        """Give a deleted track's gallery to the ID memory (held back in position-only frames)."""
        if t.id in self._forgotten:
            return
        if t.gallery is not None and len(t.gallery):
            if appearance:
                self.memory.archive(t.id, t.gallery.descriptors)
            else:
                self._pending.append((t.id, t.gallery))

    def _birth(self, unmatched_d: np.ndarray, positions: np.ndarray, descriptors: np.ndarray | None,
               has_desc: np.ndarray, stamp: float) -> tuple[list[int], list[int]]:
        """A new track per unmatched detection, its ID from Algorithm 2; returns (new IDs, recovered IDs)."""
        new_ids: list[int] = []
        recovered_ids: list[int] = []
        for d in unmatched_d.tolist():
            desc = descriptors[d] if has_desc[d] else None  # type: ignore[index]
            track_id, recovered = self._new_track(positions[d], desc, stamp)
            new_ids.append(track_id)
            if recovered:
                recovered_ids.append(track_id)
        return new_ids, recovered_ids

    def _new_track(self, position: np.ndarray, desc: np.ndarray | None, stamp: float) -> tuple[int, bool]:
        p = self.params
        exclude = self.live_ids() | {i for i, _ in self._pending}
        track_id, recovered, ids, dist = self.memory.assign_weighed(desc, exclude, p.t_recover)
        mean, cov = kalman.initiate(position, np.asarray(p.sigma0))
        t = ThesisTrack(track_id, mean, cov, None, stamp, stamp)
        if len(ids):  # Algorithm 2 weighed remembered people: why, reported once the track is confirmed
            t.decision = nearest(stamp, float(mean[0]), float(mean[1]), track_id, recovered, ids, dist, p.t_recover,
                                 p.gate)
        if p.n_init <= 1:
            t.status, t.ever_confirmed = TrackStatus.CONFIRMED, True
        if desc is not None:
            self._add_descriptor(t, desc)
        self.tracks.append(t)
        return track_id, recovered

    def _hit(self, t: ThesisTrack, mean: np.ndarray, cov: np.ndarray, stamp: float) -> None:
        t.mean, t.cov = mean, cov
        t.hits += 1
        t.total_hits += 1
        t.misses = 0
        t.last_update = stamp
        if t.status is TrackStatus.TENTATIVE and t.hits >= self.params.n_init:
            t.status, t.ever_confirmed = TrackStatus.CONFIRMED, True

    def _add_descriptor(self, t: ThesisTrack, desc: np.ndarray) -> None:
        if t.id in self._forgotten:
            return
        if t.gallery is None:
            t.gallery = Gallery(len(desc), self.params.gallery_size)
        t.gallery.add(desc)

    def _flush_pending(self) -> None:
        for track_id, gallery in self._pending:
            self.memory.archive(track_id, gallery.descriptors)
        self._pending.clear()

    # ---------------------------------------------------------------- snapshots
    def snapshot(self) -> ThesisState:
        """The whole state, for :meth:`restore`; galleries are shared copy-on-write."""
        return ThesisState([t.copy() for t in self.tracks], self.memory.copy(),
                            [(i, g.copy()) for i, g in self._pending], self.last_stamp)

    def restore(self, state: ThesisState) -> None:
        """Go back to ``state`` (which stays valid for another restore)."""
        self.tracks = [t.copy() for t in state.tracks]
        self.memory = state.memory.copy()
        self._pending = [(i, g.copy()) for i, g in state.pending]
        self.last_stamp = state.last_stamp

    def forget(self, track_id: int) -> dict[str, int | bool]:
        """:meth:`TrackerCore.forget`: the remembered and pending descriptors, a live track's gallery."""
        removed = self.memory.forget(track_id)
        removed += sum(len(g) for i, g in self._pending if i == track_id)
        self._pending = [(i, g) for i, g in self._pending if i != track_id]
        live = False
        for t in self.tracks:
            if t.id == track_id:
                removed += len(t.gallery) if t.gallery is not None else 0
                t.gallery, live = None, True
                self._forgotten.add(track_id)
        return {"descriptors": removed, "classifier": False, "live_track": live}

    def predict_reports(self, reports: list[TrackReport], dt: float) -> list[TrackReport]:
        """:meth:`TrackerCore.predict_reports` by the thesis's motion model."""
        if not reports or dt <= 0:
            return list(reports)
        scale = dt / self.params.frame_period_s  # Q per nominal frame; the step in frames or seconds
        step = scale if self.params.time_step == "frame" else dt
        means, covs = kalman.predict(np.stack([v.mean for v in reports]), np.stack([v.cov for v in reports]), step,
                                     kalman.process_noise(self.params.sigma_q, scale))
        return [replace(v, mean=m, cov=c) for v, m, c in zip(reports, means, covs)]

    def restart_clock(self) -> list[int]:
        """:meth:`TrackerCore.restart_clock`: each track's gallery goes to the memory."""
        ended = [t.id for t in self.tracks]
        for t in self.tracks:
            if t.gallery is not None and len(t.gallery):
                self.memory.archive(t.id, t.gallery.descriptors)
        self._flush_pending()
        self.tracks = []
        self.last_stamp = None
        return ended

    def reported(self, result: FrameResult) -> list[TrackReport]:
        """The tracker's output for ``result``: the Confirmed tracks (as in the thesis)."""
        return result.confirmed

    def export_memory(self) -> KeptMemory:
        """The galleries of every live track and every pending archive; the thesis keeps no
        classifiers and no recovery state."""
        out = [(t.id, t.gallery.descriptors) for t in self.tracks if t.gallery is not None and len(t.gallery)]
        return KeptMemory(out + [(i, g.descriptors) for i, g in self._pending], {}, {})

    def import_memory(self, kept: KeptMemory) -> None:
        """Nothing to take: Pinto's Algorithm 2 reads the remembered galleries alone (the memory)."""
        return None


def _view(t: ThesisTrack, stamp: float) -> TrackReport:
    return TrackReport(t.id, t.status, t.mean.copy(), t.cov.copy(), t.total_hits, t.misses,
                     max(0.0, stamp - t.first_stamp), t.last_update, len(t.gallery) if t.gallery else 0,
                     t.ever_confirmed)


def _with_descriptor(descriptors: np.ndarray | None, n: int) -> np.ndarray:
    """(N,) bool: which detections carry a usable (finite) descriptor."""
    if descriptors is not None and descriptors.shape[1]:
        return np.all(np.isfinite(descriptors), axis=1)
    return np.zeros(n, bool)
