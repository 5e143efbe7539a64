"""Top-down pictures of tracks against ground truth, one panel per sequence (matplotlib).

Each panel draws the ground-truth people's paths in grey, the tracker's paths in a
colour per track ID (the live page's colours), and marks where the evaluation counted an
ID switch (a star), a miss (a grey cross at the person) and a false positive (a red
ring at the track). The title holds the sequence's Table II figures. Box formats
(MOTChallenge) are drawn by box centre in image coordinates.

matplotlib is imported only when a plot is drawn (the ``view`` extra).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from tools.evaluation.metrics import ClearMot, FrameEvents
from tools.evaluation.readers import TrackTable
from tools.drawing.tracks import colour_rgb

__all__ = ["PlotUnavailable", "SequencePlot", "plot_sequences"]


class PlotUnavailable(RuntimeError):
    """matplotlib is not installed."""


@dataclass
class SequencePlot:
    """What one panel shows: the tables, the result and the events by frame (pass
    ``on_frame`` to ``evaluate_tables`` and keep its result in ``result``)."""

    name: str
    gt: TrackTable
    hyp: TrackTable
    result: ClearMot | None = None
    events: dict[int, FrameEvents] = field(default_factory=dict)

    def on_frame(self, frame: int, events: FrameEvents) -> None:
        self.events[frame] = events


def _xy(table: TrackTable) -> np.ndarray:
    """(K, 2) points: positions' (x, y), or boxes' centres."""
    v = table.values
    if v.shape[1] == 4:
        return np.stack([v[:, 0] + v[:, 2] / 2, v[:, 1] + v[:, 3] / 2], axis=1)
    return v[:, :2]


def _position(table: TrackTable, xy: np.ndarray, frame: int, ident: int) -> np.ndarray | None:
    rows = np.nonzero((table.frames == frame) & (table.ids == ident))[0]
    return xy[rows[0]] if rows.size else None


def _title(seq: SequencePlot) -> str:
    r = seq.result
    if r is None:
        return seq.name
    return (f"{seq.name}: MOTA {100 * r.mota:.1f}%  MOTP {r.motp:.3f}\n"
            f"misses {r.percent(r.misses):.1f}%  FP {r.percent(r.false_positives):.1f}%  "
            f"IDSW {r.id_switches} ({r.percent(r.id_switches):.2f}%)  recall err {r.recall_errors}")


def _panel(ax: object, seq: SequencePlot) -> None:
    gt_xy, hyp_xy = _xy(seq.gt), _xy(seq.hyp)
    for ident in np.unique(seq.gt.ids):
        pts = gt_xy[seq.gt.ids == ident]
        ax.plot(pts[:, 0], pts[:, 1], color="0.75", lw=4, alpha=0.6, solid_capstyle="round", zorder=1)  # type: ignore[attr-defined]
    for ident in np.unique(seq.hyp.ids):
        pts = hyp_xy[seq.hyp.ids == ident]
        colour = tuple(c / 255 for c in colour_rgb(int(ident)))
        ax.plot(pts[:, 0], pts[:, 1], color=colour, lw=1.2, zorder=2)  # type: ignore[attr-defined]
        ax.annotate(str(int(ident)), pts[-1], color=colour, fontsize=7, zorder=5)  # type: ignore[attr-defined]
    misses, fps, switches = [], [], []
    for frame, ev in seq.events.items():
        misses += [p for o in ev.misses if (p := _position(seq.gt, gt_xy, frame, o)) is not None]
        fps += [p for h in ev.false_positives if (p := _position(seq.hyp, hyp_xy, frame, h)) is not None]
        switches += [p for o, _, _ in ev.switches if (p := _position(seq.gt, gt_xy, frame, o)) is not None]
    for pts, kw in ((misses, {"marker": "x", "color": "0.45", "s": 10, "label": f"miss ({len(misses)})"}),
                    (fps, {"marker": "o", "facecolors": "none", "edgecolors": "#d62728", "s": 14,
                           "label": f"false positive ({len(fps)})"}),
                    (switches, {"marker": "*", "color": "black", "s": 90, "label": f"ID switch ({len(switches)})"})):
        arr = np.array(pts).reshape(-1, 2)
        ax.scatter(arr[:, 0], arr[:, 1], zorder=4, linewidths=1.0, **kw)  # type: ignore[attr-defined]
    ax.plot([], [], color="0.75", lw=4, label="ground truth")  # type: ignore[attr-defined]
    ax.set_title(_title(seq), fontsize=9)  # type: ignore[attr-defined]
    ax.set_aspect("equal", adjustable="datalim")  # type: ignore[attr-defined]
    ax.grid(True, lw=0.3)  # type: ignore[attr-defined]
    if seq.gt.values.shape[1] == 4:
        ax.invert_yaxis()  # type: ignore[attr-defined]
        ax.set_xlabel("u (px)")  # type: ignore[attr-defined]
        ax.set_ylabel("v (px)")  # type: ignore[attr-defined]
    else:
        ax.set_xlabel("x (m)")  # type: ignore[attr-defined]
        ax.set_ylabel("y (m)")  # type: ignore[attr-defined]
    ax.legend(fontsize=7, loc="best")  # type: ignore[attr-defined]


def plot_sequences(sequences: list[SequencePlot], out: Path | str, dpi: int = 110) -> Path:
    """Draw one panel per sequence into the PNG ``out``; returns its path."""
    try:
        from matplotlib.figure import Figure
    except ImportError as exc:
        raise PlotUnavailable("plots need matplotlib: pip install 'people-perception[view]'") from exc
    if not sequences:
        raise ValueError("no sequence to plot")
    cols = min(3, len(sequences))
    rows = math.ceil(len(sequences) / cols)
    fig = Figure(figsize=(5.5 * cols, 5.2 * rows), layout="constrained")
    axes = fig.subplots(rows, cols, squeeze=False)
    for ax, seq in zip(axes.flat, sequences):
        _panel(ax, seq)
    for ax in list(axes.flat)[len(sequences):]:
        ax.set_visible(False)
    out = Path(out)
    out.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(out, dpi=dpi)
    return out
