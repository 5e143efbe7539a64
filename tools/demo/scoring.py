"""Collect the simulator's ground truth and score the tracker's output with ``evaluate``.

Frames are matched on the source frame's ``seq``: the simulator's ground truth and the
tracker's ``Tracks`` both carry the camera frame's header. Only the people the simulator
marks as ``counted`` (in view and visible enough) are ground-truth objects; a frame the
tracker published nothing for counts all its objects as misses.
"""

from __future__ import annotations

import logging
import time
from pathlib import Path
from typing import Any

import numpy as np

from common.keys import Delivery, Keys
from common.schemas import PeopleGroundTruth
from common.transport import Transport
from tools.demo.monitor import Monitor
from tools.evaluation.evaluate import evaluate_tables, format_table, make_report
from tools.evaluation.plot import PlotUnavailable, SequencePlot, plot_sequences
from tools.evaluation.readers import TrackTable

__all__ = ["GroundTruthLog", "score", "score_rows"]

log = logging.getLogger(__name__)


class GroundTruthLog:
    """Every ground-truth message of the run, by frame seq."""

    def __init__(self, transport: Transport, keys: Keys) -> None:
        self._sub = transport.subscribe(keys.groundtruth(), PeopleGroundTruth,
                                        Delivery(latest=False, queue=4096, congestion="block"))
        self.frames: dict[int, PeopleGroundTruth] = {}
        self._last_arrival = time.monotonic()

    def poll(self) -> None:
        while (got := self._sub.try_recv()) is not None:
            self.frames[got.msg.header.seq] = got.msg
            self._last_arrival = time.monotonic()

    def idle_for(self, seconds: float) -> bool:
        return time.monotonic() - self._last_arrival >= seconds


def _table(rows: list[tuple[int, int, np.ndarray]]) -> TrackTable:
    if not rows:
        return TrackTable.from_arrays(np.zeros(0, int), np.zeros(0, int), np.zeros((0, 3)))
    frames, ids, pos = zip(*rows)
    return TrackTable.from_arrays(np.array(frames), np.array(ids), np.stack(pos))


def score(gt: GroundTruthLog, monitor: Monitor, name: str, plot: Path | None = None) -> tuple[dict[str, Any], str]:
    """(metrics as a dict, Table II as text) of the run; ``plot``: also draw it there (PNG)."""
    gt_rows = [(seq, p.id, p.position) for seq, msg in gt.frames.items() for p in msg.counted()]
    hyp_rows = [(t.header.seq, tr.id, tr.position) for t in monitor.all_tracks for tr in t.tracks
                if t.header.seq in gt.frames]
    return score_rows(gt_rows, hyp_rows, name, plot)


def score_rows(gt_rows: list[tuple[int, int, np.ndarray]], hyp_rows: list[tuple[int, int, np.ndarray]],
               name: str, plot: Path | None = None) -> tuple[dict[str, Any], str]:
    """(metrics as a dict, Table II as text) of (frame, id, position) rows.

    ``plot``: also draw the tracks against the ground truth there (``perception evaluate
    --plot``'s picture); without matplotlib it is skipped with a warning.
    """
    gt, hyp = _table(gt_rows), _table(hyp_rows)
    panel = SequencePlot(name, gt, hyp)
    mot = evaluate_tables(gt, hyp, on_frame=panel.on_frame if plot is not None else None)
    if plot is not None:
        panel.result = mot
        try:
            plot_sequences([panel], plot)
        except PlotUnavailable as exc:
            log.warning("no plot of the run: %s", exc)
    report = make_report([(name, mot)])
    return report.to_dict(), format_table(report)
