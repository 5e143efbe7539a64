"""Ground-truth CSV for ``perception evaluate``: ``frame,id,x,y,z`` (map frame, metres).

``frame`` is the camera frame's ``header.seq``; only people that count as ground-truth
objects in that frame (``counted``: visible enough) are written.
"""

from __future__ import annotations

import csv
from pathlib import Path
from typing import Iterable, TextIO

from common.messages.schemas import PeopleGroundTruth

__all__ = ["GT_COLUMNS", "GroundTruthCsv", "groundtruth_rows", "write_groundtruth_csv"]

GT_COLUMNS = ("frame", "id", "x", "y", "z")


def groundtruth_rows(msg: PeopleGroundTruth) -> list[tuple[int, int, float, float, float]]:
    """(frame, id, x, y, z) of the counted people of one message."""
    return [
        (msg.header.seq, p.id, float(p.position[0]), float(p.position[1]), float(p.position[2]))
        for p in msg.people
        if p.counted
    ]


class GroundTruthCsv:
    """Writes rows as messages arrive; use as a context manager."""

    def __init__(self, path: Path) -> None:
        self.path = Path(path)
        self._handle: TextIO = self.path.open("w", newline="", encoding="utf-8")
        self._writer = csv.writer(self._handle)
        self._writer.writerow(GT_COLUMNS)
        self.rows = 0

    def add(self, msg: PeopleGroundTruth) -> None:
        for frame, pid, x, y, z in groundtruth_rows(msg):
            self._writer.writerow((frame, pid, f"{x:.4f}", f"{y:.4f}", f"{z:.4f}"))
            self.rows += 1

    def close(self) -> None:
        self._handle.close()

    def __enter__(self) -> GroundTruthCsv:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


def write_groundtruth_csv(path: Path, messages: Iterable[PeopleGroundTruth]) -> int:
    """Write the counted people of ``messages`` to ``path``; returns the number of rows."""
    with GroundTruthCsv(path) as out:
        for msg in messages:
            out.add(msg)
        return out.rows
