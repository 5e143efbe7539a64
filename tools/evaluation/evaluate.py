"""Evaluate track files against ground truth: the Python API behind ``perception evaluate``.

>>> report = evaluate_sequences("gt/", "tracks/")          # doctest: +SKIP
>>> print(format_table(report))                            # doctest: +SKIP
"""

from __future__ import annotations

import logging
import textwrap
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Callable

import numpy as np

from tools.evaluation.distances import distance_similarity, euclidean_distances, iou_distances, iou_similarity
from tools.evaluation.identity import DEFAULT_GAP, DEFAULT_MIN_FRAMES, Identity, IdentityCollector
from tools.evaluation.metrics import ClearMot, ClearMotAccumulator, FrameEvents, HotaAccumulator
from tools.evaluation.readers import EvaluationInputError, TrackTable, read_table

__all__ = ["FORMATS", "Report", "SequenceFiles", "default_threshold", "evaluate_sequences", "evaluate_tables",
           "find_sequences", "format_identity", "format_table", "hota_zero_distance", "make_report", "pair_sequences"]

log = logging.getLogger(__name__)

#: format -> (default threshold, inclusive gate, distance unit).
#: tracks: a match needs a ground-plane (or 3-D) distance < 1 m (Pinto's thesis, SPEC §4).
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
    ignore: bool = False
    identity: list[tuple[str, Identity]] | None = None  # per sequence, with --identity

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

    @property
    def hota_similarity(self) -> str:
        """HOTA's similarity of a pair, in words."""
        if self.fmt == "motchallenge":
            return "IoU"
        return f"max(0, 1 - d / {hota_zero_distance(self.threshold):g} m)"

    def to_dict(self) -> dict[str, object]:
        return {
            "format": self.fmt,
            "threshold": self.threshold,
            "match_rule": self.match_rule,
            "hota_similarity": self.hota_similarity,
            "ignore_regions": self.ignore,
            "dims": self.dims if self.fmt == "tracks" else 2,
            "sequences": {name: result.to_dict() for name, result in self.sequences},
            "overall": self.overall.to_dict(),
            **({"identity": self.identity_dict()} if self.identity is not None else {}),
        }

    def identity_dict(self) -> dict[str, object]:
        """The identity measures: settings, per sequence (coverage and events), overall totals."""
        parts = self.identity or []
        total = Identity.combine(i for _, i in parts).to_dict()
        for key in ("coverage", "events"):
            total.pop(key)
        return {"sequences": {name: i.to_dict() for name, i in parts}, "overall": total}


def hota_zero_distance(threshold: float) -> float:
    """Distance at which the tracks format's HOTA similarity reaches 0: twice the match threshold.

    With the 1 m gate this is TrackEval's 2 m for points, so alpha = 0.5 is the gate.
    """
    return 2.0 * threshold


def evaluate_tables(gt: TrackTable, hyp: TrackTable, fmt: str = "tracks", threshold: float | None = None,
                    ignore: TrackTable | None = None,
                    on_frame: Callable[[int, FrameEvents], None] | None = None) -> ClearMot:
    """CLEAR MOT, IDF1 and HOTA of one sequence over the union of the frames of ``gt`` and ``hyp``.

    ``ignore`` (optional): people neither required nor penalised, same columns as ``gt``.
    A hypothesis left unmatched by the CLEAR MOT matching but within the gate of one of
    them in the same frame is removed from that frame before any metric counts it.
    HOTA's similarity is IoU for ``motchallenge`` and ``max(0, 1 - d / (2 * threshold))``
    for ``tracks`` (:func:`hota_zero_distance`). ``on_frame(frame, events)``, if given, sees
    each frame's matches, switches, misses and false positives (for plots).
    """
    threshold = default_threshold(fmt) if threshold is None else threshold
    distance = iou_distances if fmt == "motchallenge" else euclidean_distances
    if len(gt) and len(hyp) and gt.values.shape[1] != hyp.values.shape[1]:
        raise ValueError(f"ground truth has {gt.values.shape[1]} values per row, tracks {hyp.values.shape[1]}")
    if ignore is not None and len(ignore) and len(hyp) and ignore.values.shape[1] != hyp.values.shape[1]:
        raise ValueError(f"ignore regions have {ignore.values.shape[1]} values per row, tracks {hyp.values.shape[1]}")
    acc = ClearMotAccumulator(threshold, inclusive=FORMATS[fmt][1])
    hota = HotaAccumulator()
    zero_distance = hota_zero_distance(threshold)
    gt_rows, hyp_rows = gt.frame_slices(), hyp.frame_slices()
    ignore_rows = ignore.frame_slices() if ignore is not None else {}
    none = slice(0, 0)
    for frame in sorted(gt_rows.keys() | hyp_rows.keys()):
        g, h = gt_rows.get(frame, none), hyp_rows.get(frame, none)
        gt_ids, hyp_ids = gt.ids[g], hyp.ids[h]
        dist = distance(gt.values[g], hyp.values[h]) if gt_ids.size and hyp_ids.size else None
        ignore_dist = None
        if ignore is not None and frame in ignore_rows and hyp_ids.size:
            ignore_dist = distance(hyp.values[h], ignore.values[ignore_rows[frame]])
        events = acc.update(gt_ids, hyp_ids, dist, ignore_dist)
        if on_frame is not None:
            on_frame(int(frame), events)
        hyp_values = hyp.values[h]
        if events.ignored:  # HOTA sees the frame without the dropped hypotheses
            keep = ~np.isin(hyp_ids, events.ignored)
            hyp_ids, hyp_values = hyp_ids[keep], hyp_values[keep]
            dist = dist[:, keep] if dist is not None and keep.any() else None
        similarity = None
        if dist is not None:
            if fmt == "motchallenge":
                similarity = iou_similarity(gt.values[g], hyp_values)
            else:
                similarity = distance_similarity(dist, zero_distance)
        hota.update(gt_ids, hyp_ids, similarity)
    return replace(acc.result(), hota_counts=hota.result())


#: File-name prefixes that say which role a file plays in a directory (KITTI dev set:
#: gt_SEQ.csv, gt_ignore_SEQ.csv, dets_SEQ.csv side by side). Longest first.
_ROLE_PREFIXES: tuple[tuple[str, str], ...] = (("gt_ignore_", "ignore"), ("gt_", "gt"), ("tracks_", "tracks"),
                                               ("dets_", "dets"))


def _split_role(stem: str) -> tuple[str | None, str]:
    """(role, sequence name) of a file stem: ``gt_ignore_0000`` -> ("ignore", "0000"); ``still`` -> (None, "still")."""
    for prefix, role in _ROLE_PREFIXES:
        if stem.startswith(prefix) and len(stem) > len(prefix):
            return role, stem[len(prefix):]
    return None, stem


def _sequence_files(directory: Path, role: str = "gt") -> dict[str, Path]:
    """Sequence name -> file of ``role`` in ``directory``.

    ``NAME.csv``/``NAME.txt`` or MOTChallenge's ``NAME/gt/gt.txt`` is sequence NAME for any
    role; ``gt_NAME``, ``gt_ignore_NAME`` and ``tracks_NAME`` are sequence NAME for the
    ground truth, the ignore regions and the tracks only; ``dets_NAME`` (detections) for none.
    """
    found: dict[str, Path] = {}
    for p in sorted(directory.iterdir()):
        if p.is_file() and p.suffix.lower() in _SUFFIXES:
            file_role, name = _split_role(p.stem)
            if file_role is not None and file_role != role:
                continue
        elif p.is_dir() and (p / "gt" / "gt.txt").is_file():
            name, p = p.name, p / "gt" / "gt.txt"
        else:
            continue
        if name in found:
            raise EvaluationInputError(f"{directory}: two files for sequence {name!r}: {found[name].name}, {p.name}")
        found[name] = p
    return found


def _sequence_name(path: Path) -> str:
    """A file's sequence name; ``SEQ/gt.txt`` and ``SEQ/gt/gt.txt`` are named SEQ, ``gt_SEQ.csv`` too."""
    parts = [path.stem, *(p.name for p in path.parents)]
    name = next((n for n in parts if n and n != "gt"), path.stem)
    return _split_role(name)[1]


@dataclass(frozen=True)
class SequenceFiles:
    """The files of one sequence; ``ignore`` is None when it has no ignore regions."""

    name: str
    gt: Path
    tracks: Path
    ignore: Path | None = None


def find_sequences(gt: Path, tracks: Path, ignore: Path | None = None) -> list[SequenceFiles]:
    """The sequences to evaluate: two files, or two directories matched on sequence names.

    ``ignore`` (optional) is a file with file inputs, or a directory: a sequence's ignore
    file there is ``gt_ignore_SEQ`` or ``SEQ`` (.csv/.txt). With directories, a sequence
    without one has no ignore regions (a warning), but a directory matching none is an error.
    """
    for path in (gt, tracks, ignore):
        if path is not None and not path.exists():
            raise EvaluationInputError(f"{path}: no such file or directory")
    if gt.is_file() and tracks.is_file():
        name = _sequence_name(gt)
        if ignore is None or ignore.is_file():
            return [SequenceFiles(name, gt, tracks, ignore)]
        found = _sequence_files(ignore, "ignore").get(name)
        if found is None:
            raise EvaluationInputError(f"{ignore}: no ignore file for sequence {name!r} "
                                       f"(expected e.g. {ignore / ('gt_ignore_' + name + '.csv')})")
        return [SequenceFiles(name, gt, tracks, found)]
    if gt.is_file() or tracks.is_file():
        raise EvaluationInputError(f"give two files or two directories, not {gt} and {tracks}")
    if ignore is not None and ignore.is_file():
        raise EvaluationInputError(
            f"--gt and --tracks are directories, so the ignore regions must be one too, not {ignore}")
    gt_files, track_files = _sequence_files(gt, "gt"), _sequence_files(tracks, "tracks")
    if not gt_files:
        raise EvaluationInputError(f"{gt}: no ground-truth files (*.csv, *.txt, gt_SEQ.csv or SEQ/gt/gt.txt)")
    lacking = sorted(gt_files.keys() - track_files.keys())
    if lacking:
        raise EvaluationInputError(
            f"{tracks}: no tracks file for sequence(s) {', '.join(lacking)} (expected e.g. {tracks / (lacking[0] + '.csv')})")
    for extra in sorted(track_files.keys() - gt_files.keys()):
        log.warning("%s has no ground truth in %s; not evaluated", track_files[extra], gt)
    ignore_files: dict[str, Path] = {}
    if ignore is not None:
        ignore_files = _sequence_files(ignore, "ignore")
        if not ignore_files.keys() & gt_files.keys():
            raise EvaluationInputError(f"{ignore}: no ignore file for any sequence of {gt} "
                                       f"(expected e.g. {ignore / ('gt_ignore_' + min(gt_files) + '.csv')})")
        for name in sorted(gt_files.keys() - ignore_files.keys()):
            log.warning("sequence %s has no ignore file in %s; evaluated without ignore regions", name, ignore)
        for extra in sorted(ignore_files.keys() - gt_files.keys()):
            log.warning("%s has no ground truth in %s; not used", ignore_files[extra], gt)
    return [SequenceFiles(name, gt_files[name], track_files[name], ignore_files.get(name)) for name in sorted(gt_files)]


def pair_sequences(gt: Path, tracks: Path) -> list[tuple[str, Path, Path]]:
    """(name, gt file, tracks file) for two files, or for two directories of same-named files."""
    return [(s.name, s.gt, s.tracks) for s in find_sequences(gt, tracks)]


def evaluate_sequences(gt: Path | str, tracks: Path | str, fmt: str = "tracks", threshold: float | None = None,
                       dims: int = 2, ignore: Path | str | None = None, identity: bool = False,
                       gap: int = DEFAULT_GAP, min_frames: int = DEFAULT_MIN_FRAMES) -> Report:
    """Evaluate files or directories of sequences; raises :class:`EvaluationInputError` on bad input.

    ``ignore``: a file or directory of ignore regions (tracks format only), see :func:`find_sequences`.
    ``identity``: also the identity measures per person (:mod:`tools.evaluation.identity`), a
    return being an appearance after ``gap`` frames out of the ground truth.
    """
    if fmt not in FORMATS:
        raise ValueError(f"unknown format {fmt!r}; expected one of {', '.join(FORMATS)}")
    if ignore is not None and fmt != "tracks":
        raise ValueError("ignore regions apply to the tracks format only (MOTChallenge drops GT rows with conf < 1)")
    threshold = default_threshold(fmt) if threshold is None else float(threshold)
    if not np.isfinite(threshold) or threshold <= 0:
        raise ValueError(f"threshold must be a positive number, got {threshold}")
    results: list[tuple[str, ClearMot]] = []
    identities: list[tuple[str, Identity]] = []
    for seq in find_sequences(Path(gt), Path(tracks), None if ignore is None else Path(ignore)):
        gt_table = read_table(seq.gt, fmt, ground_truth=True, dims=dims)
        hyp_table = read_table(seq.tracks, fmt, ground_truth=False, dims=dims)
        ignore_table = read_table(seq.ignore, fmt, ground_truth=True, dims=dims) if seq.ignore is not None else None
        collect = IdentityCollector() if identity else None
        results.append((seq.name, evaluate_tables(gt_table, hyp_table, fmt, threshold, ignore=ignore_table,
                                                  on_frame=collect)))
        if collect is not None:
            identities.append((seq.name, collect.result(gt_table.frames, gt_table.ids, gap, min_frames)))
    report = make_report(results, fmt, threshold, dims, ignore=ignore is not None)
    return replace(report, identity=identities) if identity else report


def make_report(results: list[tuple[str, ClearMot]], fmt: str = "tracks", threshold: float | None = None,
                dims: int = 2, ignore: bool = False) -> Report:
    """A :class:`Report` from per-sequence results computed elsewhere (e.g. by :func:`evaluate_tables`).

    ``ignore``: whether ignore regions were used (the table then shows the dropped tracks).
    """
    threshold = default_threshold(fmt) if threshold is None else float(threshold)
    return Report(fmt=fmt, threshold=threshold, dims=dims, sequences=list(results),
                  overall=ClearMot.combine(r for _, r in results), ignore=ignore)


def _pct(x: float) -> str:
    return f"{100.0 * x:.2f}" if np.isfinite(x) else "-"


def _num(x: float, digits: int = 3) -> str:
    return f"{x:.{digits}f}" if np.isfinite(x) else "-"


def format_table(report: Report, width: int | None = None) -> str:
    """Table II of Pinto's thesis (CLEAR MOT and recall errors), then the identity measures.

    ``width``: the most columns a line may take (the demo's terminal: 80). A table wider than
    that is split into tables of fewer columns, each starting with the sequence's name, and
    a longer title is wrapped. None: each table on one line per row, however wide.
    """
    rows = list(report.sequences)
    if len(rows) > 1:
        rows.append(("overall", report.overall))
    clear_head = ["sequence", "objects", "matches", "misses", "misses%", "FP", "FP%", "IDSW", "IDSW%",
                  "recall err", f"MOTP ({report.unit})", "MOTA%"]
    clear = [[name, str(r.objects), str(r.matches), str(r.misses), _num(r.percent(r.misses), 2),
              str(r.false_positives), _num(r.percent(r.false_positives), 2), str(r.id_switches),
              _num(r.percent(r.id_switches), 2), str(r.recall_errors), _num(r.motp), _pct(r.mota)]
             for name, r in rows]
    if report.ignore:  # the tracks dropped by ignore regions, after FP%
        clear_head.insert(7, "ignored")
        for row, (_, r) in zip(clear, rows):
            row.insert(7, str(r.ignored))
    id_head = ["sequence", "IDF1%", "IDP%", "IDR%", "MT", "PT", "ML", "frag", "consistency%", "ID histogram (top 5, %)"]
    ident = [[name, _pct(r.idf1), _pct(r.idp), _pct(r.idr), str(r.mostly_tracked), str(r.partially_tracked),
              str(r.mostly_lost), str(r.fragmentations), _pct(r.consistency),
              " ".join(f"{100 * b:.1f}" for b in r.consistency_histogram[:5]) or "-"]
             for name, r in rows]
    hota_head = ["sequence", "HOTA%", "DetA%", "AssA%", "DetRe%", "DetPr%", "AssRe%", "AssPr%", "LocA%"]
    hota = [[name, *(_pct(getattr(r.hota_counts, k)) if r.hota_counts is not None else "-"
                     for k in ("hota", "deta", "assa", "detre", "detpr", "assre", "asspr", "loca"))]
            for name, r in rows]
    title = f"CLEAR MOT ({report.fmt}; a pair matches when {report.match_rule})"
    if report.ignore:
        title += "; tracks unmatched within the gate of an ignored person dropped"
    hota_title = f"HOTA (mean over alpha = 0.05..0.95; similarity {report.hota_similarity})"
    return "\n".join([_wrap(title, width), _render(clear_head, clear, width), "", _render(id_head, ident, width), "",
                      _wrap(hota_title, width), _render(hota_head, hota, width)])


def format_identity(report: Report, width: int | None = 80) -> str:
    """The identity measures of ``report`` (run with ``identity=True``): totals per sequence,
    then per sequence the people of each track ID and the returns and false recoveries."""
    parts = report.identity or []
    if not parts:
        return "identity: not computed"
    gap, min_frames = parts[0][1].gap, parts[0][1].min_frames
    rows = list(parts)
    if len(rows) > 1:
        rows.append(("overall", Identity.combine(i for _, i in parts)))
    head = ["sequence", "returns", "true", "missed", "unmatched", "false", "newcomers", "shared IDs"]
    table = [[name, *(str(getattr(i, k)) for k in ("returns", "true_recoveries", "missed_recoveries",
                                                     "unmatched_returns", "false_recoveries", "false_newcomers",
                                                     "shared_tracks"))] for name, i in rows]
    title = (f"Identity per person (a return: back after >= {gap} frames out of the ground truth; false "
             f"recoveries include newcomers given another person's ID; shared IDs: a track ID matched "
             f">= {min_frames} frames to each of two or more people)")
    out = [_wrap(title, width), _render(head, table, width, left_last=False)]
    for name, i in parts:
        out += ["", f"{name}: people per track ID (person: matched frames; * shared)"]
        shared = i.shared()
        for t, people in i.coverage.items():
            text = f"  {t}{'*' if t in shared else ''}: " + ", ".join(f"{p}: {n}" for p, n in people.items())
            out.append(_wrap(text, width).replace("\n  ", "\n      "))
        if i.events:
            ev = [[str(e.person), str(e.start), "return" if e.returning else "first", e.outcome,
                   "-" if e.track is None else str(e.track), " ".join(map(str, e.previous)) or "-",
                   " ".join(map(str, e.owners)) or "-"] for e in i.events]
            out += ["", _render(["person", "from frame", "", "outcome", "ID", "own IDs", "ID's others"], ev, width)]
    return "\n".join(out)


def _wrap(text: str, width: int | None) -> str:
    return text if width is None or len(text) <= width else textwrap.fill(text, width, subsequent_indent="  ")


def _render(head: list[str], rows: list[list[str]], width: int | None = None, left_last: bool = True) -> str:
    """The table, or with ``width`` as many tables as it takes (columns split, the first kept in each)."""
    widths = [max(len(c) for c in col) for col in zip(head, *rows)]
    if width is None or sum(widths) + 2 * (len(widths) - 1) <= width:
        return _render_one(head, rows, left_last)
    parts: list[list[int]] = [[]]
    used = widths[0]
    for k in range(1, len(widths)):
        if parts[-1] and used + 2 + widths[k] > width:
            parts.append([])
            used = widths[0]
        parts[-1].append(k)
        used += 2 + widths[k]
    last = len(widths) - 1
    return "\n\n".join(_render_one([head[0], *(head[k] for k in ks)], [[r[0], *(r[k] for k in ks)] for r in rows],
                                   left_last=left_last and ks[-1] == last)
                       for ks in parts)


def _render_one(head: list[str], rows: list[list[str]], left_last: bool = True) -> str:
    """Numbers right-aligned; the first column (the name) and, with ``left_last``, the last
    (the ID histogram) left-aligned."""
    widths = [max(len(c) for c in col) for col in zip(head, *rows)]
    lines = [head, ["-" * w for w in widths], *rows]
    left = {0, len(widths) - 1} if left_last else {0}
    return "\n".join(
        "  ".join(c.ljust(w) if k in left else c.rjust(w) for k, (c, w) in enumerate(zip(line, widths))).rstrip()
        for line in lines)
