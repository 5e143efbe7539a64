"""The robust profile's settings (services/tracker/README.md, *How it works*, explains them)."""

from __future__ import annotations

from dataclasses import dataclass, field

from common.geometry.occupancy import ObstacleMap
from services.tracker.core.cues.classifier import ClassifierParams
from services.tracker.core.cues.posture import PostureParams
from services.tracker.core.recovery import RecoveryParams
from services.tracker.core.cues.stature import StatureParams
from services.tracker.core.types import AppearanceModel, ScoreModel

__all__ = ["RobustParams"]

_F3 = tuple[float, float, float]


@dataclass(frozen=True)
class RobustParams:
    """The robust profile's settings and their defaults (README of the tracker, *Settings*: what
    each one does). Their ranges are checked where they are read, services/tracker/profiles.py's
    RobustConfig (the only builder outside the tests)."""

    q_accel: float = 3.0  # m^2/s^3, white acceleration on x and y
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
    view_margin: float = 0.1
    max_coast_s: float = 2.0
    max_position_var: float = 4.0  # m^2, trace of the (x, y) covariance
    #: the two limits out of every camera's view, where a miss says nothing (a blind stretch between views)
    max_coast_unseen_s: float = 2.0
    max_position_var_unseen: float = 4.0
    handover_gate_sq: float | None = None
    #: two people's centres are never closer than this (m): a second report of one (a split cluster)
    birth_separation_m: float = 0.3
    #: the robot's static map: no track is born within ``birth_clearance_m`` of an obstacle
    obstacles: ObstacleMap | None = None
    birth_clearance_m: float = 0.1
    gallery_size: int = 100
    memory_size: int = 500
    #: the cues' own settings (core/cues/, and core/recovery.py for the ID memory's); None: that cue is off
    classifier: ClassifierParams | None = field(default_factory=ClassifierParams)
    posture: PostureParams | None = field(default_factory=PostureParams)
    stature: StatureParams | None = field(default_factory=StatureParams)
    recovery: RecoveryParams = field(default_factory=RecoveryParams)
