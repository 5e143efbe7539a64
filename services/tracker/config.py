"""TrackerConfig: the tracker's settings. Each profile has its section, ``robust:`` and
``thesis:``, with the core's defaults (:class:`RobustParams`, :class:`TrackerParams`,
written there only); the service's settings and the ID memory's are at the top.

Appearance thresholds depend on the embedding model's distance scale, so they live under
the model's name in ``appearance``. :data:`DEFAULT_APPEARANCE` below is the one place the
shipped per-model values are written.

The thesis profile's settings used to sit at the top (``n_init: 3``); such files still load:
those keys are moved under ``thesis:``, with a warning that names the new place.
"""

from __future__ import annotations

import dataclasses
import logging
import os
from pathlib import Path
from typing import Any, Literal

import numpy as np
from pydantic import BaseModel, ConfigDict, Field, field_validator, model_validator

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

__all__ = ["DEFAULT_APPEARANCE", "DEFAULT_EMBEDDING_MODEL", "PROFILES", "SEVERAL_CAMERAS", "AppearanceConfig",
           "RobustConfig", "ScoreConfig", "ThesisConfig", "TrackerConfig", "default_memory_path"]

log = logging.getLogger(__name__)

#: The tracker's profiles: ``robust`` (the default, built from Pinto's thesis, the TU Ilmenau
#: framework, Basso/Munaro and Ban et al.) and ``thesis`` (Pinto's thesis exactly, for
#: comparison and reproduction).
PROFILES = ("robust", "thesis")

#: The project's default embedder (services/embedder): an L2-normalised colour histogram.
DEFAULT_EMBEDDING_MODEL = "colour"


class AppearanceConfig(BaseModel):
    """Algorithm 1 and 2 thresholds on one embedding model's distance scale."""

    model_config = ConfigDict(extra="forbid")

    t_lower: float = Field(ge=0.0, description="below: appearance alone admits a pair")
    t_upper: float = Field(gt=0.0, description="at or above: the pair is never admitted")
    t_recover: float = Field(gt=0.0, description="Algorithm 2: reuse a remembered ID closer than this")
    s_max: float | None = Field(default=None, ge=0.0, description="per-model S_max (thesis profile); None uses thesis.s_max")
    metric: Literal["euclidean", "cosine"] | None = Field(
        default=None, description="how the model's descriptors compare; None: as its model card says (euclidean if none)")

    @model_validator(mode="after")
    def _ordered(self) -> AppearanceConfig:
        if not self.t_lower < self.t_upper:
            raise ValueError(f"t_lower ({self.t_lower}) must be below t_upper ({self.t_upper})")
        return self


# --------------------------------------------------------------------------------------
# Shipped thresholds, per embedding model. THE place to change them.
#  * trinet: Pinto's thesis (eq. 17 and 18), in TriNet's raw 128-D feature scale.
#  * colour: the default colour-histogram embedder; L2-normalised, so distances lie in
#    [0, sqrt(2)]. Calibrated on PETS09 crops and synthetic lighting changes with
#    `perception calibrate-embedder`; the embedder's model card carries the same values
#    (services/embedder/core/colour.py, COLOUR_THRESHOLDS; a test keeps them equal).
DEFAULT_APPEARANCE: dict[str, dict[str, float]] = {
    "trinet": {"t_lower": 300.0, "t_upper": 700.0, "t_recover": 400.0, "s_max": 0.05},
    "colour": {"t_lower": 0.31, "t_upper": 0.75, "t_recover": 0.38},
}
# --------------------------------------------------------------------------------------


def default_memory_path() -> Path:
    """``$XDG_STATE_HOME/people-perception/tracker-id-memory.npz`` (``~/.local/state`` by default)."""
    base = os.environ.get("XDG_STATE_HOME") or str(Path.home() / ".local" / "state")
    return Path(base) / "people-perception" / "tracker-id-memory.npz"


def _default_appearance() -> dict[str, AppearanceConfig]:
    return {k: AppearanceConfig(**v) for k, v in DEFAULT_APPEARANCE.items()}


#: The core's defaults: every default below that the core also has is taken from here,
#: so it is written once, in the core (tests/unit/test_config_defaults.py checks they agree).
_D = TrackerParams()
_R = RobustParams()
_SC = ScoreModel()

#: The robust settings for several cameras with blind stretches between their views (the
#: head camera and one on the base looking backwards): a track out of every view coasts up
#: to 6 s and 100 m^2 (about 3 s of walking at q_accel 3), and a person confirmed in one
#: camera's view takes the ID of a track that left another camera's view, by motion (the
#: chi2 gate of the association). ``deploy/two-cameras.yaml``, ``perception demo
#: --back-camera`` and ``run_chain(back_camera=...)`` use them. They are not the defaults: on
#: one moving camera (the head turning away from people, the base driving) the longer
#: coasting lets drifted predictions take the wrong person when the view comes back
#: (simulator moving-base IDF1 0.705 -> 0.643; moving-head 0.798 -> 0.797).
SEVERAL_CAMERAS: dict[str, float] = {"max_coast_unseen_s": 6.0, "max_position_var_unseen": 100.0,
                                     "handover_gate_sq": 13.8}


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
    recover_score: float = Field(default=_CL.recover_score,
                                 description="mean log-odds that gives a remembered person's ID back")

    def params(self) -> ClassifierParams | None:
        return ClassifierParams(self.rate, self.l2, self.clip, self.weight, self.recover_score) if self.enabled else None


_PO = PostureParams()


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

    def params(self) -> PostureParams | None:
        if not self.enabled:
            return None
        return PostureParams(self.posture_tau_s, self.orientation_tau_s, self.min_speed, self.kappa_per_mps,
                             self.max_kappa)


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
                                           "width/height) or outside it is out of view: kept, not reported")
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

    def params(self, appearance: AppearanceModel | None, memory_size: int) -> RobustParams:
        fields = self.model_dump(exclude={"scores", "detector_scores", "use_detection_covariance", "classifier",
                                          "posture"})
        return RobustParams(**fields, appearance=appearance, scores=self.scores.model(), memory_size=memory_size,
                            classifier=self.classifier.params(), posture=self.posture.params())

    def build(self, appearance: AppearanceModel | None, memory: IdentityMemory | None, memory_size: int) -> TrackerCore:
        return RobustTracker(self.params(appearance, memory_size), memory)

    def score_models(self) -> dict[str, ScoreModel]:
        """The score models of the detectors that have their own, by name."""
        return {name: sc.model() for name, sc in self.detector_scores.items()}

    @property
    def covariance_fallback(self) -> np.ndarray:
        """(3, 3): what stands for an unusable detection covariance: zero (R is ``sigma_r^2``
        plus the covariance)."""
        return np.zeros((3, 3))


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

    @property
    def covariance_fallback(self) -> np.ndarray:
        """(3, 3): what stands for an unusable detection covariance: ``diag(sigma_r^2)`` (R is the covariance)."""
        return np.diag(np.asarray(self.sigma_r, float) ** 2)


#: The thesis profile's settings that used to sit at the top of the tracker's settings.
_OLD_THESIS_KEYS = tuple(ThesisConfig.model_fields)


class TrackerConfig(BaseModel):
    """Everything ``perception tracker`` and ``perception track`` can be told."""

    model_config = ConfigDict(extra="forbid")

    profile: Literal["robust", "thesis"] = Field(
        default="robust",
        description="'robust' (default): cue fusion, staged association, life cycle in seconds; "
                    "'thesis': Pinto's thesis exactly")
    robust: RobustConfig = Field(default_factory=RobustConfig, description="the robust profile's settings")
    thesis: ThesisConfig = Field(default_factory=ThesisConfig, description="the thesis profile's settings")
    # --- appearance (both profiles) and the ID memory (Algorithm 2)
    embedding_model: str | None = Field(
        default=None, min_length=1, description="accept descriptors of this model only; None: the first model seen")
    appearance: dict[str, AppearanceConfig] = Field(default_factory=_default_appearance)
    # --- bounded memory (the TU Ilmenau framework)
    memory_size: int = Field(default=_D.memory_size, ge=1, le=100_000, description="max descriptors per remembered ID")
    max_remembered_ids: int = Field(default=10_000, ge=1, le=1_000_000,
                                    description="max IDs remembered; one more forgets the one archived longest ago")
    # --- service
    camera: str = Field(default="head", min_length=1, description="camera whose streams to track ('*' for all)")
    frame_id: str = Field(default="map", min_length=1, description="tracking frame; inputs in another frame are dropped")
    output_rate_hz: float = Field(
        default=10.0, ge=0.0, le=1000.0,
        description="Tracks published at this rate, predicted to the publish time (TU Ilmenau); 0: once per input frame")
    join_wait_s: float = Field(default=0.1, ge=0.0, le=10.0,
                               description="how long localized detections wait for their embeddings")
    no_embeddings: list[str] = Field(
        default_factory=list, description="streams no embedder reads (a second, slow detector's, e.g. head-hog): "
                                          "their frames are tracked by position at once, not after join_wait_s")
    view_age_s: float = Field(
        default=1.0, gt=0.0, le=60.0,
        description="with several cameras, a coasting track is reported while in the view of any camera that sent a "
                    "frame within this long")
    reorder_window_s: float = Field(default=0.5, ge=0.0, le=10.0,
                                    description="inputs older than this behind the newest are dropped")
    clock_jump_s: float = Field(
        default=5.0, gt=0.0, le=3600.0,
        description="a frame this much older than its source's newest is a clock jump (a replay that loops): "
                    "every track ends, its ID remembered, and tracking starts over; must exceed reorder_window_s")
    memory_path: Path | None = Field(default_factory=default_memory_path,
                                     description="ID memory file, loaded at start and rewritten on change; null: none")
    retention_s: float = Field(default=7 * 86400.0, gt=0.0,
                               description="a remembered ID not seen for this long is forgotten (s; default 7 days)")
    memory_save_period_s: float = Field(default=2.0, gt=0.0, le=3600.0,
                                        description="how often live tracks' galleries are also written")

    @model_validator(mode="before")
    @classmethod
    def _old_thesis_keys(cls, data: Any) -> Any:
        """Files written before the profiles had a section each: the thesis's keys at the top
        move under ``thesis:`` (a key given in both places is refused)."""
        if not isinstance(data, dict):
            return data
        old = [k for k in _OLD_THESIS_KEYS if k in data]
        if not old:
            return data
        data = dict(data)
        section = data.get("thesis") or {}
        if isinstance(section, ThesisConfig):
            section = section.model_dump(exclude_unset=True)
        if not isinstance(section, dict):
            return data  # the section's own validation says what is wrong with it
        twice = [k for k in old if k in section]
        if twice:
            raise ValueError(f"{', '.join(twice)} given both at the top and under 'thesis:'; the thesis profile's "
                             "settings belong under 'thesis:' only")
        log.warning("tracker settings %s at the top are the thesis profile's: write them under 'thesis:' "
                    "(e.g. thesis: {%s: ...}); read as such this time", ", ".join(old), old[0])
        data["thesis"] = {**section, **{k: data.pop(k) for k in old}}
        return data

    @model_validator(mode="after")
    def _clock_jump_beyond_window(self) -> TrackerConfig:
        if not self.clock_jump_s > self.reorder_window_s:
            raise ValueError(f"clock_jump_s ({self.clock_jump_s}) must exceed reorder_window_s "
                             f"({self.reorder_window_s}): a late frame within the window is reordered, not a clock jump")
        return self

    @field_validator("appearance", mode="before")
    @classmethod
    def _merge_defaults(cls, v: object) -> object:
        """Models named in a file are added to (or override) the shipped ones."""
        if isinstance(v, dict):
            return {**DEFAULT_APPEARANCE, **v}
        return v

    @field_validator("camera")
    @classmethod
    def _camera(cls, v: str) -> str:
        if v != "*" and any(c in v for c in "/*$?# "):
            raise ValueError(f"camera {v!r} must be a name without '/', '*', '$', '?', '#' or spaces, or '*'")
        return v

    def thresholds(self, model: str) -> AppearanceConfig | None:
        """The configured thresholds of ``model``, or None."""
        return self.appearance.get(model)

    def appearance_model(self, thresholds: AppearanceConfig | None, metric: str | None = None) -> AppearanceModel | None:
        """The robust profile's view of a model's thresholds; ``metric`` from its model card."""
        if thresholds is None:
            return None
        chosen = thresholds.metric or metric or "euclidean"
        if chosen not in ("euclidean", "cosine"):
            raise ValueError(f"unknown descriptor metric {chosen!r}; the tracker knows euclidean and cosine")
        return AppearanceModel(thresholds.t_lower, thresholds.t_upper, thresholds.t_recover, chosen,  # type: ignore[arg-type]
                               thresholds.s_max)

    @property
    def profile_config(self) -> RobustConfig | ThesisConfig:
        """The settings section of the configured profile."""
        return {"robust": self.robust, "thesis": self.thesis}[self.profile]

    def score_models(self) -> dict[str, ScoreModel]:
        """The score models of the detectors that have their own (the robust profile's), by name."""
        return self.profile_config.score_models()

    def build_tracker(self, thresholds: AppearanceConfig | None, memory: IdentityMemory | None = None,
                      metric: str | None = None) -> TrackerCore:
        """The core tracker of the configured profile."""
        tracker = self.profile_config.build(self.appearance_model(thresholds, metric), memory, self.memory_size)
        tracker.memory.max_ids = self.max_remembered_ids
        return tracker

    def apply_thresholds(self, tracker: TrackerCore, thresholds: AppearanceConfig, metric: str | None = None) -> None:
        """Give ``tracker`` a model's thresholds (e.g. once its model card is known)."""
        tracker.set_appearance(self.appearance_model(thresholds, metric))

    @property
    def uses_detection_covariance(self) -> bool:
        return self.profile_config.use_detection_covariance

    @property
    def covariance_fallback(self) -> np.ndarray:
        """(3, 3): what replaces an unusable detection covariance, so that the profile's R is its
        fixed one (:attr:`RobustConfig.covariance_fallback`, :attr:`ThesisConfig.covariance_fallback`)."""
        return self.profile_config.covariance_fallback
