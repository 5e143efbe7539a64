"""The tracker's profile sections of :class:`~services.tracker.config.TrackerConfig`:
``robust:`` (:class:`RobustConfig`) and ``thesis:`` (:class:`ThesisConfig`), each with its
core's defaults (written once, in :class:`RobustParams` and :class:`TrackerParams`;
tests/unit/test_config_defaults.py checks they agree), and each building its core."""

from __future__ import annotations

import dataclasses
from pathlib import Path
from typing import Literal

from pydantic import BaseModel, ConfigDict, Field, PrivateAttr, field_validator, model_validator

from common.geometry.map_file import MapFileError, load_obstacles
from common.geometry.occupancy import ObstacleMap

from services.tracker.core import (
    AppearanceGate,
    AppearanceModel,
    RobustParams,
    RobustTracker,
    ScoreModel,
    Tracker,
    TrackerCore,
    TrackerParams,
)
from services.tracker.core.classifier import ClassifierParams
from services.tracker.core.identity import IdentityMemory
from services.tracker.core.posture import PostureParams
from services.tracker.core.recovery import RecoveryParams
from services.tracker.core.stature import StatureParams

__all__ = ["ClassifierConfig", "PostureConfig", "RobustConfig", "ScoreConfig", "StaticMapConfig", "StatureConfig",
           "ThesisConfig"]

_D = TrackerParams()
_R = RobustParams()
_SC = ScoreModel()


class ScoreConfig(BaseModel):
    """How the detector's scores read as P(true person): ``sigmoid((score - center) / scale)``."""

    model_config = ConfigDict(extra="forbid")

    center: float | None = Field(default=_SC.center, description="score of P = 0.5; null: scores are not calibrated")
    scale: float = Field(default=_SC.scale, gt=0.0, description="score units per unit of log-odds")
    default_p: float = Field(default=_SC.default_p, gt=0.0, lt=1.0, description="P(true person) when center is null")
    birth_score: float | None = Field(
        default=_SC.birth_score, description="detections below it update tracks but never start one; null: all may")

    def model(self) -> ScoreModel:
        return ScoreModel(self.center, self.scale, self.default_p, self.birth_score)


_CL = ClassifierParams()


class ClassifierConfig(BaseModel):
    """Basso/Munaro's online per-track appearance classifiers (services/tracker/core/classifier.py)."""

    model_config = ConfigDict(extra="forbid")

    enabled: bool = Field(default=True, description="train one classifier per track and use it")
    rate: float = Field(default=_CL.rate, gt=0.0, description="SGD step")
    l2: float = Field(default=_CL.l2, ge=0.0, lt=1.0, description="weight decay per step")
    clip: float = Field(default=_CL.clip, gt=0.0, description="bound on a classifier's log-odds")
    weight: float = Field(default=_CL.weight, ge=0.0, description="weight of its log-odds in the association")

    def params(self) -> ClassifierParams | None:
        return ClassifierParams(self.rate, self.l2, self.clip, self.weight) if self.enabled else None


_ST = StatureParams()


class StatureConfig(BaseModel):
    """The person's stature as a cue, a soft biometric (services/tracker/core/stature.py)."""

    model_config = ConfigDict(extra="forbid")

    enabled: bool = Field(default=True, description="learn each track's stature and weigh the detections' against it")
    noise_m: float = Field(default=_ST.noise_m, gt=0.0, le=0.5, description="one measurement's std (m)")
    population_mean_m: float = Field(default=_ST.population_mean_m, gt=0.5, lt=2.5,
                                     description="adults' mean stature (m): a stranger's")
    population_sd_m: float = Field(default=_ST.population_sd_m, gt=0.0, le=0.5, description="its std (m)")
    outlier_low: float = Field(default=_ST.outlier_low, gt=0.0, lt=1.0,
                               description="share of measurements lower than the stature (sitting high, a bent or "
                               "hidden head)")
    low_range_m: float = Field(default=_ST.low_range_m, gt=0.0, le=2.0, description="how much lower they reach (m)")
    outlier_high: float = Field(default=_ST.outlier_high, gt=0.0, lt=1.0,
                                description="share of measurements higher than the stature (a raised arm, a hat)")
    high_range_m: float = Field(default=_ST.high_range_m, gt=0.0, le=2.0, description="how much higher they reach (m)")
    gate_m: float = Field(default=_ST.gate_m, gt=0.0, description="a learnt stature ignores measurements this far off (m)")
    min_samples: int = Field(default=_ST.min_samples, ge=1, description="measurements before a track's stature counts")
    window: int = Field(default=_ST.window, ge=1, description="the running mean's memory (measurements)")
    clip: float = Field(default=_ST.clip, gt=0.0, description="bound on its log-odds")
    weight: float = Field(default=_ST.weight, ge=0.0, description="weight of its log-odds in the association")

    @model_validator(mode="after")
    def _window(self) -> StatureConfig:
        if self.window < self.min_samples:
            raise ValueError(f"window ({self.window}) must be at least min_samples ({self.min_samples})")
        if self.outlier_low + self.outlier_high >= 1:
            raise ValueError("outlier_low + outlier_high must be below 1")
        return self

    def params(self) -> StatureParams | None:
        return StatureParams(**self.model_dump(exclude={"enabled"})) if self.enabled else None


_PO = PostureParams()


class StaticMapConfig(BaseModel):
    """The robot's static map, its laser's walls and furniture (services/tracker/README.md, *A static
    map*): no track is born on an obstacle. Read when the settings are loaded."""

    model_config = ConfigDict(extra="forbid")

    path: Path | None = Field(default=None, description="a ROS map YAML file (map_server's, Nav2 map_saver's, "
                                                        "slam_toolbox's) in the tracking frame; null: no map")
    birth_clearance_m: float = Field(default=_R.birth_clearance_m, ge=0.0, le=1.0,
                                     description="no track is born this near (m) an obstacle of the map (about a "
                                                 "localization error)")
    topic: bool = Field(default=True, description="without a path: take the map from the static_map stream (the ros2 "
                                                  "node's /map, as Nav2's map_server or slam_toolbox publish it)")
    min_obstacle_m: float = Field(default=0.3, ge=0.0, le=5.0,
                                  description="occupied areas shorter than this (m) on both sides are no obstacle: "
                                              "chair and table legs, posts (a detection of someone behind a chair "
                                              "lands among its legs)")
    _obstacles: ObstacleMap | None = PrivateAttr(default=None)

    @field_validator("path", mode="before")
    @classmethod
    def _empty_is_none(cls, value: object) -> object:
        return None if value == "" else value  # a launch file's ${STATIC_MAP:-} when unset

    @model_validator(mode="after")
    def _load(self) -> StaticMapConfig:
        if self.path is not None:
            try:
                self._obstacles = load_obstacles(self.path, self.min_obstacle_m)
            except (OSError, MapFileError) as exc:
                raise ValueError(str(exc)) from None
        return self

    @property
    def obstacles(self) -> ObstacleMap | None:
        return self._obstacles


class PostureConfig(BaseModel):
    """The TU Ilmenau framework's posture and orientation filters (services/tracker/core/posture.py)."""

    model_config = ConfigDict(extra="forbid")

    enabled: bool = Field(default=True, description="estimate posture and orientation per track")
    posture_tau_s: float = Field(default=_PO.posture_tau_s, gt=0.0, description="drift of posture to unknown (s)")
    orientation_tau_s: float = Field(default=_PO.orientation_tau_s, gt=0.0,
                                     description="drift of orientation to unknown (s)")
    min_speed: float = Field(default=_PO.min_speed, ge=0.0, description="walking slower says nothing of orientation (m/s)")
    kappa_per_mps: float = Field(default=_PO.kappa_per_mps, gt=0.0, description="von Mises concentration per m/s")
    max_kappa: float = Field(default=_PO.max_kappa, gt=0.0, description="its cap")
    reported_likelihood: list[list[float]] = Field(
        default=[list(r) for r in _PO.reported_likelihood], min_length=3, max_length=3,
        description="P(a detector reports standing / sitting / lying | the person stands, sits, lies): one row "
                    "per report; rows of equal values ignore the detector")

    @model_validator(mode="after")
    def _valid(self) -> PostureConfig:
        PostureParams(reported_likelihood=tuple(tuple(r) for r in self.reported_likelihood))  # type: ignore[arg-type]
        return self

    def params(self) -> PostureParams | None:
        if not self.enabled:
            return None
        return PostureParams(self.posture_tau_s, self.orientation_tau_s, self.min_speed, self.kappa_per_mps,
                             self.max_kappa, tuple(tuple(r) for r in self.reported_likelihood))  # type: ignore[misc]


_RE = RecoveryParams()


class RecoveryConfig(BaseModel):
    """The ID memory's open-set decision (services/tracker/core/recovery.py)."""

    model_config = ConfigDict(extra="forbid")

    p_new: float | None = Field(default=_RE.p_new, gt=0.0, lt=1.0,
                                description="prior that a newly confirmed person is someone new; null: estimated "
                                            "online from the recent contested confirmations")
    prior_window: float = Field(default=_RE.prior_window, ge=1.0, description="confirmations the estimate counts")
    prior_new: float = Field(default=_RE.prior_new, gt=0.0, description="the estimate's prior: new (pseudo-counts)")
    prior_returned: float = Field(default=_RE.prior_returned, gt=0.0,
                                  description="the estimate's prior: returning (pseudo-counts)")
    p_recover: float = Field(default=_RE.p_recover, gt=0.0, lt=1.0,
                             description="posterior a remembered person needs to get their ID back")
    p_undo: float = Field(default=_RE.p_undo, gt=0.0, lt=1.0,
                          description="during probation, a recovery whose posterior falls below this is undone")
    max_speed: float = Field(default=_RE.max_speed, gt=0.0, description="fastest walk (m/s): farther is unreachable")
    n_sigma: float = Field(default=_RE.n_sigma, ge=0.0, description="position standard deviations allowed on top")
    probation_s: float = Field(default=_RE.probation_s, ge=0.0,
                               description="how long a recovery is checked again (s); 0: never undone")
    check_period_s: float = Field(default=_RE.check_period_s, gt=0.0, description="how often during probation (s)")
    compete: bool = Field(default=_RE.compete, description="a detection near a coasting track, or near a confirmed "
                          "one whose person it does not look like, that looks like a remembered person known to be "
                          "someone else counts that as an alternative")
    left_weight: float = Field(default=_RE.left_weight, gt=0.0, le=1.0,
                               description="prior weight of a remembered person who walked out of the cameras' view, "
                                           "against one lost inside it; 1: no difference")
    exit_horizon_s: float = Field(default=_RE.exit_horizon_s, ge=0.0,
                                  description="a person walked out when their walk from the last fix in view left it "
                                              "within this time (s)")

    @model_validator(mode="after")
    def _undo_below_recover(self) -> RecoveryConfig:
        if not self.p_undo <= self.p_recover:
            raise ValueError(f"p_undo ({self.p_undo}) must not exceed p_recover ({self.p_recover})")
        return self

    def params(self) -> RecoveryParams:
        return RecoveryParams(**self.model_dump())


class RobustConfig(BaseModel):
    """The ``robust`` profile's settings (services/tracker/README.md explains each)."""

    model_config = ConfigDict(extra="forbid")

    motion: Literal["cv", "ukf"] = Field(
        default=_R.motion, description="'cv': constant-velocity Kalman; 'ukf': unscented filter, coordinated turn")
    q_accel: float = Field(default=_R.q_accel, gt=0.0, description="white acceleration noise on x, y (m^2/s^3)")
    q_turn: float = Field(default=_R.q_turn, ge=0.0, description="random walk of the turn rate, 'ukf' (rad^2/s^3)")
    sigma0_turn: float = Field(default=_R.sigma0_turn, ge=0.0, description="a new track's turn-rate std, 'ukf' (rad/s)")
    q_z: float = Field(default=_R.q_z, gt=0.0, description="random-walk noise of z (m^2/s)")
    sigma0_position: float = Field(default=_R.sigma0_position, gt=0.0, description="a new track's position std (m)")
    sigma0_velocity: float = Field(default=_R.sigma0_velocity, gt=0.0, description="a new track's velocity std (m/s)")
    sigma_r: tuple[float, float, float] = Field(default=_R.sigma_r, description="measurement std without a covariance (m)")
    use_detection_covariance: bool = Field(default=True, description="use each detection's covariance when it has one")
    new_density: float = Field(default=_R.new_density, gt=0.0,
                               description="density (per m^2) of others or clutter competing with a prediction")
    gate_sq: float = Field(default=_R.gate_sq, gt=0.0, description="squared Mahalanobis bound on (x, y)")
    appearance_weight: float = Field(default=_R.appearance_weight, ge=0.0, description="weight of the appearance cue")
    scores: ScoreConfig = Field(default_factory=ScoreConfig)
    detector_scores: dict[str, ScoreConfig] = Field(
        default_factory=dict, description="score models of named detectors (Detections.detector: depth, hog, "
                                          "yolo-onnx, ...) when several feed the tracker; the others use 'scores'")
    n_init: int = Field(default=_R.n_init, ge=1, le=100, description="confident hits that confirm a track")
    confirm_is_person: float = Field(default=_R.confirm_is_person, ge=0.5, lt=1.0,
                                     description="IsPerson probability a track needs to be confirmed")
    is_person_tau_s: float = Field(default=_R.is_person_tau_s, gt=0.0,
                                   description="time constant of IsPerson's drift back to 0.5 (s)")
    tentative_timeout_s: float = Field(default=_R.tentative_timeout_s, gt=0.0,
                                       description="a tentative track without a hit for this long is dropped (s)")
    report_coast_s: float = Field(default=_R.report_coast_s, ge=0.0,
                                  description="coasting tracks are reported this long after their last hit (s)")
    view_margin: float = Field(default=_R.view_margin, ge=0.0, lt=0.5,
                               description="a coasting track projecting into this border of the image (share of its "
                                           "width/height) or outside it is out of view: kept, not reported; a floor "
                                           "view's border is half a body's width instead (0: none)")
    max_coast_s: float = Field(default=_R.max_coast_s, gt=0.0, description="coasting longer deletes the track (s)")
    max_position_var: float = Field(default=_R.max_position_var, gt=0.0,
                                    description="a track whose (x, y) variance trace passes this is deleted (m^2)")
    max_coast_unseen_s: float = Field(default=_R.max_coast_unseen_s, gt=0.0,
                                      description="max_coast_s for a track coasting out of every camera's view (s)")
    max_position_var_unseen: float = Field(default=_R.max_position_var_unseen, gt=0.0,
                                           description="max_position_var for a track coasting out of every view (m^2)")
    handover_gate_sq: float | None = Field(
        default=_R.handover_gate_sq, gt=0.0,
        description="a track confirmed within this squared Mahalanobis distance of a track coasting out of view "
                    "takes its ID (a person walking from one camera's view into another's); null: off")
    birth_separation_m: float = Field(
        default=_R.birth_separation_m, ge=0.0, le=2.0,
        description="a detection this near (m, ground plane) one that went to a track, or to a likelier new one, "
                    "does not start a track (a second report of the same person); 0: off")
    gallery_size: int = Field(default=_R.gallery_size, ge=1, le=100_000, description="max descriptors per track")
    classifier: ClassifierConfig = Field(default_factory=ClassifierConfig)
    posture: PostureConfig = Field(default_factory=PostureConfig)
    stature: StatureConfig = Field(default_factory=StatureConfig)
    recovery: RecoveryConfig = Field(default_factory=RecoveryConfig)
    static_map: StaticMapConfig = Field(default_factory=StaticMapConfig)

    def params(self, appearance: AppearanceModel | None, memory_size: int) -> RobustParams:
        fields = self.model_dump(exclude={"scores", "detector_scores", "use_detection_covariance", "classifier",
                                          "posture", "stature", "recovery", "static_map"})
        return RobustParams(**fields, appearance=appearance, scores=self.scores.model(), memory_size=memory_size,
                            classifier=self.classifier.params(), posture=self.posture.params(),
                            stature=self.stature.params(), recovery=self.recovery.params(),
                            obstacles=self.static_map.obstacles, birth_clearance_m=self.static_map.birth_clearance_m)

    def build(self, appearance: AppearanceModel | None, memory: IdentityMemory | None, memory_size: int) -> TrackerCore:
        return RobustTracker(self.params(appearance, memory_size), memory)

    def score_models(self) -> dict[str, ScoreModel]:
        """The score models of the detectors that have their own, by name."""
        return {name: sc.model() for name, sc in self.detector_scores.items()}


class ThesisConfig(BaseModel):
    """The ``thesis`` profile's settings: Pinto's thesis (services/tracker/README.md, *Parameters*)."""

    model_config = ConfigDict(extra="forbid")

    # --- Kalman filter (Pinto's thesis, III-C)
    sigma0: tuple[float, float, float, float, float, float] = Field(
        default=_D.sigma0, description="initial std of (x, y, z, vx, vy, vz); P0 = diag(sigma0^2)")
    sigma_q: tuple[float, float, float, float, float, float] = Field(
        default=_D.sigma_q, description="process noise std per nominal frame; Q = diag(sigma_q^2)")
    sigma_r: tuple[float, float, float] = Field(default=_D.sigma_r, description="measurement noise std (m)")
    use_detection_covariance: bool = Field(
        default=False, description="use each LocalizedDetection's covariance as R instead of sigma_r")
    time_step: Literal["time", "frame"] = Field(
        default=_D.time_step, description="'time': dt from stamps; 'frame': dt = 1 per frame, as the thesis")
    frame_period_s: float = Field(default=_D.frame_period_s, gt=0.0, le=10.0,
                                  description="nominal frame period: Q and miss counts are per this period")
    # --- association (Algorithm 1)
    s_max: float = Field(default=_D.s_max, ge=0.0,
                         description="S_max: max squared Mahalanobis (x, y) in the ambiguous band")
    infinite_cost: float = Field(default=_D.inf, gt=0.0, description="cost of an inadmissible pair")
    position_gate_probability: float = Field(default=_D.position_gate_probability, gt=0.0, lt=1.0,
                                             description="chi-square (2 dof) gate of position-only association")
    # --- life cycle (Pinto's thesis, III-E)
    n_init: int = Field(default=_D.n_init, ge=1, le=100, description="consecutive associated frames to confirm")
    max_misses: int = Field(default=_D.max_misses, ge=1, le=1000, description="frames without association to delete")
    gallery_size: int = Field(default=_D.gallery_size, ge=1, le=100_000,
                              description="max descriptors per track gallery")

    @field_validator("sigma0", "sigma_q", "sigma_r")
    @classmethod
    def _positive(cls, v: tuple[float, ...]) -> tuple[float, ...]:
        if any(not (s > 0) for s in v):
            raise ValueError(f"every standard deviation must be positive, got {v}")
        return v

    def params(self, appearance: AppearanceModel | None, memory_size: int) -> TrackerParams:
        """The core's parameters; ``appearance`` None means position-only association.

        ``gate`` and ``t_recover`` come from the embedding model's thresholds, not from the
        core's defaults (the core's ``t_recover`` 400 is TriNet's): position-only, there is
        no gate and ``t_recover`` is 0 (unused: no descriptor is ever compared).
        """
        params = TrackerParams(
            sigma0=self.sigma0, sigma_q=self.sigma_q, sigma_r=self.sigma_r, gate=None, t_recover=0.0,
            n_init=self.n_init, max_misses=self.max_misses, time_step=self.time_step,
            frame_period_s=self.frame_period_s, gallery_size=self.gallery_size, memory_size=memory_size,
            position_gate_probability=self.position_gate_probability, inf=self.infinite_cost, s_max=self.s_max,
        )
        if appearance is None:
            return params
        s_max = self.s_max if appearance.s_max is None else appearance.s_max
        gate = AppearanceGate(appearance.t_lower, appearance.t_upper, s_max, self.infinite_cost)
        return dataclasses.replace(params, gate=gate, t_recover=appearance.t_recover)

    def build(self, appearance: AppearanceModel | None, memory: IdentityMemory | None, memory_size: int) -> TrackerCore:
        return Tracker(self.params(appearance, memory_size), memory)

    def score_models(self) -> dict[str, ScoreModel]:
        """The thesis reads no detector scores."""
        return {}
