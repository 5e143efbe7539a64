"""The confidence cue: the detector's score read as P(true person) (the robust profile's
:class:`~services.tracker.core.types.ScoreModel`), the same for every track a detection is
paired with: a confident detection prefers a track to "clutter or someone new"."""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from services.tracker.core.cues.base import Cue, Pairing

if TYPE_CHECKING:
    from services.tracker.core.tracks import RobustTrackerState

__all__ = ["ConfidenceCue", "logit"]


def logit(p: np.ndarray | float) -> np.ndarray:
    p = np.minimum(np.maximum(p, 1e-6), 1 - 1e-6)  # np.clip's values, without its dispatch
    return np.log(p / (1.0 - p))


class ConfidenceCue(Cue):
    """(N, 1) the log-odds of each detection's P(true person), broadcast over the tracks."""

    name = "confidence"

    def log_odds(self, pairing: Pairing, state: RobustTrackerState) -> np.ndarray:
        return logit(pairing.p_det)[:, None]
