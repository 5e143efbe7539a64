"""The one interface of a tracker core: what the service, ``perception track``, the config
and the benchmarks may ask of either profile (the thesis's
:class:`~services.tracker.core.tracker.Tracker`, the robust
:class:`~services.tracker.core.robust.RobustTracker`), so nothing outside the core needs
to tell them apart.

Both profiles subclass :class:`TrackerCore` explicitly and so share :meth:`TrackerCore.update`,
which converts loose arrays once into a :class:`~services.tracker.core.types.FrameInput`
and hands it to the profile's :meth:`~TrackerCore.step`.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any, Protocol

import numpy as np

from services.tracker.core.identity import IdentityMemory
from services.tracker.core.types import AppearanceModel, FrameInput, FrameResult, ScoreModel, TrackView

if TYPE_CHECKING:
    from common.geometry.occupancy import ObstacleMap
    from services.tracker.core.view import View

__all__ = ["TrackerCore"]


class TrackerCore(Protocol):
    """A multi-person tracker: one :meth:`step` per frame, in stamp order."""

    #: the ID memory (Algorithm 2 of Pinto's thesis): remembered people's descriptors
    memory: IdentityMemory

    def step(self, stamp: float, frame: FrameInput) -> FrameResult:
        """Process one frame (``stamp`` in seconds, never older than the last one)."""
        ...

    def update(self, stamp: float, positions: np.ndarray, descriptors: np.ndarray | None = None,
               measurement_cov: np.ndarray | None = None, scores: np.ndarray | None = None,
               view: View | None = None, aspects: np.ndarray | None = None,
               orientations: np.ndarray | None = None, score_model: ScoreModel | None = None,
               camera: str = "", postures: np.ndarray | None = None,
               statures: np.ndarray | None = None) -> FrameResult:
        """:meth:`step` on loose arrays (see :class:`FrameInput` for each)."""
        return self.step(stamp, FrameInput.of(positions, descriptors, measurement_cov, scores, view, aspects,
                                              orientations, score_model, camera, postures, statures))

    def reported(self, result: FrameResult) -> list[TrackView]:
        """What to output of ``result``: the profile's reported tracks."""
        ...

    def predict_views(self, views: list[TrackView], dt: float) -> list[TrackView]:
        """``views`` moved ``dt`` seconds ahead by the motion model (output at a fixed rate
        between frames); the tracker's state does not change."""
        ...

    def set_appearance(self, model: AppearanceModel | None) -> None:
        """Use the embedding model's calibrated thresholds (None: position-only association)."""
        ...

    def set_obstacles(self, obstacles: ObstacleMap | None) -> None:
        """Use a static map's obstacles: no track is born on them (robust; the thesis profile has
        no birth map and keeps none). None: no map."""
        ...

    def snapshot(self) -> Any:
        """The whole state, for :meth:`restore` (which leaves it valid for another restore)."""
        ...

    def restore(self, state: Any) -> None:
        ...

    def forget(self, track_id: int) -> dict[str, int | bool]:
        """Forget a person: their remembered appearance goes, a live track with that ID keeps
        its ID but loses its appearance and learns none. Returns ``descriptors`` (removed),
        ``classifier`` (whether one was removed), ``live_track`` (whether one was cleared)."""
        ...

    def forget_all(self) -> list[int]:
        """Forget everyone; returns the IDs."""
        ...

    def restart_clock(self) -> list[int]:
        """End every live track and forget the clock, keeping the ID memory (a clock jump);
        returns the ended IDs."""
        ...

    def live_ids(self) -> set[int]:
        """The IDs of the live tracks."""
        ...

    def live_galleries(self) -> list[tuple[int, np.ndarray]]:
        """(ID, descriptors (M, D)) to keep beside the memory: the live tracks' appearance."""
        ...

    def kept_classifiers(self) -> dict[int, np.ndarray]:
        """ID -> trained appearance classifier to keep beside the memory (none: a profile without)."""
        return {}

    def kept_recovery(self) -> dict[str, np.ndarray]:
        """What the ID memory's recovery knows, as named arrays to keep beside the memory (where
        and when each person was last detected, who was seen with whom); none: a profile without."""
        return {}

    def load_recovery(self, arrays: dict[str, np.ndarray]) -> None:
        """The recovery's state, as :meth:`kept_recovery` gave it (a profile without ignores it;
        ValueError when it is inconsistent)."""

    def load_classifiers(self, weights: dict[int, np.ndarray]) -> None:
        """The remembered people's classifiers, as :meth:`kept_classifiers` gave them (a profile
        without ignores them)."""
