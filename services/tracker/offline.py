"""Offline tracking of a detections CSV file: the formats of ``perception track`` (its
``--help`` and services/tracker/README.md, *Run it*, describe them)."""

from __future__ import annotations

import io
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from common.runtime.progress import progress
from services.tracker.config import AppearanceConfig, TrackerConfig
from services.tracker.core import TrackerCore
from services.tracker.core.types import FrameInput, FrameResult
from services.tracker.core.view import View

__all__ = ["Detections", "OUTPUT_HEADER", "Row", "read_detections", "thresholds_for", "track", "track_config",
           "write_tracks"]

INPUT_COLUMNS = ("frame", "stamp", "x", "y", "z", "score")
#: One output row: (frame, stamp, id, x, y, z, status), status "confirmed" or "coasting".
Row = tuple[int, float, int, float, float, float, str]
OUTPUT_HEADER = "frame,stamp,id,x,y,z"


class FormatError(ValueError):
    """The detections file does not follow the format; the message says where."""


@dataclass
class Detections:
    """A detections file: ``frames`` (M,) int64, ``stamps`` (M,) s, ``positions`` (M, 3),
    ``scores`` (M,), ``descriptors`` (M, D) float32 or None."""

    frames: np.ndarray
    stamps: np.ndarray
    positions: np.ndarray
    scores: np.ndarray
    descriptors: np.ndarray | None


def read_detections(path: str | Path) -> Detections:
    """Parse and validate a detections CSV file (raises :class:`FormatError`)."""
    try:
        text = Path(path).read_bytes().decode("utf-8")
    except UnicodeDecodeError as exc:
        raise FormatError(f"{path}: not a text file (expected a CSV file with the header "
                          f"{','.join(INPUT_COLUMNS)}[,e0,e1,...])") from exc
    first, _, body = text.partition("\n")
    header = [h.strip() for h in first.strip().split(",")]
    if tuple(header[:6]) != INPUT_COLUMNS:
        raise FormatError(f"{path}:1: the header must start with {','.join(INPUT_COLUMNS)}, got {first.strip()!r}")
    extra = header[6:]
    if extra != [f"e{i}" for i in range(len(extra))]:
        raise FormatError(f"{path}: columns after 'score' must be e0,e1,...,e{len(extra) - 1} in order, got {','.join(extra)}")
    try:
        data = np.loadtxt(io.StringIO(body), delimiter=",", ndmin=2, dtype=np.float64) if body.strip() else np.zeros((0, len(header)))
    except ValueError as exc:
        raise FormatError(f"{path}:{_first_bad_value(body, header)}") from exc
    if data.shape[1] != len(header):
        raise FormatError(f"{path}: rows have {data.shape[1]} values, the header names {len(header)}")
    if not np.all(np.isfinite(data[:, :5])):
        raise FormatError(f"{path}: frame, stamp, x, y and z must be finite numbers")
    frames = data[:, 0]
    if np.any(frames != np.round(frames)):
        raise FormatError(f"{path}: frame numbers must be integers")
    if np.any(np.diff(frames) < 0):
        row = int(np.argmax(np.diff(frames) < 0)) + 3
        raise FormatError(f"{path}: rows must be sorted by frame (line {row} goes back)")
    descriptors = data[:, 6:].astype(np.float32) if extra else None
    if descriptors is not None and not np.all(np.isfinite(descriptors)):
        raise FormatError(f"{path}: embedding values must be finite numbers")
    return Detections(frames.astype(np.int64), data[:, 1], data[:, 2:5], data[:, 5], descriptors)


def _first_bad_value(body: str, header: list[str]) -> str:
    """``"N: what"``: the file's line number N where the rows under the header stop being numbers, and why."""
    for n, line in enumerate(body.splitlines(), 2):
        if not line.strip():
            continue
        values = [v.strip() for v in line.split(",")]
        if len(values) != len(header):
            return f"{n}: {len(values)} values, the header names {len(header)}"
        for name, value in zip(header, values):
            try:
                float(value)
            except ValueError:
                return f"{n}: {name} is {value!r}, not a number"
    return " the rows are not all numbers"


def frame_stamps(dets: Detections) -> tuple[np.ndarray, np.ndarray]:
    """Every frame number from the first to the last (F,), and its stamp (F,) in seconds: its first
    row's, else interpolated from the frame numbers (the first and the last frame have rows)."""
    if len(dets.frames) == 0:
        return np.zeros(0, np.int64), np.zeros(0)
    known, first_row = np.unique(dets.frames, return_index=True)
    all_frames = np.arange(known[0], known[-1] + 1, dtype=np.int64)
    return all_frames, np.interp(all_frames, known, dets.stamps[first_row])


def track(dets: Detections, tracker: TrackerCore, show_progress: bool = False, view: View | None = None,
          on_result: Callable[[int, FrameResult], None] | None = None) -> list[Row]:
    """Run ``tracker`` over every frame: a :data:`Row` per reported track per frame. ``show_progress``:
    a bar on a terminal; ``view``: what the fixed camera sees (e.g. a
    :class:`~services.tracker.core.view.FloorView`; None: not known); ``on_result(frame, result)``:
    called with each frame's result (e.g. its ID decisions)."""
    frames, stamps = frame_stamps(dets)
    starts = np.searchsorted(dets.frames, frames, side="left")
    ends = np.searchsorted(dets.frames, frames, side="right")
    # converted once, as the service converts each message once: each frame's input is a slice
    whole = FrameInput.of(dets.positions, dets.descriptors, None, dets.scores)
    positions, descriptors, scores = whole.positions, whole.descriptors, whole.scores
    rows: list[Row] = []
    steps = zip(frames.tolist(), stamps.tolist(), starts.tolist(), ends.tolist())
    for frame, stamp, a, b in progress(steps, total=len(frames), desc="track", unit="frame") if show_progress else steps:
        desc = descriptors[a:b] if descriptors is not None else None
        result = tracker.step(stamp, FrameInput(positions[a:b], desc, None, None, scores[a:b], view))
        if on_result is not None:
            on_result(frame, result)
        for seen in tracker.reported(result):
            x, y, z = seen.mean[:3].tolist()
            rows.append((frame, stamp, seen.id, x, y, z, seen.status.value))
    return rows


def track_config(dets: Detections, config: TrackerConfig, embedding_model: str | None = None,
                 view: View | None = None) -> list[Row]:
    """Track ``dets`` as ``perception track`` does with ``config``: descriptors, if any, with
    ``embedding_model``'s thresholds (ValueError if it has none), else position-only."""
    return track(dets, config.build_tracker(thresholds_for(dets, config, embedding_model)), view=view)


def thresholds_for(dets: Detections, config: TrackerConfig, model: str | None) -> AppearanceConfig | None:
    """The appearance thresholds of ``model`` when ``dets`` have descriptors (ValueError: none
    configured), else None: position-only."""
    if dets.descriptors is None:
        return None
    thresholds = config.thresholds(model or "")
    if thresholds is None:
        known = ", ".join(sorted(config.appearance)) or "none"
        raise ValueError(f"no appearance thresholds for embedding model {model!r} (configured: {known})")
    return thresholds


def write_tracks(path: str | Path, rows: list[Row], status: bool = False) -> None:
    """Write ``frame,stamp,id,x,y,z[,status]`` rows (stamps and positions to the microsecond / micrometre)."""
    if status:
        lines = [OUTPUT_HEADER + ",status"] + [f"{f},{s:.6f},{i},{x:.6f},{y:.6f},{z:.6f},{st}"
                                               for f, s, i, x, y, z, st in rows]
    else:
        lines = [OUTPUT_HEADER] + [f"{f},{s:.6f},{i},{x:.6f},{y:.6f},{z:.6f}" for f, s, i, x, y, z, _ in rows]
    Path(path).write_text("\n".join(lines) + "\n")
