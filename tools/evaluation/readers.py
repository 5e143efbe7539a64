"""Readers of the files ``perception evaluate`` compares, with errors naming file, line and column.

- Tracking CSV (header row, extra columns ignored, any column order):
  ground truth ``frame,id,x,y,z``; tracks ``frame,stamp,id,x,y,z`` as written by
  ``perception track`` (``stamp`` is not needed, so a GT file also reads as tracks).
- MOTChallenge 2-D (no header): ``frame,id,left,top,width,height[,conf,...]`` in pixels;
  ground-truth rows with ``conf < 1`` are dropped (MOTChallenge's "ignore" rows).
"""

from __future__ import annotations

import csv
from dataclasses import dataclass
from pathlib import Path
from typing import Iterator

import numpy as np
from numpy.typing import ArrayLike, NDArray

__all__ = ["EvaluationInputError", "TrackTable", "read_motchallenge", "read_table", "read_tracking_csv"]

TRACKING_COLUMNS = ("frame", "id", "x", "y", "z")
MOT_COLUMNS = ("frame", "id", "left", "top", "width", "height", "conf")


class EvaluationInputError(ValueError):
    """A file that cannot be evaluated; the message names the file and, where known, line and column."""


@dataclass(frozen=True)
class TrackTable:
    """One file's rows, stably sorted by frame (file order kept within a frame).

    frames (K,) int64, ids (K,) int64, values (K, D) float64: D = 2 or 3 positions in
    metres, or D = 4 boxes (left, top, width, height) in pixels.
    """

    path: Path
    frames: NDArray[np.int64]
    ids: NDArray[np.int64]
    values: NDArray[np.float64]

    @classmethod
    def from_arrays(cls, frames: ArrayLike, ids: ArrayLike, values: ArrayLike, path: Path | None = None) -> TrackTable:
        """A table from in-memory rows: frames (K,), ids (K,), values (K, D); sorted stably by frame."""
        f = np.asarray(frames, dtype=np.int64).reshape(-1)
        i = np.asarray(ids, dtype=np.int64).reshape(-1)
        v = np.asarray(values, dtype=np.float64)
        v = v.reshape(f.size, -1) if f.size else v.reshape(0, v.shape[-1] if v.ndim == 2 else 0)
        if i.size != f.size:
            raise ValueError(f"{f.size} frames but {i.size} ids")
        order = np.argsort(f, kind="stable")
        return cls(path=path or Path("<memory>"), frames=f[order], ids=i[order], values=np.ascontiguousarray(v[order]))

    def __len__(self) -> int:
        return int(self.frames.size)

    def frame_slices(self) -> dict[int, slice]:
        """Frame number -> slice of its rows."""
        frames, starts = np.unique(self.frames, return_index=True)
        ends = np.append(starts[1:], self.frames.size)
        return {int(f): slice(int(s), int(e)) for f, s, e in zip(frames, starts, ends)}


def _rows(path: Path) -> Iterator[tuple[int, list[str]]]:
    """(line number, cells) of the non-blank lines of ``path``."""
    try:
        handle = path.open(newline="", encoding="utf-8")
    except OSError as exc:
        raise EvaluationInputError(f"{path}: cannot open ({exc.strerror})") from exc
    with handle:
        try:
            for number, cells in enumerate(csv.reader(handle), start=1):
                if cells and any(c.strip() for c in cells):
                    yield number, [c.strip() for c in cells]
        except (UnicodeDecodeError, csv.Error) as exc:
            raise EvaluationInputError(f"{path}: not a readable CSV text file ({exc})") from exc


def _number(path: Path, line: int, column: str, text: str, integer: bool) -> float:
    try:
        value = float(text)
    except ValueError:
        raise EvaluationInputError(f"{path}:{line}: column {column!r}: {text!r} is not a number") from None
    if not np.isfinite(value):
        raise EvaluationInputError(f"{path}:{line}: column {column!r}: {text!r} is not a finite number")
    if integer and value != int(value):
        raise EvaluationInputError(f"{path}:{line}: column {column!r}: {text!r} is not an integer")
    return value


def _table(path: Path, rows: list[tuple[int, list[float]]], width: int) -> TrackTable:
    """Build the table from (line, [frame, id, values...]) rows of ``width`` numbers; rejects an ID twice in a frame."""
    data = np.array([r for _, r in rows], dtype=np.float64).reshape(len(rows), width)
    lines = np.array([n for n, _ in rows], dtype=np.int64)
    order = np.argsort(data[:, 0], kind="stable") if rows else np.empty(0, dtype=np.intp)
    data, lines = data[order], lines[order]
    frames = data[:, 0].astype(np.int64)
    ids = data[:, 1].astype(np.int64)
    if frames.size:
        pair_order = np.lexsort((lines, ids, frames))
        f, i = frames[pair_order], ids[pair_order]
        dup = np.flatnonzero((f[1:] == f[:-1]) & (i[1:] == i[:-1]))
        if dup.size:
            first, second = lines[pair_order[dup[0]]], lines[pair_order[dup[0] + 1]]
            raise EvaluationInputError(
                f"{path}:{second}: ID {i[dup[0]]} appears twice in frame {f[dup[0]]} (first on line {first})")
    return TrackTable(path=path, frames=frames, ids=ids, values=np.ascontiguousarray(data[:, 2:]))


def read_tracking_csv(path: Path, dims: int = 2) -> TrackTable:
    """Read a tracking CSV (``frame,id,x,y,z`` at least, with a header row); keep x, y (and z if dims = 3)."""
    if dims not in (2, 3):
        raise ValueError(f"dims must be 2 or 3, got {dims}")
    rows = _rows(path)
    first = next(rows, None)
    if first is None:
        raise EvaluationInputError(f"{path}: empty file; expected a header row with {','.join(TRACKING_COLUMNS)}")
    _, header = first
    index = {name.lower(): k for k, name in enumerate(header)}
    missing = [c for c in TRACKING_COLUMNS if c not in index]
    if missing:
        raise EvaluationInputError(
            f"{path}:1: header lacks column(s) {', '.join(missing)} (found: {','.join(header)}); "
            f"expected at least {','.join(TRACKING_COLUMNS)}")
    wanted = ("frame", "id", "x", "y", "z")[: 2 + dims]
    cols = [index[c] for c in wanted]
    parsed: list[tuple[int, list[float]]] = []
    for line, cells in rows:
        if len(cells) < len(header):
            raise EvaluationInputError(f"{path}:{line}: {len(cells)} columns, the header has {len(header)}")
        parsed.append((line, [_number(path, line, name, cells[k], integer=name in ("frame", "id"))
                              for name, k in zip(wanted, cols)]))
    return _table(path, parsed, len(wanted))


def read_motchallenge(path: Path, ground_truth: bool) -> TrackTable:
    """Read a MOTChallenge 2-D file; for ground truth keep only rows with ``conf >= 1``."""
    parsed: list[tuple[int, list[float]]] = []
    for line, cells in _rows(path):
        if len(cells) < 6:
            raise EvaluationInputError(
                f"{path}:{line}: {len(cells)} columns; MOTChallenge rows are frame,id,left,top,width,height,conf,...")
        values = [_number(path, line, name, cells[k], integer=k < 2) for k, name in enumerate(MOT_COLUMNS[:6])]
        if ground_truth and len(cells) > 6 and _number(path, line, "conf", cells[6], integer=False) < 1:
            continue
        parsed.append((line, values))
    return _table(path, parsed, 6)


def read_table(path: Path, fmt: str, ground_truth: bool, dims: int = 2) -> TrackTable:
    """Read ``path`` in format ``"tracks"`` or ``"motchallenge"``."""
    if fmt == "tracks":
        return read_tracking_csv(path, dims)
    if fmt == "motchallenge":
        return read_motchallenge(path, ground_truth)
    raise ValueError(f"unknown format {fmt!r} (expected 'tracks' or 'motchallenge')")
