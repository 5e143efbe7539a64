"""The ``robust`` tracker profile: the thesis's tracker rebuilt from four papers' ideas.

One call of :meth:`RobustTracker.update` processes one frame, in time (seconds), not in
nominal frames, so the same settings hold at 5, 10 or 30 Hz. The papers are Pinto's thesis,
the TU Ilmenau framework, Basso/Munaro's RGB-D tracker and Ban et al.'s robotic head.

1. **Predict** every track with a constant-velocity model whose process noise is white
   acceleration (``q_accel``, m^2/s^3) on (x, y) and a random walk on z; or, with
   ``motion="ukf"``, Basso/Munaro's unscented filter with a coordinated-turn model (a person
   walks arcs of constant turn rate, :mod:`services.tracker.core.ukf`).
2. **Score every (detection, track) pair** by the TU Ilmenau framework's cue fusion: each
   cue gives a probability that the pair is the same person, 0.5 meaning "no information",
   and the cues combine by the Bayesian product (Eq 1), i.e. their log-odds add:

   * *position*: the log-likelihood ratio of the detection under the track's predicted
     Gaussian (innovation covariance ``S = HPH^T + R``) against a uniform density
     ``new_density`` (people per m^2) of someone else or clutter. A track that has coasted
     long has a wide ``S`` and scores lower everywhere (TU Ilmenau's |Sigma_h| penalty);
   * *appearance*: the descriptor distance to the track's gallery through a Fermi
     function placed by the embedding model's calibrated thresholds (0.9 at ``t_lower``,
     0.1 at ``t_upper``). No descriptor, or a track without one yet, gives 0.5, so a
     track born while the embedder was down gains appearance later without an ID switch;
   * *confidence*: the detector's score as P(true person).

   A detection may also be explained as **clutter or a new person** (Ban et al.'s clutter
   class), at log-odds 0: a pair is only accepted when its combined log-odds are positive.
3. **Associate in stages** (ByteTrack's second stage, Basso/Munaro's confirmation):
   confident detections with the confirmed and coasting tracks (Hungarian on the
   log-odds), then low-score detections with the confirmed tracks still free (they may
   keep a track alive, never start one), then the remaining confident detections with
   the tentative tracks.
4. **Update** the matched tracks with each detection's own covariance when it has one
   (the localizer's, which grows with distance^2 as in Basso/Munaro's tracker), else ``sigma_r``.
5. **Life cycle, in time.** A confident detection nobody explains starts a *tentative*
   track: a birth candidate (Ban et al.: unexplained detections that move like one
   person over several frames). It is confirmed after ``n_init`` confident hits if its
   IsPerson probability reaches ``confirm_is_person``, and dropped when it goes
   ``tentative_timeout_s`` without one. A confirmed track that misses is *coasting*: it
   keeps its prediction, is reported for ``report_coast_s`` (with its status, so a
   consumer can tell), and is deleted after ``max_coast_s`` without a detection or when
   its position variance passes ``max_position_var``.
6. **IsPerson** (TU Ilmenau): each track's probability of being a person, a binary Bayes
   filter over its detections' confidences that fades back to 0.5 with ``is_person_tau_s``.
7. **Identity memory** (Algorithm 2): a tentative track takes its ID when confirmed. If it
   has appearance and a remembered (deleted) person's gallery is nearer than the model's
   ``t_recover``, it takes that person's ID back; otherwise a new one. A deleted track's
   gallery goes to the memory.

Pure numpy and scipy; no I/O.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, replace
from typing import Literal

import numpy as np
from scipy.optimize import linear_sum_assignment

from services.tracker.core import classifier as clf
from services.tracker.core import kalman, ukf
from services.tracker.core.classifier import ClassifierParams
from services.tracker.core.gallery import Gallery
from services.tracker.core import posture as pose
from services.tracker.core.identity import IdentityMemory
from services.tracker.core.posture import PostureParams
from services.tracker.core.protocol import TrackerCore
from services.tracker.core.types import AppearanceModel, FrameInput, FrameResult, ScoreModel, TrackStatus, TrackView
from services.tracker.core.view import FieldOfView, Views

__all__ = ["AppearanceModel", "RobustParams", "RobustTracker", "RobustTrackerState", "ScoreModel"]

_F3 = tuple[float, float, float]
_LOG_2PI = math.log(2.0 * math.pi)


@dataclass(frozen=True)
class RobustParams:
    """The robust profile's settings (README of the tracker: what each one does)."""

    #: "cv": constant-velocity Kalman filter; "ukf": unscented filter, coordinated turn (Basso/Munaro)
    motion: Literal["cv", "ukf"] = "cv"
    q_accel: float = 3.0  # m^2/s^3, white acceleration on x and y
    q_turn: float = 0.01  # rad^2/s^3, random walk of the turn rate ("ukf")
    sigma0_turn: float = 0.5  # rad/s, a new track's turn-rate std ("ukf")
    q_z: float = 0.05  # m^2/s, random walk of z
    sigma0_position: float = 0.3  # m, a new track's position std
    sigma0_velocity: float = 2.0  # m/s, a new track's velocity std (people walk at ~1.4 m/s; the frame may move)
    sigma_r: _F3 = (0.2, 0.2, 0.3)  # m, measurement std when a detection has no covariance
    new_density: float = 0.02  # people (or clutter) per m^2 that compete with a track's prediction
    gate_sq: float = 13.8  # squared Mahalanobis bound on (x, y): chi2(0.999, 2)
    appearance_weight: float = 1.0
    appearance: AppearanceModel | None = None
    scores: ScoreModel = field(default_factory=ScoreModel)
    n_init: int = 3
    confirm_is_person: float = 0.75
    is_person_tau_s: float = 2.0
    tentative_timeout_s: float = 0.25
    report_coast_s: float = 0.3
    view_margin: float = 0.1  # image border (share of its size) where a coasting person counts as out of view
    max_coast_s: float = 2.0
    max_position_var: float = 4.0  # m^2, trace of the (x, y) covariance
    #: the same two limits for a track coasting out of every camera's view (it cannot be
    #: detected there, so a miss says nothing about it: a person walking from one camera's
    #: view into another's through a blind stretch); no view known: the limits above
    max_coast_unseen_s: float = 2.0
    max_position_var_unseen: float = 4.0
    #: hand-over by motion: a track confirmed within this squared Mahalanobis distance (x, y)
    #: of a track coasting out of view takes that track's ID (the person came back into a
    #: view elsewhere); None: off
    handover_gate_sq: float | None = None
    #: two people's centres are never closer than this on the ground (m): a detection this near
    #: one that went to a track, or to a stronger birth, is a second report of that person (a
    #: split depth cluster, a double box), not a new track; 0: off
    birth_separation_m: float = 0.3
    gallery_size: int = 100
    memory_size: int = 500
    #: Basso/Munaro's online per-track appearance classifiers; None: off
    classifier: ClassifierParams | None = field(default_factory=ClassifierParams)
    #: TU Ilmenau's posture and orientation filters; None: off
    posture: PostureParams | None = field(default_factory=PostureParams)

    def __post_init__(self) -> None:
        if self.n_init < 1:
            raise ValueError("n_init must be at least 1")
        if self.motion not in ("cv", "ukf"):
            raise ValueError(f"motion must be 'cv' or 'ukf', got {self.motion!r}")
        if not (self.q_turn >= 0 and self.sigma0_turn >= 0):
            raise ValueError("q_turn and sigma0_turn must not be negative")
        for name in ("q_accel", "q_z", "sigma0_position", "sigma0_velocity", "new_density", "gate_sq",
                     "is_person_tau_s", "max_position_var"):
            if not getattr(self, name) > 0:
                raise ValueError(f"{name} must be positive, got {getattr(self, name)}")
        if not (0 < self.tentative_timeout_s and 0 <= self.report_coast_s <= self.max_coast_s):
            raise ValueError("need tentative_timeout_s > 0 and 0 <= report_coast_s <= max_coast_s")
        if not (self.max_coast_unseen_s > 0 and self.max_position_var_unseen > 0):
            raise ValueError("max_coast_unseen_s and max_position_var_unseen must be positive")
        if self.handover_gate_sq is not None and not self.handover_gate_sq > 0:
            raise ValueError(f"handover_gate_sq must be positive or None, got {self.handover_gate_sq}")
        if not 0 <= self.view_margin < 0.5:
            raise ValueError(f"view_margin must be in [0, 0.5), got {self.view_margin}")
        if not self.birth_separation_m >= 0:
            raise ValueError(f"birth_separation_m must not be negative, got {self.birth_separation_m}")
        if not 0.5 <= self.confirm_is_person < 1:
            raise ValueError("confirm_is_person must be in [0.5, 1)")


@dataclass
class _Track:
    id: int  # 0 while tentative: the ID is given at confirmation
    mean: np.ndarray
    cov: np.ndarray
    gallery: Gallery | None
    first_stamp: float
    last_update: float
    status: TrackStatus = TrackStatus.TENTATIVE
    confident_hits: int = 1
    total_hits: int = 1
    is_person: float = 0.5  # probability
    ever_confirmed: bool = False
    clf: np.ndarray | None = None  # online classifier weights (D + 1), once trained
    clf_steps: int = 0
    forgotten: bool = False  # its person was forgotten: it learns and leaves no appearance
    in_view: bool | None = None  # coasting: inside some camera's view at the last frame (None: not known)
    unseen_s: float = 0.0  # of this coast, the time spent out of every view
    camera: str = ""  # the camera of its last detection
    posture: np.ndarray = field(default_factory=lambda: pose.uniform(3))
    orientation: np.ndarray = field(default_factory=lambda: pose.uniform(pose.ORIENTATION_BINS))

    def copy(self) -> _Track:
        return replace(self, mean=self.mean.copy(), cov=self.cov.copy(),
                       gallery=self.gallery.copy() if self.gallery is not None else None)


@dataclass
class RobustTrackerState:
    tracks: list[_Track]
    memory: IdentityMemory
    last_stamp: float | None
    classifiers: dict[int, np.ndarray] = field(default_factory=dict)


def _logit(p: np.ndarray | float) -> np.ndarray:
    p = np.clip(p, 1e-6, 1 - 1e-6)
    return np.log(p / (1.0 - p))


class RobustTracker(TrackerCore):
    """The robust profile (:class:`~services.tracker.core.protocol.TrackerCore`)."""

    def __init__(self, params: RobustParams, memory: IdentityMemory | None = None) -> None:
        self.params = params
        self.memory = memory if memory is not None else IdentityMemory(params.memory_size)
        self.tracks: list[_Track] = []
        self.last_stamp: float | None = None
        self._r = np.diag(np.asarray(params.sigma_r, float) ** 2)
        self._p0 = np.diag([params.sigma0_position ** 2] * 3 + [params.sigma0_velocity ** 2] * 2 + [0.0])
        self._ukf = params.motion == "ukf"
        if self._ukf:
            self._p0 = ukf.initiate(np.zeros(3), params.sigma0_position, params.sigma0_velocity, params.sigma0_turn)[1]
        #: detections whose covariance was unusable (NaN, asymmetric, not positive definite)
        self.bad_covariances = 0
        #: the trained classifiers of remembered (deleted) people, by ID
        self.classifiers: dict[int, np.ndarray] = {}
        self._d2: dict[tuple[int, int], np.ndarray] = {}  # this frame's pair distances to galleries
        self._q_dt, self._q_last = -1.0, np.zeros((6, 6))  # the last step's process noise
        self._r_cache: dict[int, np.ndarray] = {}
        self._pose_dt, self._pose_m = -1.0, (np.eye(3), np.eye(pose.ORIENTATION_BINS))  # drift matrices of the last dt

    # ------------------------------------------------------------------ helpers
    def set_appearance(self, model: AppearanceModel | None) -> None:
        """Set the embedding model's calibration (e.g. once its model card is known)."""
        self.params = replace(self.params, appearance=model)

    def _q(self, dt: float) -> np.ndarray:
        if dt == self._q_dt:
            return self._q_last
        q = np.zeros((6, 6))
        a = self.params.q_accel
        for i in (0, 1):
            q[i, i] = a * dt ** 3 / 3.0
            q[i, i + 3] = q[i + 3, i] = a * dt ** 2 / 2.0
            q[i + 3, i + 3] = a * dt
        q[2, 2] = self.params.q_z * dt
        self._q_dt, self._q_last = dt, q
        return q

    def live_ids(self) -> set[int]:
        return {t.id for t in self.tracks if t.id}

    # ------------------------------------------------------------------ update
    def step(self, stamp: float, frame: FrameInput) -> FrameResult:
        """Process one frame (see :class:`FrameInput`): ``stamp`` in seconds. A coasting track
        out of ``frame.view`` is kept but not reported; without ``frame.aspects`` posture is not
        estimated (the positions' z need not be a height above the floor either);
        ``frame.orientations`` are used while the person is too slow for the walking direction
        to tell; ``frame.score_model`` (None: ``params.scores``) reads this frame's detector's
        scores, when several detectors feed the tracker; ``frame.camera``: a hand-over by motion
        (``handover_gate_sq``) joins a track last seen by one camera to a new track born in
        another's view only."""
        p = self.params
        positions, descriptors = frame.positions, frame.descriptors
        aspects, orientations, view, camera = frame.aspects, frame.orientations, frame.view, frame.camera
        n = len(positions)
        if n == 0 and not self.tracks and (self.last_stamp is None or stamp >= self.last_stamp):
            self.last_stamp = stamp  # nothing to track, nothing to predict
            return FrameResult(stamp=stamp, appearance_available=frame.has_descriptors and p.appearance is not None)
        if self.last_stamp is not None and stamp < self.last_stamp:
            raise ValueError(f"stamp {stamp} is older than the last update {self.last_stamp}; apply frames in order")
        scores = np.zeros(n) if frame.scores is None else frame.scores
        r = self._measurement_cov(frame.measurement_cov, frame.cov_usable, n)
        self._predict(stamp)
        previous, self.last_stamp = self.last_stamp, stamp
        appearance = descriptors is not None and p.appearance is not None and descriptors.shape[1] > 0
        has_desc = np.all(np.isfinite(descriptors), axis=1) if appearance else np.zeros(n, bool)  # type: ignore[arg-type]
        score_model = p.scores if frame.score_model is None else frame.score_model
        p_det = score_model.probability(scores)
        confident = score_model.confident(scores)
        self._d2: dict[tuple[int, int], np.ndarray] = {}
        log_odds = self._pair_log_odds(positions, r, descriptors if appearance else None, has_desc, p_det)
        result = FrameResult(stamp=stamp, appearance_available=appearance)
        matches = self._associate(log_odds, confident)
        self._update_matched(matches, positions, r, descriptors, has_desc, p_det, confident, stamp, camera)
        self._update_pose(matches, positions, aspects, orientations)
        self._train_classifiers(matches, descriptors, has_desc, confident)
        matched_d = {d for d, _ in matches}
        self._age(stamp, result, appearance, view, previous)
        self._birth(self._births([d for d in range(n) if d not in matched_d and confident[d]], matched_d, positions,
                                 p_det), positions, descriptors, has_desc, p_det, stamp, camera)
        self._confirm(result)
        result.matches = len(matches)
        result.tracks = [self._view(t, stamp) for t in self.tracks]
        if view is not None:
            for k, t in enumerate(self.tracks):
                if t.status is TrackStatus.COASTING:
                    result.tracks[k] = replace(result.tracks[k], in_view=t.in_view)
        return result

    def _measurement_cov(self, cov: np.ndarray | None, good: np.ndarray | None, n: int) -> np.ndarray:
        """Each detection's R: its own covariance when usable (``good``), else ``sigma_r``. A
        covariance that is not finite, not symmetric or not positive definite is replaced (and
        counted in ``bad_covariances``)."""
        if cov is None or good is None:
            r = self._r_cache.get(n)
            if r is None:
                r = self._r_cache[n] = np.broadcast_to(self._r, (n, 3, 3))
            return r
        sym = 0.5 * (cov + np.swapaxes(cov, 1, 2))
        # Basso/Munaro's sigma^2 = sigma_v^2 + sigma_d^2: a fixed part (here the body's extent
        # around the point the sensor saw) plus the sensor's own, which grows with distance^2
        out = np.where(good[:, None, None], sym + self._r, self._r)
        self.bad_covariances += int(n - good.sum())
        return out

    def _predict(self, stamp: float) -> None:
        if not self.tracks or self.last_stamp is None:
            return
        dt = stamp - self.last_stamp
        if dt <= 0:
            return
        means = np.array([t.mean for t in self.tracks])
        covs = np.array([t.cov for t in self.tracks])
        if self._ukf:
            means, covs = ukf.predict(means, covs, dt, self.params.q_accel, self.params.q_z, self.params.q_turn)
        else:
            means, covs = kalman.predict(means, covs, dt, self._q(dt))
        fade = math.exp(-dt / self.params.is_person_tau_s)  # IsPerson drifts back to "unknown"
        for t, m, c in zip(self.tracks, means, covs):
            t.mean, t.cov = m, c
            t.is_person = 0.5 + (t.is_person - 0.5) * fade
        pp = self.params.posture
        if pp is not None:  # every track's posture and orientation drift in two products
            step = round(dt, 3)  # to the millisecond: the matrices are rebuilt only when the rate changes
            if step != self._pose_dt:
                self._pose_dt = step
                self._pose_m = (pose.transition(3, step, pp.posture_tau_s),
                                pose.transition(pose.ORIENTATION_BINS, step, pp.orientation_tau_s, circular=True))
            postures = np.array([t.posture for t in self.tracks]) @ self._pose_m[0]
            orientations = np.array([t.orientation for t in self.tracks]) @ self._pose_m[1]
            for t, p_, o_ in zip(self.tracks, postures, orientations):
                t.posture, t.orientation = p_, o_

    def _pair_log_odds(self, positions: np.ndarray, r: np.ndarray, descriptors: np.ndarray | None,
                       has_desc: np.ndarray, p_det: np.ndarray) -> np.ndarray:
        """(N, T) combined log-odds that detection d is track t; ``-inf`` outside the gate."""
        p = self.params
        n, nt = len(positions), len(self.tracks)
        if n == 0 or nt == 0:
            return np.zeros((n, nt))
        means = np.array([t.mean[:2] for t in self.tracks])  # (T, 2)
        covs = np.array([t.cov[:2, :2] for t in self.tracks])  # (T, 2, 2)
        s = covs[None, :, :, :] + r[:, None, :2, :2]  # (N, T, 2, 2)
        diff = positions[:, None, :2] - means[None, :, :]  # (N, T, 2)
        a, b, c = s[..., 0, 0], s[..., 0, 1], s[..., 1, 1]
        det = a * c - b * b
        dx, dy = diff[..., 0], diff[..., 1]
        d2 = (c * dx * dx - 2 * b * dx * dy + a * dy * dy) / det
        log_n = -0.5 * d2 - _LOG_2PI - 0.5 * np.log(det)
        total = log_n - math.log(p.new_density)
        gated = d2 <= p.gate_sq
        if descriptors is not None and has_desc.any() and p.appearance is not None:
            total = total + p.appearance_weight * self._appearance_log_odds(descriptors, has_desc & gated.T)
            if p.classifier is not None and p.classifier.weight > 0:
                total = total + p.classifier.weight * self._classifier_log_odds(descriptors, has_desc)
        total = total + _logit(p_det)[:, None]
        return np.where(gated, total, -np.inf)

    def _appearance_log_odds(self, descriptors: np.ndarray, pairs: np.ndarray) -> np.ndarray:
        """(N, T) appearance log-odds of the pairs in ``pairs`` (T, N) (0 elsewhere: only pairs
        inside the position gate are compared). Keeps each pair's squared distances to the
        track's gallery for the insertion that follows a match (``self._d2``)."""
        model = self.params.appearance
        assert model is not None
        dist = np.full((len(descriptors), len(self.tracks)), np.nan)
        for j, t in enumerate(self.tracks):
            if t.gallery is not None and len(t.gallery) and pairs[j].any():
                rows = np.flatnonzero(pairs[j])
                d2 = t.gallery.sq_distances(descriptors[rows])
                dist[rows, j] = model.from_euclidean(np.sqrt(d2.min(axis=1)))
                for k, d in enumerate(rows.tolist()):
                    self._d2[(d, j)] = d2[k]
        return model.log_odds(dist)

    def _classifier_log_odds(self, descriptors: np.ndarray, has_desc: np.ndarray) -> np.ndarray:
        """(N, T) the tracks' classifiers' log-odds (0 for an untrained one or no descriptor)."""
        cp = self.params.classifier
        assert cp is not None
        out = np.zeros((len(descriptors), len(self.tracks)))
        cols = [j for j, t in enumerate(self.tracks) if t.clf_steps > 0]
        if cols:
            w = np.stack([self.tracks[j].clf for j in cols])  # type: ignore[misc]
            out[np.ix_(np.flatnonzero(has_desc), cols)] = clf.scores(w, clf.normalise(descriptors[has_desc]), cp.clip)
        return out

    def _train_classifiers(self, matches: list[tuple[int, int]], descriptors: np.ndarray | None,
                           has_desc: np.ndarray, confident: np.ndarray) -> None:
        """One step for every track matched with a confident descriptor while others are in view."""
        cp = self.params.classifier
        if cp is None or descriptors is None or self.params.appearance is None or has_desc.sum() < 2:
            return
        rows = np.flatnonzero(has_desc)
        row_of = {int(d): i for i, d in enumerate(rows)}
        pairs = [(row_of[d], self.tracks[j]) for d, j in matches if has_desc[d] and confident[d]]
        if not pairs:
            return
        u = clf.normalise(descriptors[rows])
        dim = u.shape[1]
        w = np.stack([t.clf if t.clf is not None and len(t.clf) == dim + 1 else np.zeros(dim + 1) for _, t in pairs])
        w = clf.train(w, u, np.array([r for r, _ in pairs]), cp)
        for (_, t), wk in zip(pairs, w):
            t.clf, t.clf_steps = wk, t.clf_steps + 1

    def _associate(self, log_odds: np.ndarray, confident: np.ndarray) -> list[tuple[int, int]]:
        """Stages: confident detections x established tracks, low-score detections x the
        established tracks left, remaining confident detections x tentative tracks."""
        established = [j for j, t in enumerate(self.tracks) if t.status is not TrackStatus.TENTATIVE]
        tentative = [j for j, t in enumerate(self.tracks) if t.status is TrackStatus.TENTATIVE]
        high = np.flatnonzero(confident).tolist()
        low = np.flatnonzero(~confident).tolist()
        matches = _hungarian(log_odds, high, established)
        taken_d, taken_t = {d for d, _ in matches}, {j for _, j in matches}
        matches += _hungarian(log_odds, low, [j for j in established if j not in taken_t])
        matches += _hungarian(log_odds, [d for d in high if d not in taken_d], tentative)
        return matches

    def _update_matched(self, matches: list[tuple[int, int]], positions: np.ndarray, r: np.ndarray,
                        descriptors: np.ndarray | None, has_desc: np.ndarray, p_det: np.ndarray,
                        confident: np.ndarray, stamp: float, camera: str = "") -> None:
        if not matches:
            return
        d_idx = np.array([d for d, _ in matches])
        t_idx = [j for _, j in matches]
        means = np.array([self.tracks[j].mean for j in t_idx])
        covs = np.array([self.tracks[j].cov for j in t_idx])
        new_means, new_covs = kalman.update(means, covs, positions[d_idx], r[d_idx])
        for k, (d, j) in enumerate(matches):
            t = self.tracks[j]
            t.mean, t.cov = new_means[k], new_covs[k]
            t.last_update = stamp
            t.unseen_s = 0.0
            t.camera = camera
            t.total_hits += 1
            t.is_person = _bayes(t.is_person, p_det[d])
            if confident[d]:
                t.confident_hits += 1
            if t.status is TrackStatus.COASTING:
                t.status = TrackStatus.CONFIRMED
            if has_desc[d] and descriptors is not None and confident[d]:
                self._add_descriptor(t, descriptors[d], self._d2.get((d, j)))

    def _update_pose(self, matches: list[tuple[int, int]], positions: np.ndarray, aspects: np.ndarray | None,
                     orientations: np.ndarray | None = None) -> None:
        """TU Ilmenau: posture from the body height and box shape, orientation from walking or,
        standing still, from the crop classifier."""
        pp = self.params.posture
        if pp is None:
            return
        for d, j in matches:
            t = self.tracks[j]
            if aspects is not None:
                t.posture = pose.update(t.posture, pose.posture_evidence(float(positions[d, 2]), float(aspects[d])))
            if t.status is TrackStatus.TENTATIVE:  # a young track's velocity is its prior
                continue
            walking = pose.orientation_evidence(t.mean[3:5], pp)
            if walking is not None:
                t.orientation = pose.update(t.orientation, walking)
            elif orientations is not None and np.all(np.isfinite(orientations[d])):
                t.orientation = pose.update(t.orientation, np.asarray(orientations[d], float) + 1e-3)

    def _age(self, stamp: float, result: FrameResult, appearance: bool, view: FieldOfView | Views | None,
             previous: float | None) -> None:
        """Coasting, the tracks' view flags and deletion; ``previous``: the last frame's stamp."""
        p = self.params
        keep = []
        for t in self.tracks:
            gap = stamp - t.last_update
            if gap > 0 and t.status is TrackStatus.CONFIRMED:
                t.status = TrackStatus.COASTING
            if t.status is not TrackStatus.COASTING:
                t.in_view = None
        coasting = [t for t in self.tracks if t.status is TrackStatus.COASTING]
        if view is not None and coasting:
            seen = view.contains(np.array([t.mean[:3] for t in coasting]), p.view_margin)
            for t, s in zip(coasting, seen.tolist()):
                if t.in_view is False:  # out of view since the last frame
                    t.unseen_s += max(0.0, stamp - max(previous if previous is not None else stamp, t.last_update))
                t.in_view = s
        for t in self.tracks:
            # in view, a track is dropped on the usual limits; the time out of every view
            # does not count towards max_coast_s, and a track that has been out of view has
            # the wider variance bound (it may come back into a view far from its prediction)
            gap = stamp - t.last_update
            var = t.cov[0, 0] + t.cov[1, 1]
            if t.status is TrackStatus.TENTATIVE:
                if gap > p.tentative_timeout_s:
                    continue  # a birth candidate that did not go on: clutter
            elif (gap - t.unseen_s > p.max_coast_s or gap > p.max_coast_unseen_s or var > p.max_position_var_unseen
                  or (t.unseen_s == 0.0 and t.in_view is not False and var > p.max_position_var)):
                t.status = TrackStatus.DELETED
                result.deleted.append(self._view(t, stamp))
                self._archive(t)
                continue
            keep.append(t)
        self.tracks = keep

    def _archive(self, t: _Track) -> None:
        """A deleted person's gallery and classifier go to the ID memory."""
        if t.forgotten:
            return
        if t.gallery is not None and len(t.gallery):
            self.memory.archive(t.id, t.gallery.descriptors)
        if t.clf_steps and t.clf is not None:
            self.classifiers[t.id] = t.clf
        if len(self.classifiers) > len(self.memory):  # follow the memory's evictions and forgetting
            self.classifiers = {i: w for i, w in self.classifiers.items() if i in self.memory}

    def _births(self, free: list[int], matched: set[int], positions: np.ndarray, p_det: np.ndarray) -> list[int]:
        """The unmatched confident detections that start tracks: all of them, or with
        ``birth_separation_m`` those not that near a matched detection or a likelier birth."""
        sep = self.params.birth_separation_m
        if sep <= 0 or not free:
            return free
        taken = [positions[d, :2] for d in matched]
        out = []
        for d in sorted(free, key=lambda d: -p_det[d]):
            if all(float(np.linalg.norm(positions[d, :2] - q)) >= sep for q in taken):
                out.append(d)
                taken.append(positions[d, :2])
        return sorted(out)

    def _birth(self, dets: list[int], positions: np.ndarray, descriptors: np.ndarray | None, has_desc: np.ndarray,
               p_det: np.ndarray, stamp: float, camera: str = "") -> None:
        for d in dets:
            mean = np.concatenate([positions[d], np.zeros(4 if self._ukf else 3)])  # at rest, not turning
            t = _Track(0, mean, self._p0, None, stamp, stamp, is_person=_bayes(0.5, p_det[d]), camera=camera)
            if has_desc[d] and descriptors is not None:
                self._add_descriptor(t, descriptors[d])
            self.tracks.append(t)

    def _confirm(self, result: FrameResult) -> None:
        p = self.params
        for t in list(self.tracks):  # a hand-over removes the coasting track it replaces
            if t.status is TrackStatus.TENTATIVE and t.confident_hits >= p.n_init and t.is_person >= p.confirm_is_person:
                t.status, t.ever_confirmed = TrackStatus.CONFIRMED, True
                handed = self._handover(t)
                if handed is not None:
                    t.id = handed
                    result.new_ids.append(t.id)
                    result.recovered_ids.append(t.id)
                    continue
                t.id, recovered = self._identity(t)
                result.new_ids.append(t.id)
                if recovered:
                    result.recovered_ids.append(t.id)

    def _handover(self, t: _Track) -> int | None:
        """Hand-over by motion: the ID of the track coasting out of view, last seen by another
        camera than the one ``t`` was born in, whose prediction the newly confirmed ``t`` is
        nearest (squared Mahalanobis distance on (x, y) within ``handover_gate_sq``), which
        ``t`` replaces (it takes its gallery and classifier too); None when there is none. A
        person leaving one camera's view and coming back into it is left to appearance."""
        gate = self.params.handover_gate_sq
        if gate is None:
            return None
        best, best_d2 = None, gate
        for c in self.tracks:
            if (c.status is not TrackStatus.COASTING or c.in_view is not False or not c.id or c.forgotten
                    or not c.camera or c.camera == t.camera):  # the same camera: re-identification's job
                continue
            s = c.cov[:2, :2] + t.cov[:2, :2]
            diff = t.mean[:2] - c.mean[:2]
            d2 = float(diff @ np.linalg.solve(s, diff))
            if d2 <= best_d2:
                best, best_d2 = c, d2
        if best is None:
            return None
        if best.gallery is not None and len(best.gallery):
            if t.gallery is None:
                t.gallery = best.gallery
            else:
                for desc in best.gallery.descriptors:
                    t.gallery.add(desc)
        if best.clf_steps and t.clf_steps == 0:
            t.clf, t.clf_steps = best.clf, best.clf_steps
        self.tracks.remove(best)
        return best.id

    def _identity(self, t: _Track) -> tuple[int, bool]:
        """Algorithm 2 through the calibrated model: a remembered person nearer than ``t_recover``."""
        model = self.params.appearance
        if model is None or t.gallery is None or not len(t.gallery) or not self.memory.entries:
            return self.memory.new_id(), False
        live = self.live_ids()
        ids, dist = self.memory.distances(t.gallery.descriptors.mean(axis=0), exclude=live)
        if len(ids):
            dist = model.from_euclidean(dist)
            best = int(np.argmin(dist))
            if dist[best] < model.t_recover:
                return int(ids[best]), True
        recovered = self._recover_by_classifier(t, live)
        if recovered is not None:
            return recovered, True
        return self.memory.new_id(), False

    def _recover_by_classifier(self, t: _Track, live: set[int]) -> int | None:
        """Basso/Munaro's recovery: the remembered people's classifiers score the new track's views;
        the best mean log-odds above ``recover_score`` gives its ID back."""
        cp = self.params.classifier
        assert t.gallery is not None
        u = clf.normalise(t.gallery.descriptors)
        cands = [(i, w) for i, w in self.classifiers.items()
                 if i not in live and i in self.memory and len(w) == u.shape[1] + 1]
        if cp is None or not cands:
            return None
        s = clf.scores(np.stack([w for _, w in cands]), u, cp.clip).mean(axis=0)
        best = int(np.argmax(s))
        return int(cands[best][0]) if s[best] >= cp.recover_score else None

    def _add_descriptor(self, t: _Track, desc: np.ndarray, d2: np.ndarray | None = None) -> None:
        if t.forgotten:
            return
        if t.gallery is None:
            t.gallery = Gallery(len(desc), self.params.gallery_size, prune="nearest")
        t.gallery.add(desc, d2)

    def _view(self, t: _Track, stamp: float) -> TrackView:
        # the arrays are shared: the tracker never writes into a track's mean or cov, every
        # predict and update makes new ones
        mean, cov = (t.mean[:6], t.cov[:6, :6]) if self._ukf else (t.mean, t.cov)  # (x, y, z, vx, vy, vz)
        on = self.params.posture is not None
        return TrackView(t.id, t.status, mean, cov, t.total_hits, 0, max(0.0, stamp - t.first_stamp),
                         t.last_update, len(t.gallery) if t.gallery else 0, t.ever_confirmed,
                         posture=t.posture if on else None, orientation=t.orientation if on else None)

    def forget(self, track_id: int) -> dict[str, int | bool]:
        """Forget a person: their remembered descriptors and classifier go, and a live track
        with that ID keeps its ID and position but loses its appearance history and learns
        none from now on, so the person gets a new ID when they come back. Returns what
        was removed: ``descriptors`` (remembered and live), ``classifier``, ``live_track``."""
        removed = self.memory.forget(track_id)
        had_classifier = self.classifiers.pop(track_id, None) is not None
        live = False
        for t in self.tracks:
            if t.id == track_id:
                removed += len(t.gallery) if t.gallery is not None else 0
                had_classifier = had_classifier or t.clf_steps > 0
                t.gallery, t.clf, t.clf_steps, t.forgotten = None, None, 0, True
                live = True
        return {"descriptors": removed, "classifier": had_classifier, "live_track": live}

    def forget_all(self) -> list[int]:
        """Forget everyone (:meth:`forget` for every remembered or live ID); returns the IDs."""
        ids = sorted(set(self.memory.entries) | set(self.classifiers) | self.live_ids())
        for i in ids:
            self.forget(i)
        return ids

    def predict_views(self, views: list[TrackView], dt: float) -> list[TrackView]:
        """``views`` moved ``dt`` seconds ahead by the constant-velocity model (for output at
        a fixed rate between frames); the tracker's state does not change."""
        if not views or dt <= 0:
            return list(views)
        means, covs = kalman.predict(np.stack([v.mean for v in views]), np.stack([v.cov for v in views]), dt,
                                     self._q(dt))
        return [replace(v, mean=m, cov=c) for v, m, c in zip(views, means, covs)]

    def restart_clock(self) -> list[int]:
        """End every live track and forget the clock, keeping the ID memory (a clock jump:
        a replay that loops, a sensor clock reset). Each confirmed track's gallery goes to
        the memory, so a person seen again after the jump gets their ID back; returns the
        ended IDs (tentative tracks have none and are dropped)."""
        ended = [t.id for t in self.tracks if t.id]
        for t in self.tracks:
            if t.id:
                self._archive(t)
        self.tracks = []
        self.last_stamp = None
        return ended

    def reported(self, result: FrameResult) -> list[TrackView]:
        """What to output: confirmed tracks, and coasting ones missed for at most
        ``report_coast_s`` unless known to be out of the camera's view."""
        limit = self.params.report_coast_s
        return [v for v in result.tracks if v.status is TrackStatus.CONFIRMED or
                (v.status is TrackStatus.COASTING and result.stamp - v.last_update <= limit and v.in_view is not False)]

    # ---------------------------------------------------------------- snapshots
    def snapshot(self) -> RobustTrackerState:
        return RobustTrackerState([t.copy() for t in self.tracks], self.memory.copy(), self.last_stamp,
                                  dict(self.classifiers))

    def restore(self, state: RobustTrackerState) -> None:
        self.tracks = [t.copy() for t in state.tracks]
        self.memory = state.memory.copy()
        self.last_stamp = state.last_stamp
        self.classifiers = dict(state.classifiers)

    def live_classifiers(self) -> dict[int, np.ndarray]:
        """ID -> weights of every confirmed live track's trained classifier."""
        return {t.id: t.clf for t in self.tracks if t.id and t.clf_steps and t.clf is not None}

    def kept_classifiers(self) -> dict[int, np.ndarray]:
        """The classifiers to keep: the remembered people's and the live tracks'."""
        return {**self.classifiers, **self.live_classifiers()}

    def load_classifiers(self, weights: dict[int, np.ndarray]) -> None:
        """The remembered people's classifiers (from the ID memory's file)."""
        self.classifiers = dict(weights)

    def live_galleries(self) -> list[tuple[int, np.ndarray]]:
        return [(t.id, t.gallery.descriptors) for t in self.tracks if t.id and t.gallery is not None and len(t.gallery)]


def _bayes(p: float, q: float) -> float:
    """Binary Bayes update of ``p`` with evidence ``q`` (both probabilities)."""
    num = p * q
    return float(num / (num + (1 - p) * (1 - q)))


def _hungarian(log_odds: np.ndarray, dets: list[int], tracks: list[int]) -> list[tuple[int, int]]:
    """Maximum total log-odds over the pairs with positive log-odds (others: clutter/new)."""
    if not dets or not tracks:
        return []
    sub = log_odds[dets][:, tracks]
    if len(dets) == 1 or len(tracks) == 1:  # no assignment problem: the best positive pair
        i, j = divmod(int(np.argmax(sub)), len(tracks))
        return [(dets[i], tracks[j])] if sub[i, j] > 0 else []
    allowed = sub > 0
    if not allowed.any():
        return []
    cost = np.where(allowed, -sub, 0.0)  # a disallowed pair is worth as much as no pair
    rows, cols = linear_sum_assignment(cost)
    return [(dets[i], tracks[j]) for i, j in zip(rows.tolist(), cols.tolist()) if allowed[i, j]]
