"""What a cue of the robust tracker is: :class:`Cue`, the frame's evidence it reads
(:class:`Pairing`), and the per-track state it may keep in the track table
(:class:`~services.tracker.core.tracks.Columns`).

A cue gives every (detection, track) pair of a frame a log-odds that the pair is the same
person (0: no information; the TU Ilmenau framework's Bayesian product, Eq 1: the cues' log-odds
add), and learns from the frame's matches. The tracker calls every cue's hooks in the order of
its cue list; a cue overrides the hooks it needs. Pure numpy; no I/O.
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
    """One frame's evidence, as every cue reads it: the detections' ``positions`` (N, 3) and their
    measurement covariances ``r`` (N, 3, 3); ``descriptors`` (N, D), None when the frame has no
    appearance (no descriptors, or no embedding model's calibration); ``has_desc`` (N,) which rows
    are described; ``u`` those rows as unit vectors (None: none); the detector's ``p_det`` (N,) as
    P(true person) and which detections are ``confident`` (may start a track). What the cues
    compute on the way for the others: ``gated`` (N, T) (the position cue's gate), ``appearance``
    (N, T) (the appearance cue's log-odds, before its weight) and ``distances`` (the squared
    descriptor distances of the pairs compared, for the galleries' insertion). ``moved``: the
    tracks' arrays are this frame's own (the predict made new ones), so a cue may write into them."""

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
    """One source of evidence about who is who. Subclasses set ``name`` and override the hooks
    they need; each hook is called with the tracker's state (its tracks, galleries and memory).

    * :meth:`columns`: its per-track state (None: it keeps none), created once with the table;
    * :meth:`predict`: the tracks moved ``dt`` seconds ahead (a cue whose state drifts in time);
    * :meth:`log_odds`: (N, T) its log-odds of every pair, or None for "no information";
    * :meth:`learn`: the frame's matches (``rows``: (2, M) detections and tracks);
    * :meth:`born`: new tracks at rows ``first`` on, one per detection of ``dets``.
    """

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
