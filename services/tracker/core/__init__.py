"""The tracker's pure core (numpy and scipy only): Kalman filter, association, galleries,
ID memory and the multi-person tracker of Pinto's thesis, sections III-C to III-E."""

from services.tracker.core.association import AppearanceGate, match
from services.tracker.core.gallery import Gallery
from services.tracker.core.identity import IdentityMemory
from services.tracker.core.tracker import FrameResult, Track, TrackStatus, Tracker, TrackerParams

__all__ = [
    "AppearanceGate",
    "FrameResult",
    "Gallery",
    "IdentityMemory",
    "Track",
    "TrackStatus",
    "Tracker",
    "TrackerParams",
    "match",
]
