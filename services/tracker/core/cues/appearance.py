"""The appearance cue (Pinto's thesis, Algorithm 1; the TU Ilmenau framework's bounded sample
set): the detection's descriptor against the nearest of the track's gallery, through a Fermi
function placed by the embedding model's calibrated thresholds. The galleries live in one
:class:`~services.tracker.core.bank.GalleryBank` (``state.bank``, a track's ``slot``); a matched
track learns its confident detection's descriptor."""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from services.tracker.core.cues.base import Cue, PairDistances, Pairing

if TYPE_CHECKING:
    from services.tracker.core.bank import GalleryBank
    from services.tracker.core.tracks import RobustTrackerState
    from services.tracker.core.types import AppearanceModel

__all__ = ["AppearanceCue", "PairDistances", "appearance_log_odds"]


def appearance_log_odds(model: AppearanceModel, bank: GalleryBank, slots: list[int], descriptors: np.ndarray,
                        pairs: np.ndarray) -> tuple[np.ndarray, PairDistances]:
    """(N, T) log-odds that detection d is track t by appearance: the model's distance from
    the detection's descriptor (``descriptors`` (N, D)) to the nearest descriptor of the
    track's gallery (``slots`` (T,) in ``bank``, -1: none) through a Fermi function placed by
    the model's calibrated thresholds. Only the ``pairs`` (N, T) bool are compared (0
    elsewhere: no information), in one batched product; their squared distances come back
    for the insertion that follows a match."""
    d_idx, t_idx = np.nonzero(pairs & (bank.sizes(slots) > 0)[None, :])
    d2 = bank.pair_sq_distances(np.asarray(slots, np.int64)[t_idx], descriptors[d_idx])
    out = np.zeros(pairs.shape)
    dist = model.from_euclidean(np.sqrt(d2.min(axis=1))).astype(np.float64)  # the log-odds in float64
    out[d_idx, t_idx] = model.log_odds(dist)
    return out, PairDistances(d_idx.tolist(), t_idx.tolist(), d2)


class AppearanceCue(Cue):
    """``weight`` x :func:`appearance_log_odds` of the gated pairs whose detection has a
    descriptor (no descriptor, or a track without a gallery yet: no information, so a track born
    while the embedder was down gains appearance later without an ID switch). A matched track
    learns its detection's descriptor when the detection is confident and the person not
    forgotten; a new track starts its gallery with it."""

    name = "appearance"

    def __init__(self, model: AppearanceModel, weight: float) -> None:
        self.model, self.weight = model, weight

    def log_odds(self, pairing: Pairing, state: RobustTrackerState) -> np.ndarray | None:
        if pairing.descriptors is None or pairing.u is None or pairing.gated is None:
            return None
        app, pairing.distances = appearance_log_odds(self.model, state.bank, state.tracks.slot, pairing.descriptors,
                                                     pairing.has_desc[:, None] & pairing.gated)
        pairing.appearance = app
        return self.weight * app

    def learn(self, pairing: Pairing, state: RobustTrackerState, rows: np.ndarray) -> None:
        descriptors = pairing.descriptors
        if descriptors is None or not rows.shape[1]:
            return
        t, bank = state.tracks, state.bank
        with_desc, sure, forgotten = pairing.has_desc.tolist(), pairing.confident.tolist(), t.forgotten
        learn = [(d, j) for d, j in zip(*rows.tolist()) if with_desc[d] and sure[d] and not forgotten[j]]
        if not learn:
            return
        for _, j in learn:
            if t.slot[j] < 0:
                t.slot[j] = bank.allocate(descriptors.shape[1])
        d_new, t_new = np.array([d for d, _ in learn]), np.array([j for _, j in learn])
        d2 = pairing.distances.get(d_new, t_new) if pairing.distances is not None else None
        bank.add_many(np.array([t.slot[j] for _, j in learn]), descriptors[d_new], d2)

    def born(self, pairing: Pairing, state: RobustTrackerState, first: int, dets: np.ndarray) -> None:
        descriptors = pairing.descriptors
        if descriptors is None:
            return
        t, has = state.tracks, pairing.has_desc[dets]
        rows = [first + k for k, h in enumerate(has.tolist()) if h]
        if rows:
            for j in rows:
                t.slot[j] = state.bank.allocate(descriptors.shape[1])
            state.bank.add_many(np.array([t.slot[j] for j in rows]), descriptors[dets[has]], None)
