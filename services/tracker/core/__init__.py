"""The tracker's pure core (numpy and scipy only): one interface (:class:`TrackerCore`) and
its two profiles, the robust tracker (the default) and the multi-person tracker of Pinto's
thesis (sections III-C to III-E), with their Kalman filters, association, galleries and ID
memory."""

from services.tracker.core.association import AppearanceGate, match
from services.tracker.core.gallery import Gallery
from services.tracker.core.identity import IdentityMemory
from services.tracker.core.protocol import TrackerCore
from services.tracker.core.robust import RobustParams, RobustTracker
from services.tracker.core.thesis import ThesisTrack, ThesisTracker, ThesisParams
from services.tracker.core.types import (
    AppearanceModel,
    FrameInput,
    FrameResult,
    ScoreModel,
    TrackStatus,
    TrackReport,
)

__all__ = [
    "AppearanceGate",
    "AppearanceModel",
    "FrameInput",
    "FrameResult",
    "Gallery",
    "IdentityMemory",
    "RobustParams",
    "RobustTracker",
    "ScoreModel",
    "ThesisTrack",
    "TrackStatus",
    "TrackReport",
    "ThesisTracker",
    "TrackerCore",
    "ThesisParams",
    "match",
]
