"""Evaluate track files against ground truth: the Python API behind ``perception evaluate``.

>>> report = evaluate_sequences("gt/", "tracks/")          # doctest: +SKIP
>>> print(format_table(report))                            # doctest: +SKIP
"""

from __future__ import annotations

import logging
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from tools.evaluation.distances import euclidean_distances, iou_distances
from tools.evaluation.metrics import ClearMot, ClearMotAccumulator
from tools.evaluation.readers import EvaluationInputError, TrackTable, read_table

__all__ = ["FORMATS", "Report", "default_threshold", "evaluate_sequences", "evaluate_tables", "format_table",
           "make_report", "pair_sequences"]

log = logging.getLogger(__name__)

#: format -> (default threshold, inclusive gate, distance unit).
#: tracks: a match needs a ground-plane (or 3-D) distance < 1 m (seed 000, SPEC §4).
#: motchallenge: IoU >= 0.5, i.e. 1 - IoU <= 0.5, as py-motmetrics.
FORMATS: dict[str, tuple[float, bool, str]] = {
    "tracks": (1.0, False, "m"),
    "motchallenge": (0.5, True, "1-IoU"),
}
_SUFFIXES = (".csv", ".txt")


def default_threshold(fmt: str) -> float:
    return FORMATS[fmt][0]


@dataclass(frozen=True)
class Report:
    """Per-sequence results, in name order, and their total (``overall``)."""

    fmt: str
    threshold: float
    dims: int
    sequences: list[tuple[str, ClearMot]]
    overall: ClearMot

    @property
    def inclusive(self) -> bool:
        return FORMATS[self.fmt][1]

    @property
    def unit(self) -> str:
        return FORMATS[self.fmt][2]

    @property
    def match_rule(self) -> str:
        """When a GT/hypothesis pair may match, in words."""
        if self.fmt == "motchallenge":
            return f"1 - IoU <= {self.threshold:g}"
        space = "ground plane (x, y)" if self.dims == 2 else "3-D (x, y, z)"
        return f"{space} distance < {self.threshold:g} m"

    def to_dict(self) -> dict[str, object]:
        return {
            "format": self.fmt,
            "threshold": self.threshold,
            "match_rule": self.match_rule,
            "dims": self.dims if self.fmt == "tracks" else 2,
            "sequences": {name: result.to_dict() for name, result in self.sequences},
            "overall": self.overall.to_dict(),
        }


def evaluate_tables(gt: TrackTable, hyp: TrackTable, fmt: str = "tracks", threshold: float | None = None) -> ClearMot:
    """CLEAR MOT of one sequence over the union of the frames of both tables."""
    threshold = default_threshold(fmt) if threshold is None else threshold
    distance = iou_distances if fmt == "motchallenge" else euclidean_distances
    if len(gt) and len(hyp) and gt.values.shape[1] != hyp.values.shape[1]:
        raise ValueError(f"ground truth has {gt.values.shape[1]} values per row, tracks {hyp.values.shape[1]}")
    acc = ClearMotAccumulator(threshold, inclusive=FORMATS[fmt][1])
    gt_rows, hyp_rows = gt.frame_slices(), hyp.frame_slices()
    none = slice(0, 0)
    for frame in sorted(gt_rows.keys() | hyp_rows.keys()):
        g, h = gt_rows.get(frame, none), hyp_rows.get(frame, none)
        gt_ids, hyp_ids = gt.ids[g], hyp.ids[h]
        dist = distance(gt.values[g], hyp.values[h]) if gt_ids.size and hyp_ids.size else None
        acc.update(gt_ids, hyp_ids, dist)
    return acc.result()


def _sequence_files(directory: Path) -> dict[str, Path]:
    """Sequence name -> file: ``NAME.csv``/``NAME.txt``, or MOTChallenge's ``NAME/gt/gt.txt``."""
    found: dict[str, Path] = {}
    for p in sorted(directory.iterdir()):
        if p.is_file() and p.suffix.lower() in _SUFFIXES:
            name = p.stem
        elif p.is_dir() and (p / "gt" / "gt.txt").is_file():
            name, p = p.name, p / "gt" / "gt.txt"
        else:
            continue
        if name in found:
            raise EvaluationInputError(f"{directory}: two files for sequence {name!r}: {found[name].name}, {p.name}")
        found[name] = p
    return found


def _sequence_name(path: Path) -> str:
    """A file's sequence name; ``SEQ/gt.txt`` and ``SEQ/gt/gt.txt`` are named SEQ."""
    parts = [path.stem, *(p.name for p in path.parents)]
    return next((n for n in parts if n and n != "gt"), path.stem)


def pair_sequences(gt: Path, tracks: Path) -> list[tuple[str, Path, Path]]:
    """(name, gt file, tracks file) for two files, or for two directories of same-named files."""
    if not gt.exists():
        raise EvaluationInputError(f"{gt}: no such file or directory")
    if not tracks.exists():
        raise EvaluationInputError(f"{tracks}: no such file or directory")
    if gt.is_file() and tracks.is_file():
        return [(_sequence_name(gt), gt, tracks)]
    if gt.is_file() or tracks.is_file():
        raise EvaluationInputError(f"give two files or two directories, not {gt} and {tracks}")
    gt_files, track_files = _sequence_files(gt), _sequence_files(tracks)
    if not gt_files:
        raise EvaluationInputError(f"{gt}: no ground-truth files (*.csv, *.txt or SEQ/gt/gt.txt)")
    lacking = sorted(gt_files.keys() - track_files.keys())
    if lacking:
        raise EvaluationInputError(
            f"{tracks}: no tracks file for sequence(s) {', '.join(lacking)} (expected e.g. {tracks / (lacking[0] + '.csv')})")
    for extra in sorted(track_files.keys() - gt_files.keys()):
        log.warning("%s has no ground truth in %s; not evaluated", track_files[extra], gt)
    return [(name, gt_files[name], track_files[name]) for name in sorted(gt_files)]


def evaluate_sequences(gt: Path | str, tracks: Path | str, fmt: str = "tracks", threshold: float | None = None,
                       dims: int = 2) -> Report:
    """Evaluate files or directories of sequences; raises :class:`EvaluationInputError` on bad input."""
    if fmt not in FORMATS:
        raise ValueError(f"unknown format {fmt!r}; expected one of {', '.join(FORMATS)}")
    threshold = default_threshold(fmt) if threshold is None else float(threshold)
    if not np.isfinite(threshold) or threshold <= 0:
        raise ValueError(f"threshold must be a positive number, got {threshold}")
    results: list[tuple[str, ClearMot]] = []
    for name, gt_path, tracks_path in pair_sequences(Path(gt), Path(tracks)):
        gt_table = read_table(gt_path, fmt, ground_truth=True, dims=dims)
        hyp_table = read_table(tracks_path, fmt, ground_truth=False, dims=dims)
        results.append((name, evaluate_tables(gt_table, hyp_table, fmt, threshold)))
    return make_report(results, fmt, threshold, dims)


def make_report(results: list[tuple[str, ClearMot]], fmt: str = "tracks", threshold: float | None = None,
                dims: int = 2) -> Report:
    """A :class:`Report` from per-sequence results computed elsewhere (e.g. by :func:`evaluate_tables`)."""
    threshold = default_threshold(fmt) if threshold is None else float(threshold)
    return Report(fmt=fmt, threshold=threshold, dims=dims, sequences=list(results),
                  overall=ClearMot.combine(r for _, r in results))


def _pct(x: float) -> str:
    return f"{100.0 * x:.2f}" if np.isfinite(x) else "-"


def _num(x: float, digits: int = 3) -> str:
    return f"{x:.{digits}f}" if np.isfinite(x) else "-"


def format_table(report: Report) -> str:
    """Table II of seed 000 (CLEAR MOT and recall errors), then the identity measures."""
    rows = list(report.sequences)
    if len(rows) > 1:
        rows.append(("overall", report.overall))
    clear_head = ["sequence", "objects", "matches", "misses", "misses%", "FP", "FP%", "IDSW", "IDSW%",
                  "recall err", f"MOTP ({report.unit})", "MOTA%"]
    clear = [[name, str(r.objects), str(r.matches), str(r.misses), _num(r.percent(r.misses), 2),
              str(r.false_positives), _num(r.percent(r.false_positives), 2), str(r.id_switches),
              _num(r.percent(r.id_switches), 2), str(r.recall_errors), _num(r.motp), _pct(r.mota)]
             for name, r in rows]
    id_head = ["sequence", "IDF1%", "IDP%", "IDR%", "MT", "PT", "ML", "frag", "consistency%", "ID histogram (top 5, %)"]
    ident = [[name, _pct(r.idf1), _pct(r.idp), _pct(r.idr), str(r.mostly_tracked), str(r.partially_tracked),
              str(r.mostly_lost), str(r.fragmentations), _pct(r.consistency),
              " ".join(f"{100 * b:.1f}" for b in r.consistency_histogram[:5]) or "-"]
             for name, r in rows]
    title = f"CLEAR MOT ({report.fmt}; a pair matches when {report.match_rule})"
    return "\n".join([title, _render(clear_head, clear), "", _render(id_head, ident)])


def _render(head: list[str], rows: list[list[str]]) -> str:
    widths = [max(len(c) for c in col) for col in zip(head, *rows)]
    lines = [head, ["-" * w for w in widths], *rows]
    return "\n".join(
        "  ".join(c.ljust(w) if k == 0 or k == len(widths) - 1 else c.rjust(w) for k, (c, w) in enumerate(zip(line, widths)))
        .rstrip()
        for line in lines)
