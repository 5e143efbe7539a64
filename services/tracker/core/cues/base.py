"""What a cue of the robust tracker is: :class:`Cue`, the frame's evidence it reads
(:class:`Pairing`) and the per-track state it may keep in the track table
(:class:`~services.tracker.core.tracks.Columns`). A cue gives every (detection, track) pair a
log-odds that the pair is the same person (0: no information; the cues' log-odds add, TU
Ilmenau's Bayesian product, Eq 1) and learns from the frame's matches; the tracker calls the
cues' hooks in the order of its cue list. Pure numpy; no I/O.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

if TYPE_CHECKING:
    from services.tracker.core.tracks import Columns, RobustTrackerState
    from services.tracker.core.types import FrameInput

__all__ = ["Cue", "PairDistances", "Pairing"]


@dataclass(frozen=True)
class PairDistances:
    """The squared descriptor distances of the pairs :func:`appearance_log_odds` compared:
    ``d2[k]`` (capacity,) for the pair (``dets[k]``, ``tracks[k]``)."""

    dets: list[int]
    tracks: list[int]
    d2: np.ndarray

    def get(self, d: np.ndarray, t: np.ndarray) -> np.ndarray | None:
        """The rows of pairs (``d[k]``, ``t[k]``), or None if one of them was not compared."""
        dets, tracks = d.tolist(), t.tolist()
        if dets == self.dets and tracks == self.tracks:  # the very pairs compared (all matched)
            return self.d2
        index = dict(zip(zip(self.dets, self.tracks), range(len(self.dets))))
        rows = [index.get(pair) for pair in zip(dets, tracks)]
        return None if None in rows else self.d2[rows]


@dataclass
class Pairing:
    """One frame's evidence as every cue reads it: ``positions`` (N, 3), measurement covariances ``r``
    (N, 3, 3), ``descriptors`` (N, D) (None: no appearance: no descriptors or no calibration),
    ``has_desc`` (N,) the described rows, ``u`` those as unit vectors, ``p_det`` (N,) P(true person),
    ``confident`` (N,) (may start a track). What cues compute for the others: ``gated`` (N, T) (the
    position cue's gate), ``appearance`` (N, T) (the appearance cue's unweighted log-odds),
    ``distances`` (for the galleries' insertion). ``moved``: the tracks' arrays are this frame's own
    (the predict made new ones), so a cue may write into them."""

    stamp: float
    frame: FrameInput
    positions: np.ndarray
    r: np.ndarray
    descriptors: np.ndarray | None
    has_desc: np.ndarray
    u: np.ndarray | None
    p_det: np.ndarray
    confident: np.ndarray
    moved: bool = False
    gated: np.ndarray | None = None
    appearance: np.ndarray | None = None
    distances: PairDistances | None = None


class Cue:
    """One source of evidence about who is who: a subclass sets ``name`` and overrides the hooks it
    needs, each called with the tracker's state: :meth:`columns` (its per-track state, None: none),
    :meth:`predict` (the tracks moved ``dt`` s ahead), :meth:`log_odds` ((N, T), None: no
    information), :meth:`learn` (the matches, ``rows`` (2, M) detections and tracks), :meth:`born`
    (new tracks from row ``first`` on, one per detection of ``dets``)."""

    name = ""

    def columns(self) -> Columns | None:
        return None

    def predict(self, state: RobustTrackerState, dt: float) -> None:
        return None

    def log_odds(self, pairing: Pairing, state: RobustTrackerState) -> np.ndarray | None:
        return None

    def learn(self, pairing: Pairing, state: RobustTrackerState, rows: np.ndarray) -> None:
        return None

    def born(self, pairing: Pairing, state: RobustTrackerState, first: int, dets: np.ndarray) -> None:
        return None
