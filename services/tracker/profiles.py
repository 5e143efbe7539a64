"""The tracker's profile sections of :class:`~services.tracker.config.TrackerConfig`:
``robust:`` (:class:`RobustConfig`, its cues' sections in :mod:`services.tracker.cue_settings`)
and ``thesis:`` (:class:`ThesisConfig`), each setting declared once with
:func:`~common.runtime.settings.setting` and its default read from the core (:class:`RobustParams`,
:class:`ThesisParams`; tests/unit/test_config_defaults.py checks they agree), each building its core."""

from __future__ import annotations

import dataclasses
from typing import Literal

from pydantic import ConfigDict, field_validator, model_validator

from common.runtime.settings import AdvancedBlock, setting
from services.tracker.core import (
    AppearanceGate,
    AppearanceModel,
    RobustParams,
    RobustTracker,
    ScoreModel,
    ThesisTracker,
    TrackerCore,
    ThesisParams,
)
from services.tracker.core.identity import IdentityMemory
from services.tracker.cue_settings import (
    ClassifierConfig,
    PostureConfig,
    RecoveryConfig,
    ScoreConfig,
    StaticMapConfig,
    StatureConfig,
)

__all__ = ["ClassifierConfig", "PostureConfig", "RecoveryConfig", "RobustConfig", "ScoreConfig", "StaticMapConfig",
           "StatureConfig", "ThesisConfig"]

_D = ThesisParams()
_R = RobustParams()

#: The shipped score models of named detectors. ``laser-legs`` (services/laser: a 2-D laser's people)
#: scores the classifier's calibrated probability that a leg is a leg; chair and table legs imitate
#: legs, so its own IsPerson belief stops at 0.7, below ``confirm_is_person`` (0.75): the laser keeps
#: and supports the people a camera confirmed, and never confirms anyone alone (the TU Ilmenau
#: framework's IsPerson per detector). The node publishes people from 0.2 on (many false ones, as the
#: framework's laser: about one an empty scan on the dev rooms); below 0.5 they keep tracks, never
#: start one.
DETECTOR_SCORES: dict[str, ScoreConfig] = {
    "laser-legs": ScoreConfig(center=0.5, scale=0.2, max_is_person=0.7, birth_score=0.5),
}


class RobustConfig(AdvancedBlock):
    """The ``robust`` profile's settings (services/tracker/README.md, *Settings*)."""

    model_config = ConfigDict(extra="forbid")

    q_accel: float = setting(_R.q_accel, "white acceleration noise on x and y", unit="m²/s³", gt=0.0, advanced=True)
    q_z: float = setting(_R.q_z, "random-walk noise of z", unit="m²/s", gt=0.0, advanced=True)
    sigma0_position: float = setting(_R.sigma0_position, "a new track's position std", unit="m", gt=0.0,
                                     advanced=True)
    sigma0_velocity: float = setting(_R.sigma0_velocity, "a new track's velocity std (people walk at about 1.4 m/s; "
                                     "the frame may move)", unit="m/s", gt=0.0, advanced=True)
    sigma_r: tuple[float, float, float] = setting(_R.sigma_r, "measurement std of (x, y, z) for a detection without "
                                                  "a covariance", unit="m", advanced=True)
    use_detection_covariance: bool = setting(True, "use each detection's covariance as its measurement noise when it "
                                             "has one", advanced=True)
    new_density: float = setting(_R.new_density, "density of others or clutter competing with a track's prediction: "
                                 "the log-odds' alternative to the track", unit="1/m²", gt=0.0, advanced=True)
    gate_sq: float = setting(_R.gate_sq, "a detection farther than this squared Mahalanobis distance on (x, y) from a "
                             "track's prediction is never its (13.8: chi2 0.999, 2 dof)", gt=0.0)
    appearance_weight: float = setting(_R.appearance_weight, "weight of the appearance cue's log-odds", ge=0.0,
                                       advanced=True)
    scores: ScoreConfig = setting(description="the detectors' scores as P(true person)", default_factory=ScoreConfig)
    detector_scores: dict[str, ScoreConfig] = setting(
        default_factory=lambda: dict(DETECTOR_SCORES), advanced=True,
        description="score models of named detectors (Detections.detector: depth, hog, yolo-onnx, laser-legs, ...) "
                    "when several feed the tracker; the others use scores. A file's are added to (or override) the "
                    "shipped one: laser-legs, whose belief stops at 0.7, below confirm_is_person")
    n_init: int = setting(_R.n_init, "confident hits that confirm a track", ge=1, le=100, advanced=True)
    confirm_is_person: float = setting(_R.confirm_is_person, "P(IsPerson) a track needs to be confirmed", ge=0.5,
                                       lt=1.0, advanced=True)
    is_person_tau_s: float = setting(_R.is_person_tau_s, "time constant of P(IsPerson)'s drift back to 0.5",
                                     unit="s", gt=0.0, advanced=True)
    tentative_timeout_s: float = setting(_R.tentative_timeout_s, "a tentative track without a hit for this long is "
                                         "dropped", unit="s", gt=0.0, advanced=True)
    report_coast_s: float = setting(_R.report_coast_s, "coasting tracks are still reported this long after their "
                                    "last hit (at most max_coast_s)", unit="s", ge=0.0, advanced=True)
    view_margin: float = setting(_R.view_margin, "a coasting track projecting into this border of the image (share "
                                 "of its width and height) or outside it is out of view: kept, not reported; a floor "
                                 "view's border is half a body's width instead; 0: none", ge=0.0, lt=0.5,
                                 advanced=True)
    max_coast_s: float = setting(_R.max_coast_s, "a track coasting (not detected) longer than this is deleted, its "
                                 "ID remembered", unit="s", gt=0.0)
    max_position_var: float = setting(_R.max_position_var, "a track whose (x, y) covariance trace passes this is "
                                      "deleted", unit="m²", gt=0.0, advanced=True)
    max_coast_unseen_s: float = setting(_R.max_coast_unseen_s, "max_coast_s for a track coasting out of every "
                                        "camera's view (the several-cameras preset: 6)", unit="s", gt=0.0,
                                        advanced=True)
    max_position_var_unseen: float = setting(_R.max_position_var_unseen, "max_position_var for a track coasting out "
                                             "of every camera's view", unit="m²", gt=0.0, advanced=True)
    handover_gate_sq: float | None = setting(
        _R.handover_gate_sq, gt=0.0,
        description="a track confirmed within this squared Mahalanobis distance of a track coasting out of view takes "
                    "its ID (a person walking from one camera's view into another's; the several-cameras preset: "
                    "13.8); none: off")
    birth_separation_m: float = setting(
        _R.birth_separation_m, unit="m", ge=0.0, le=2.0, advanced=True,
        description="a detection this near (on the ground) one that went to a track, or to a likelier new one, does "
                    "not start a track (a second report of the same person); 0: off")
    gallery_size: int = setting(_R.gallery_size, "most descriptors a track's gallery keeps", ge=1, le=100_000,
                                advanced=True)
    classifier: ClassifierConfig = setting(description="the online appearance classifiers",
                                           default_factory=ClassifierConfig)
    posture: PostureConfig = setting(description="the posture and orientation filters", default_factory=PostureConfig)
    stature: StatureConfig = setting(description="the stature cue", default_factory=StatureConfig)
    recovery: RecoveryConfig = setting(description="the ID memory's decision", default_factory=RecoveryConfig)
    static_map: StaticMapConfig = setting(description="the robot's static map", default_factory=StaticMapConfig)

    @field_validator("detector_scores", mode="after")
    @classmethod
    def _shipped_scores(cls, v: dict[str, ScoreConfig]) -> dict[str, ScoreConfig]:
        return {**DETECTOR_SCORES, **v}

    @model_validator(mode="after")
    def _report_within_coast(self) -> RobustConfig:
        if not self.report_coast_s <= self.max_coast_s:
            raise ValueError(f"report_coast_s ({self.report_coast_s}) must not exceed max_coast_s "
                             f"({self.max_coast_s}): a deleted track cannot be reported")
        return self

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


class ThesisConfig(AdvancedBlock):
    """The ``thesis`` profile's settings: Pinto's thesis (services/tracker/README.md, *Settings*)."""

    model_config = ConfigDict(extra="forbid")

    # --- Kalman filter (Pinto's thesis, III-C)
    sigma0: tuple[float, float, float, float, float, float] = setting(
        _D.sigma0, "initial std of (x, y, z, vx, vy, vz), each positive: P0 = diag(sigma0²) (Pinto's thesis eq. 3)",
        unit="m, m/s", advanced=True)
    sigma_q: tuple[float, float, float, float, float, float] = setting(
        _D.sigma_q, "process noise std per nominal frame, each positive: Q = diag(sigma_q²) (the thesis: Q = P0)",
        unit="m, m/s", advanced=True)
    sigma_r: tuple[float, float, float] = setting(_D.sigma_r, "measurement noise std of (x, y, z), each positive: R "
                                                  "(Pinto's thesis eq. 9)", unit="m", advanced=True)
    use_detection_covariance: bool = setting(False, "use each LocalizedDetection's covariance as R instead of sigma_r "
                                             "(not in the thesis)", advanced=True)
    time_step: Literal["time", "frame"] = setting(_D.time_step, "time: dt from the stamps; frame: dt = 1 per frame, "
                                                  "as the thesis (--time-step)", advanced=True)
    frame_period_s: float = setting(_D.frame_period_s, "nominal frame period (the thesis camera's 30 Hz): Q and the "
                                    "miss counts are per this period", unit="s", gt=0.0, le=10.0, advanced=True)
    # --- association (Algorithm 1)
    s_max: float = setting(_D.s_max, "S_max: most squared Mahalanobis distance on (x, y) in the ambiguous "
                           "appearance band (Pinto's thesis eq. 17)", ge=0.0, advanced=True)
    infinite_cost: float = setting(_D.inf, "cost of an inadmissible pair (Algorithm 1)", gt=0.0, advanced=True)
    position_gate_probability: float = setting(_D.position_gate_probability, "chi-square (2 dof) gate of "
                                               "position-only association (not in the thesis)", gt=0.0, lt=1.0,
                                               advanced=True)
    # --- life cycle (Pinto's thesis, III-E)
    n_init: int = setting(_D.n_init, "consecutive associated frames that confirm a track (Pinto's thesis III-E)",
                          ge=1, le=100, advanced=True)
    max_misses: int = setting(_D.max_misses, "frames without association that delete a track (III-E)", ge=1, le=1000,
                              advanced=True)
    gallery_size: int = setting(_D.gallery_size, "most descriptors a track's gallery keeps (TU Ilmenau's sample "
                                "sets)", ge=1, le=100_000, advanced=True)

    @field_validator("sigma0", "sigma_q", "sigma_r")
    @classmethod
    def _positive(cls, v: tuple[float, ...]) -> tuple[float, ...]:
        if any(not (s > 0) for s in v):
            raise ValueError(f"every standard deviation must be positive, got {v}")
        return v

    def params(self, appearance: AppearanceModel | None, memory_size: int) -> ThesisParams:
        """The core's parameters (``appearance`` None: position-only). ``gate`` and ``t_recover`` come
        from the model's thresholds, not the core's defaults (its ``t_recover`` 400 is TriNet's);
        position-only there is no gate, and ``t_recover`` 0 is never compared."""
        params = ThesisParams(
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
        return ThesisTracker(self.params(appearance, memory_size), memory)

    def score_models(self) -> dict[str, ScoreModel]:
        """The thesis reads no detector scores."""
        return {}
