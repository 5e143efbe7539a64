"""The one interface of a tracker core: what the service, ``perception track``, the config and
the benchmarks may ask of either profile (:class:`~services.tracker.core.thesis.ThesisTracker`,
:class:`~services.tracker.core.robust.RobustTracker`), so nothing outside the core tells them
apart; each implements every member. A frame goes in as a
:class:`~services.tracker.core.types.FrameInput`, the static map with the settings or with a frame;
what the ID memory's file keeps beside the galleries, as one
:class:`~services.tracker.core.types.KeptMemory`.
"""

from __future__ import annotations

from typing import Protocol, TypeVar

from services.tracker.core.identity import IdentityMemory
from services.tracker.core.types import AppearanceModel, FrameInput, FrameResult, KeptMemory, TrackReport

__all__ = ["TrackerCore"]

State = TypeVar("State")


class TrackerCore(Protocol[State]):
    """A multi-person tracker: one :meth:`step` per frame, in stamp order. ``State`` is the
    profile's whole state, as :meth:`snapshot` gives it."""

    #: the ID memory (Algorithm 2 of Pinto's thesis): remembered people's descriptors
    memory: IdentityMemory

    def step(self, stamp: float, frame: FrameInput) -> FrameResult:
        """Process one frame (``stamp`` in seconds, never older than the last one)."""
        ...

    def reported(self, result: FrameResult) -> list[TrackReport]:
        """What to output of ``result``: the profile's reported tracks."""
        ...

    def predict_reports(self, reports: list[TrackReport], dt: float) -> list[TrackReport]:
        """``reports`` moved ``dt`` seconds ahead by the motion model (output at a fixed rate
        between frames); the tracker's state does not change."""
        ...

    def set_appearance(self, model: AppearanceModel | None) -> None:
        """Use the embedding model's calibrated thresholds (None: position-only association)."""
        ...

    def forget(self, track_id: int) -> dict[str, int | bool]:
        """Forget a person: their remembered appearance goes, a live track with that ID keeps
        its ID but loses its appearance and learns none. Returns ``descriptors`` (removed),
        ``classifier`` (whether one was removed), ``live_track`` (whether one was cleared)."""
        ...

    def restart_clock(self) -> list[int]:
        """End every live track and forget the clock, keeping the ID memory (a clock jump);
        returns the ended IDs."""
        ...

    def live_ids(self) -> set[int]:
        """The IDs of the live tracks."""
        ...

    def snapshot(self) -> State:
        """The whole state, for :meth:`restore` (which leaves it valid for another restore)."""
        ...

    def restore(self, state: State) -> None:
        ...

    def export_memory(self) -> KeptMemory:
        """What the ID memory's file keeps beside :attr:`memory`: the live tracks' galleries, the
        trained classifiers, the recovery's state (where and when each person was last seen)."""
        ...

    def import_memory(self, kept: KeptMemory) -> None:
        """Take back what :meth:`export_memory` gave (a part that is None is left as it is; the
        live galleries are already in the memory the file was read into). ValueError when the
        recovery's state is inconsistent."""
        ...
