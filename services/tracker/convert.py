"""Translation between messages and the core's arrays (no transport, no state)."""

from __future__ import annotations

from dataclasses import asdict

import numpy as np

from common.messages.schemas import (Embeddings, Header, IdDecisions, IdDecisionState, LocalizedDetections, TrackState,
                                     Tracks)
from services.tracker.core.types import FrameResult, IdDecision, TrackReport
from services.tracker.core.view import FieldOfView, FloorView, ScanView

__all__ = ["descriptors_for", "field_of_view", "id_decisions_message", "orientations_for", "positions_of", "track_state",
           "tracks_message"]


def field_of_view(loc: LocalizedDetections) -> FieldOfView | FloorView | ScanView | None:
    """The sensor's view at a frame, if its node sent it: a camera's pinhole view, else the view
    of a fixed camera through its floor homography, else a 2-D laser's sweep."""
    v, f, s = loc.view, loc.floor_view, loc.scan_view
    if v is not None:
        return FieldOfView(v.camera_to_frame, v.K, v.width, v.height, v.max_range_m)
    if f is not None:
        return FloorView(f.image_to_frame, f.width, f.height)
    if s is not None:
        return ScanView(s.scanner_to_frame, s.angle_min, s.angle_increment, s.ranges, s.max_range_m)
    return None


def positions_of(loc: LocalizedDetections) -> tuple[np.ndarray, np.ndarray]:
    """Positions (N, 3) and covariances (N, 3, 3) of a frame's localized detections."""
    if not loc.detections:
        return np.zeros((0, 3)), np.zeros((0, 3, 3))
    return (np.stack([d.position for d in loc.detections]).astype(np.float64),
            np.stack([d.cov for d in loc.detections]).astype(np.float64))


def descriptors_for(loc: LocalizedDetections, emb: Embeddings) -> np.ndarray:
    """Descriptors (N, D) float32 in the order of ``loc.detections``; NaN rows where the
    embedder gave none for a detection index."""
    return _per_detection(loc, emb, emb.vectors, np.full((len(loc.detections), emb.model.dim), np.nan, np.float32))


def orientations_for(loc: LocalizedDetections, emb: Embeddings | None) -> np.ndarray | None:
    """The embedder's orientation probabilities (N, 8) in the order of ``loc.detections`` (NaN rows:
    none; None without orientations or a camera view), from camera-relative bins to the tracking
    frame's (bin j centred on j * 45 degrees): camera bin k faces ``yaw + 180 + k * 45`` degrees in
    the map, ``yaw`` the optical axis's heading, a roll of the bins rounded to the nearest bin."""
    if emb is None or emb.orientation is None or loc.view is None:
        return None
    axis = loc.view.camera_to_frame[:3, 2]
    towards_camera = np.arctan2(axis[1], axis[0]) + np.pi
    shift = int(np.round(towards_camera / (np.pi / 4))) % 8
    return _per_detection(loc, emb, np.roll(emb.orientation, shift, axis=1), np.full((len(loc.detections), 8), np.nan))


def _per_detection(loc: LocalizedDetections, emb: Embeddings, rows: np.ndarray, out: np.ndarray) -> np.ndarray:
    """``out`` (N, K) with each detection's row of ``rows`` (one per embedded index of ``emb``)."""
    row_of = {int(i): r for r, i in enumerate(emb.indices.tolist())}
    for n, det in enumerate(loc.detections):
        r = row_of.get(det.index)
        if r is not None:
            out[n] = rows[r]
    return out


def track_state(view: TrackReport, appearance: bool, epoch_ns: int = 0) -> TrackState:
    """A core track as a :class:`TrackState` (core stamps are seconds since ``epoch_ns``); its
    ``appearance_available`` needs the frame's descriptors (``appearance``) and a gallery."""
    return TrackState(
        id=view.id,
        status=view.status.value,
        position=view.mean[:3].copy(),
        velocity=view.mean[3:].copy(),
        covariance=view.cov.copy(),
        last_update_ns=max(0, epoch_ns + int(round(view.last_update * 1e9))),
        hits=view.hits,
        age_s=view.age_s,
        misses=view.misses,
        appearance_available=appearance and view.gallery_size > 0,
        **({"posture": view.posture.tolist()} if view.posture is not None else {}),
        **({"orientation": view.orientation.tolist()} if view.orientation is not None else {}),
        stature_m=view.stature if view.stature is not None and 0.0 < view.stature <= 3.0 else None,
    )


def tracks_message(result: FrameResult, reported: list[TrackReport], header: Header, model: str,
                   epoch_ns: int) -> Tracks:
    """The ``reported`` tracks of ``result`` (the tracker's output: Confirmed, and coasting for
    the robust profile) as a Tracks message. Core stamps are seconds since ``epoch_ns``."""
    states = [track_state(v, result.appearance_available, epoch_ns) for v in reported]
    return Tracks(header=header, tracks=states, appearance_available=result.appearance_available, embedding_model=model)


def id_decisions_message(decisions: list[IdDecision], header: Header) -> IdDecisions:
    """The core's ID decisions of one frame as an IdDecisions message (``header``: the frame's):
    the same fields, nested alike, and each one's summary."""
    return IdDecisions(header=header, decisions=[IdDecisionState.model_validate({**asdict(d), "summary": d.summary()})
                                                 for d in decisions])
