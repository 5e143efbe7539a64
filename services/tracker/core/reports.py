"""What the robust tracker shows of its tracks: :class:`~services.tracker.core.types.TrackReport`
per track for each frame's result, and :class:`TrackRow`, a full picture of a track for
inspection and tests. Pure numpy."""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from services.tracker.core.cues import posture as pose
from services.tracker.core.bank import GalleryBank
from services.tracker.core.cues.classifier import trained
from services.tracker.core.cues.stature import stature_of
from services.tracker.core.tracks import FIELDS, RobustTrackerState, TrackTable
from services.tracker.core.types import TrackStatus, TrackReport

if TYPE_CHECKING:
    from services.tracker.core.cues.posture import PostureColumns
    from services.tracker.core.cues.stature import StatureColumns

__all__ = ["TrackRow", "track_report", "track_reports", "track_rows"]


@dataclass(frozen=True)
class TrackRow:
    """A read-only picture of one track of the table (for inspection and tests): its columns,
    ``beliefs`` IsPerson's by detector, ``clf`` None while untrained and ``gallery`` None without one."""

    id: int
    status: TrackStatus
    mean: np.ndarray
    cov: np.ndarray
    first_stamp: float
    last_update: float
    confident_hits: int
    total_hits: int
    is_person: float
    beliefs: dict[str, float]
    ever_confirmed: bool
    clf: np.ndarray | None
    clf_steps: int
    forgotten: bool
    in_view: bool | None
    misses_tell: bool
    unseen_s: float
    camera: str
    posture: np.ndarray
    orientation: np.ndarray
    stature: float
    stature_n: int
    gallery: _GalleryRow | None


@dataclass(frozen=True)
class _GalleryRow:
    """A read-only picture of one track's gallery."""

    descriptors: np.ndarray

    def __len__(self) -> int:
        return len(self.descriptors)


def _posture(t: TrackTable) -> PostureColumns | None:
    return t.extra.get("posture")  # type: ignore[return-value]


def _statures(t: TrackTable) -> list[float | None]:
    cols: StatureColumns | None = t.extra.get("stature")  # type: ignore[assignment]
    if cols is None:
        return [None] * len(t)
    return [h if k else None for h, k in zip(cols.est.tolist(), cols.n.tolist())]


def track_rows(table: TrackTable, bank: GalleryBank) -> list[TrackRow]:
    """Every track of ``table`` as a :class:`TrackRow` (copies; a cue that is off shows as
    "nothing known": uniform posture and orientation, no stature, no classifier)."""
    out, poses = [], _posture(table)
    for j in range(len(table)):
        col = {name: getattr(table, name)[j] for name in FIELDS if name not in ("slot", "fix", "probation")}
        col = {k: v.copy() if isinstance(v, np.ndarray) else v for k, v in col.items()}
        b = col["beliefs"]
        col["beliefs"] = {b: col["is_person"]} if isinstance(b, str) else dict(b)  # by detector
        h, n = stature_of(table, j)
        cols = table.extra.get("classifier")
        steps = int(cols.steps[j]) if cols is not None else 0  # type: ignore[attr-defined]
        slot = table.slot[j]
        out.append(TrackRow(**col, clf=trained(table, j), clf_steps=steps,
                            posture=poses.posture[j].copy() if poses else pose.uniform(3),
                            orientation=poses.orientation[j].copy() if poses else pose.uniform(pose.ORIENTATION_BINS),
                            stature=h, stature_n=n,
                            gallery=_GalleryRow(bank.descriptors(slot)) if slot >= 0 else None))
    return out


def track_report(state: RobustTrackerState, j: int, stamp: float, status: TrackStatus, in_view: bool | None) -> TrackReport:
    """Track ``j`` as the tracker reports it at ``stamp``; posture and orientation when the
    posture cue is on. The arrays are shared: the tracker never writes into a mean, cov, posture
    or orientation array it has shown, every change makes new ones."""
    t, poses = state.tracks, _posture(state.tracks)
    h, n = stature_of(t, j)
    return TrackReport(t.id[j], status, t.mean[j], t.cov[j], t.total_hits[j], 0, max(0.0, stamp - t.first_stamp[j]),
                     t.last_update[j], state.bank.size(t.slot[j]), t.ever_confirmed[j], in_view,
                     posture=poses.posture[j] if poses else None, orientation=poses.orientation[j] if poses else None,
                     stature=h if n else None)


def track_reports(state: RobustTrackerState, stamp: float, view_known: bool) -> list[TrackReport]:
    """Every live track as :func:`track_report`; a coasting one says whether it is in view when
    the frame had a view (``view_known``)."""
    t = state.tracks
    if not t.id:
        return []
    cols = _posture(t)
    poses = zip(cols.posture, cols.orientation) if cols else ((None, None) for _ in t.id)
    coasting, make, sizes = TrackStatus.COASTING, TrackReport.of_fields, state.bank.n.tolist()
    return [make(i, s, m, c, h, 0, max(0.0, stamp - first), last, sizes[slot] if slot >= 0 else 0, ever,
                 flag if view_known and s is coasting else None, pp, o, body)
            for i, s, m, c, h, first, last, slot, ever, flag, (pp, o), body
            in zip(t.id, t.status, t.mean, t.cov, t.total_hits, t.first_stamp, t.last_update, t.slot, t.ever_confirmed,
                   t.in_view, poses, _statures(t))]
