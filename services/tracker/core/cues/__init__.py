"""The robust tracker's cues, one module each (services/tracker/README.md, *How it works*, step 2);
:func:`build` lists the cues a tracker's settings turn on, in the order they are summed. Adding a
cue is its module (a :class:`~services.tracker.core.cues.base.Cue`) and one line in :func:`build`.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Protocol

from services.tracker.core.cues.appearance import AppearanceCue, PairDistances, appearance_log_odds
from services.tracker.core.cues.base import Cue, Pairing
from services.tracker.core.cues.confidence import ConfidenceCue, logit
from services.tracker.core.cues.memory import MemoryCue, memory_alternatives
from services.tracker.core.cues.classifier import OnlineClassifierCue, classifier_log_odds
from services.tracker.core.cues.position import PositionCue, measurement_covariance, position_log_odds
from services.tracker.core.cues.position import usable_covariances
from services.tracker.core.cues.posture import PostureCue
from services.tracker.core.cues.stature import StatureCue

if TYPE_CHECKING:
    from services.tracker.core.cues.classifier import ClassifierParams
    from services.tracker.core.cues.posture import PostureParams
    from services.tracker.core.cues.stature import StatureParams
    from services.tracker.core.recovery import RecoveryParams
    from services.tracker.core.types import AppearanceModel

__all__ = ["AppearanceCue", "ConfidenceCue", "Cue", "CueSettings", "MemoryCue", "OnlineClassifierCue", "PairDistances",
           "Pairing", "PositionCue", "PostureCue", "StatureCue", "appearance_log_odds", "build", "classifier_log_odds",
           "logit", "measurement_covariance", "memory_alternatives", "position_log_odds", "usable_covariances"]


class CueSettings(Protocol):
    """What the cues read of the tracker's settings (the robust profile's ``RobustParams``)."""

    new_density: float
    gate_sq: float
    appearance: AppearanceModel | None
    appearance_weight: float
    classifier: ClassifierParams | None
    stature: StatureParams | None
    posture: PostureParams | None
    recovery: RecoveryParams


def build(p: CueSettings) -> list[Cue]:
    """The cues of settings ``p``, in the order their log-odds are added (position first: its
    gate decides which pairs the others compare)."""
    model = p.appearance
    return [c for c in (
        PositionCue(p.new_density, p.gate_sq),
        AppearanceCue(model, p.appearance_weight) if model is not None else None,
        OnlineClassifierCue(p.classifier) if p.classifier is not None else None,
        ConfidenceCue(),
        StatureCue(p.stature) if p.stature is not None else None,
        PostureCue(p.posture) if p.posture is not None else None,
        MemoryCue(model, p.appearance_weight, p.recovery) if model is not None else None,
    ) if c is not None]
