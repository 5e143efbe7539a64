"""The robust profile's cue sections (``robust.scores``, ``robust.classifier``, ``robust.stature``,
``robust.posture``, ``robust.recovery``, ``robust.static_map``), each declared once with
:func:`~common.runtime.settings.setting`: its default read from the core's params dataclass, its
range, unit and description; each builds its core params."""

from __future__ import annotations

from pathlib import Path

from pydantic import ConfigDict, PrivateAttr, field_validator, model_validator

from common.geometry.map_file import MapFileError, load_obstacles
from common.geometry.occupancy import ObstacleMap
from common.runtime.settings import AdvancedBlock, setting
from services.tracker.core import RobustParams, ScoreModel
from services.tracker.core.cues.classifier import ClassifierParams
from services.tracker.core.cues.posture import PostureParams
from services.tracker.core.recovery import RecoveryParams
from services.tracker.core.cues.stature import StatureParams

__all__ = ["ClassifierConfig", "PostureConfig", "RecoveryConfig", "ScoreConfig", "StaticMapConfig", "StatureConfig"]

_R = RobustParams()
_SC = ScoreModel()
_CL = ClassifierParams()
_ST = StatureParams()
_PO = PostureParams()
_RE = RecoveryParams()


class ScoreConfig(AdvancedBlock):
    """How the detector's scores read as P(true person): ``sigmoid((score - center) / scale)``."""

    model_config = ConfigDict(extra="forbid")

    center: float | None = setting(_SC.center, "the detector score that means P(true person) = 0.5; none: the "
                                   "scores are not calibrated and every detection has default_p", advanced=True)
    scale: float = setting(_SC.scale, "score units per unit of log-odds", gt=0.0, advanced=True)
    default_p: float = setting(_SC.default_p, "P(true person) of every detection when center is none", gt=0.0, lt=1.0,
                               advanced=True)
    birth_score: float | None = setting(_SC.birth_score, "detections scoring below this update tracks but never "
                                        "start one (perception track --birth-score); none: all may", advanced=True)

    max_is_person: float = setting(_SC.max_is_person, "the most this detector's own IsPerson belief of a track may "
                                   "reach; below confirm_is_person it never confirms a track alone (a laser's legs)",
                                   gt=0.5, le=1.0, advanced=True)
    is_person_tau_s: float | None = setting(_SC.is_person_tau_s, "time constant of this detector's IsPerson "
                                            "belief's drift back to 0.5; none: is_person_tau_s", unit="s", gt=0.0,
                                            advanced=True)

    def model(self) -> ScoreModel:
        return ScoreModel(self.center, self.scale, self.default_p, self.birth_score, self.max_is_person,
                          self.is_person_tau_s)


class ClassifierConfig(AdvancedBlock):
    """Basso/Munaro's online per-track appearance classifiers (services/tracker/core/cues/classifier.py)."""

    model_config = ConfigDict(extra="forbid")

    enabled: bool = setting(True, "train an online appearance classifier per track (Basso/Munaro) and weigh its "
                            "log-odds in the association and the ID memory's recovery")
    rate: float = setting(_CL.rate, "its SGD step", gt=0.0, advanced=True)
    l2: float = setting(_CL.l2, "its weight decay per step", ge=0.0, lt=1.0, advanced=True)
    clip: float = setting(_CL.clip, "bound on a classifier's log-odds", gt=0.0, advanced=True)
    weight: float = setting(_CL.weight, "weight of its log-odds in the association and the recovery", ge=0.0,
                            advanced=True)

    def params(self) -> ClassifierParams | None:
        return ClassifierParams(self.rate, self.l2, self.clip, self.weight) if self.enabled else None


class StatureConfig(AdvancedBlock):
    """The person's stature as a cue, a soft biometric (services/tracker/core/cues/stature.py)."""

    model_config = ConfigDict(extra="forbid")

    enabled: bool = setting(True, "learn each track's stature from its detections' heights and weigh new "
                            "detections against it")
    noise_m: float = setting(_ST.noise_m, "one height measurement's std", unit="m", gt=0.0, le=0.5, advanced=True)
    population_mean_m: float = setting(_ST.population_mean_m, "adults' mean stature: a stranger's", unit="m", gt=0.5,
                                       lt=2.5, advanced=True)
    population_sd_m: float = setting(_ST.population_sd_m, "adults' stature std", unit="m", gt=0.0, le=0.5,
                                     advanced=True)
    outlier_low: float = setting(_ST.outlier_low, "share of measurements lower than the stature (sitting high, a bent "
                                 "or hidden head)", gt=0.0, lt=1.0, advanced=True)
    low_range_m: float = setting(_ST.low_range_m, "how much lower they reach", unit="m", gt=0.0, le=2.0, advanced=True)
    outlier_high: float = setting(_ST.outlier_high, "share of measurements higher than the stature (a raised arm, a "
                                  "hat)", gt=0.0, lt=1.0, advanced=True)
    high_range_m: float = setting(_ST.high_range_m, "how much higher they reach", unit="m", gt=0.0, le=2.0,
                                  advanced=True)
    gate_m: float = setting(_ST.gate_m, "a learnt stature ignores measurements this far off it", unit="m", gt=0.0,
                            advanced=True)
    min_samples: int = setting(_ST.min_samples, "measurements before a track's stature counts", ge=1, advanced=True)
    window: int = setting(_ST.window, "the running mean's memory, in measurements (at least min_samples)", ge=1,
                          advanced=True)
    clip: float = setting(_ST.clip, "bound on the stature's log-odds", gt=0.0, advanced=True)
    weight: float = setting(_ST.weight, "weight of its log-odds in the association", ge=0.0, advanced=True)

    @model_validator(mode="after")
    def _window(self) -> StatureConfig:
        if self.window < self.min_samples:
            raise ValueError(f"window ({self.window}) must be at least min_samples ({self.min_samples})")
        if self.outlier_low + self.outlier_high >= 1:
            raise ValueError("outlier_low + outlier_high must be below 1")
        return self

    def params(self) -> StatureParams | None:
        return StatureParams(**self.model_dump(exclude={"enabled"})) if self.enabled else None


class StaticMapConfig(AdvancedBlock):
    """The robot's static map, its laser's walls and furniture (services/tracker/README.md, *How
    it works*): no track is born on an obstacle. Read when the settings are loaded."""

    model_config = ConfigDict(extra="forbid")

    path: Path | None = setting(None, "a ROS map YAML file (map_server's, Nav2 map_saver's, slam_toolbox's) in the "
                                "tracking frame (--static-map): no track is born on its walls and furniture; none: no "
                                "map file")
    birth_clearance_m: float = setting(_R.birth_clearance_m, "no track is born this near an obstacle of the map "
                                       "(about a localization error)", unit="m", ge=0.0, le=1.0, advanced=True)
    topic: bool = setting(True, "without a path: take the map from the static_map stream (the ros2 node's /map, as "
                          "Nav2's map_server or slam_toolbox publish it)", advanced=True)
    min_obstacle_m: float = setting(0.3, "occupied areas shorter than this on both sides are no obstacle: chair and "
                                    "table legs, posts (a detection of someone behind a chair lands among its legs)",
                                    unit="m", ge=0.0, le=5.0, advanced=True)
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


class PostureConfig(AdvancedBlock):
    """The TU Ilmenau framework's posture and orientation filters (services/tracker/core/cues/posture.py)."""

    model_config = ConfigDict(extra="forbid")

    enabled: bool = setting(True, "estimate each track's posture (standing, sitting, lying) and orientation (TU "
                            "Ilmenau's filters), the detectors' posture reports as evidence; published, not "
                            "weighed in the association")
    posture_tau_s: float = setting(_PO.posture_tau_s, "time constant of the posture's drift to unknown", unit="s",
                                   gt=0.0, advanced=True)
    orientation_tau_s: float = setting(_PO.orientation_tau_s, "time constant of the orientation's drift to unknown",
                                       unit="s", gt=0.0, advanced=True)
    min_speed: float = setting(_PO.min_speed, "walking slower says nothing of the orientation", unit="m/s", ge=0.0,
                               advanced=True)
    kappa_per_mps: float = setting(_PO.kappa_per_mps, "von Mises concentration of the walking direction per m/s of "
                                   "speed", gt=0.0, advanced=True)
    max_kappa: float = setting(_PO.max_kappa, "the concentration's cap", gt=0.0, advanced=True)
    reported_likelihood: list[list[float]] = setting(
        default_factory=lambda: [list(r) for r in _PO.reported_likelihood], min_length=3, max_length=3, advanced=True,
        description="P(a detector reports standing / sitting / lying | the person stands, sits, lies): one row per "
                    "report; rows of equal values ignore the detector")

    @model_validator(mode="after")
    def _valid(self) -> PostureConfig:
        PostureParams(reported_likelihood=tuple(tuple(r) for r in self.reported_likelihood))  # type: ignore[arg-type]
        return self

    def params(self) -> PostureParams | None:
        if not self.enabled:
            return None
        return PostureParams(self.posture_tau_s, self.orientation_tau_s, self.min_speed, self.kappa_per_mps,
                             self.max_kappa, tuple(tuple(r) for r in self.reported_likelihood))  # type: ignore[misc]


class RecoveryConfig(AdvancedBlock):
    """The ID memory's open-set decision (services/tracker/core/recovery.py)."""

    model_config = ConfigDict(extra="forbid")

    p_new: float = setting(_RE.p_new, "prior that a newly confirmed person is someone new", gt=0.0, lt=1.0,
                           advanced=True)
    p_recover: float = setting(_RE.p_recover, "posterior a remembered person needs to get their ID back", gt=0.0,
                               lt=1.0, advanced=True)
    p_undo: float = setting(_RE.p_undo, "during the check after a recovery, a recovery whose posterior falls below "
                            "this is undone (at most p_recover)", gt=0.0, lt=1.0, advanced=True)
    max_speed: float = setting(_RE.max_speed, "fastest walk: a remembered person farther from where they were lost "
                               "than this speed reaches is no candidate", unit="m/s", gt=0.0, advanced=True)
    n_sigma: float = setting(_RE.n_sigma, "position standard deviations allowed on top of that walk", ge=0.0,
                             advanced=True)
    probation_s: float = setting(_RE.probation_s, "how long a recovery is checked again; 0: never undone", unit="s",
                                 ge=0.0, advanced=True)
    check_period_s: float = setting(_RE.check_period_s, "how often it is checked in that time", unit="s", gt=0.0,
                                    advanced=True)
    compete: bool = setting(_RE.compete, "a detection near a coasting track, or near a confirmed one whose person it "
                            "does not look like, that looks like a remembered person known to be someone else counts "
                            "that as an alternative", advanced=True)
    left_weight: float = setting(_RE.left_weight, "prior weight of a remembered person who walked out of the cameras' "
                                 "view, against one lost inside it: below 1 for an open place, whose people seldom "
                                 "turn straight back (the pets-site preset: 0.3); 1: no difference", gt=0.0, le=1.0)
    exit_horizon_s: float = setting(_RE.exit_horizon_s, "a person walked out when their walk from the last fix in "
                                    "view left it within this time", unit="s", ge=0.0, advanced=True)

    @model_validator(mode="after")
    def _undo_below_recover(self) -> RecoveryConfig:
        if not self.p_undo <= self.p_recover:
            raise ValueError(f"p_undo ({self.p_undo}) must not exceed p_recover ({self.p_recover})")
        return self

    def params(self) -> RecoveryParams:
        return RecoveryParams(**self.model_dump())
