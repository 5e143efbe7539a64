"""``perception evaluate``: CLEAR MOT, IDF1, HOTA, recall errors and ID consistency of a tracker's output."""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

from common.runtime.cli_util import CliError
from tools.evaluation.evaluate import (FORMATS, default_threshold, evaluate_sequences, evaluate_tables, find_sequences,
                                      format_identity, format_table)
from tools.evaluation.identity import DEFAULT_GAP, DEFAULT_MIN_FRAMES
from tools.evaluation.readers import EvaluationInputError, read_table
from tools.evaluation.why import format_reasons, id_logs, reasons

DESCRIPTION = """\
Compare tracker output with ground truth, frame by frame (CLEAR MOT, Bernardin and
Stiefelhagen 2008): last frame's correspondences are kept while still within the
threshold, the rest are matched by the Hungarian algorithm.

Formats:
  tracks        GT CSV frame,id,x,y,z; tracks CSV frame,stamp,id,x,y,z (perception track).
                Euclidean distance on the ground plane (x, y), or in 3-D with --dims 3;
                a pair matches when its distance is < 1 m (--threshold).
  motchallenge  frame,id,left,top,width,height,conf,... (no header); GT rows with conf < 1
                dropped; a pair matches when 1 - IoU <= 0.5 (IoU >= 0.5).

GT and TRACKS are two files, or two directories holding the sequences' files: one row
per sequence and an overall row. In a directory, sequence SEQ is SEQ.csv or SEQ.txt
(a GT directory may also use MOTChallenge's SEQ/gt/gt.txt); a prefix names the file's
role: gt_SEQ for --gt, tracks_SEQ for --tracks, gt_ignore_SEQ for --gt-ignore (dets_SEQ
is never read), so one folder can hold them side by side.

Ignore regions (--gt-ignore, tracks format; KITTI's rule): people a tracker is neither
required nor penalised for, in the GT's columns frame,id,x,y,z. After the matching, a
track still unmatched but within the gate of an ignored person of that frame is dropped
from the frame: no hit, no false positive, and left out of IDF1, MT/PT/ML and HOTA.
The KITTI pedestrian dev set in one go:
  perception evaluate --gt kitti_ped_dev/ --gt-ignore kitti_ped_dev/ --tracks out/
  (out/ holding 0000.csv or tracks_0000.csv, ... from perception track)

Prints the thesis's Table II (objects, matches, misses, FP, IDSW, recall errors, MOTP,
MOTA), then IDF1/IDP/IDR, MT/PT/ML, fragmentations and TU Ilmenau's ID consistency, then
HOTA, DetA and AssA (Luiten et al. 2021, as TrackEval computes them: the mean over
alpha = 0.05..0.95 of a per-alpha score). HOTA's similarity is IoU for motchallenge and
max(0, 1 - d / (2 * threshold)) for tracks (TrackEval's for points: 2 m for the 1 m
gate, so alpha = 0.5 is the gate). A recall error is an ID switch to a hypothesis ID
that had earlier been matched to a different ground-truth person.

--identity adds, per sequence, the people each track ID was matched to (frames each), and
for each person back after --gap frames (default 10) out of the ground truth whether
their first match on return had their own earlier ID (true recovery), an ID new to them
and unused (missed recovery) or an ID matched earlier to another person (false
recovery); a newcomer first matched with another person's earlier ID is a false
recovery too. Shared IDs: track IDs matched >= --min-frames (default 5) to two or more people.
With --id-log (perception track --id-log's file), each return and false recovery also says
why: the tracker's ID decision in that appearance (the candidates it weighed, their log-odds
and support, where and when they left), or that there was none (the track was continued).
"""


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--gt", required=True, metavar="GT", help="ground-truth file or directory")
    parser.add_argument("--tracks", required=True, metavar="TRACKS", help="tracker output file or directory")
    parser.add_argument("--gt-ignore", metavar="IGNORE", default=None,
                        help="tracks format: people neither required nor penalised (frame,id,x,y,z): a file, "
                             "or a directory holding gt_ignore_SEQ.csv or SEQ.csv per sequence")
    parser.add_argument("--format", dest="fmt", choices=sorted(FORMATS), default="tracks",
                        help="input format (default: tracks)")
    parser.add_argument("--threshold", type=float, default=None,
                        help="match threshold: metres for tracks (default 1.0), 1 - IoU for motchallenge (default 0.5)")
    parser.add_argument("--dims", type=int, choices=(2, 3), default=None,
                        help="tracks format: 2 = ground plane (x, y) (default), 3 = (x, y, z)")
    parser.add_argument("--json", action="store_true", help="print every figure as JSON instead of tables")
    parser.add_argument("--identity", action="store_true",
                        help="also the identity per person: each track ID's people, recoveries on return, "
                             "newcomers given another person's ID, shared track IDs")
    parser.add_argument("--gap", type=int, default=DEFAULT_GAP, metavar="N",
                        help=f"--identity: frames out of the ground truth that make a return (default {DEFAULT_GAP})")
    parser.add_argument("--min-frames", type=int, default=DEFAULT_MIN_FRAMES, metavar="N",
                        help="--identity: matched frames a person needs for a track ID to count as covering them "
                             f"(default {DEFAULT_MIN_FRAMES})")
    parser.add_argument("--id-log", type=Path, default=None, metavar="IDS",
                        help="--identity: the tracker's ID decisions (perception track --id-log's file, or a "
                             "directory of ids_SEQ.jsonl): says why each returning person and each false recovery "
                             "got their ID")
    parser.add_argument("--plot", type=Path, default=None, metavar="OUT.png",
                        help="also draw the tracks against the ground truth, one top-down panel per sequence, "
                             "with ID switches, misses and false positives marked and Table II in each title "
                             "(needs matplotlib, the 'view' extra)")


def main(args: argparse.Namespace) -> int:
    if args.fmt == "motchallenge" and args.dims is not None:
        raise CliError("--dims applies to --format tracks only (MOTChallenge files are 2-D boxes)")
    if args.fmt == "motchallenge" and args.gt_ignore is not None:
        raise CliError("--gt-ignore applies to --format tracks only (MOTChallenge GT rows with conf < 1 are dropped)")
    if args.threshold is not None and not args.threshold > 0:
        raise CliError(f"--threshold must be a positive number, got {args.threshold}")
    if args.gap < 1 or args.min_frames < 1:
        raise CliError(f"--gap and --min-frames must be >= 1, got {args.gap} and {args.min_frames}")
    if args.id_log is not None and not args.identity:
        raise CliError("--id-log explains the identity measures: add --identity")
    try:
        report = evaluate_sequences(args.gt, args.tracks, fmt=args.fmt, threshold=args.threshold,
                                    dims=args.dims or 2, ignore=args.gt_ignore, identity=args.identity,
                                    gap=args.gap, min_frames=args.min_frames)
        explained = None
        if args.id_log is not None:
            logs = id_logs(args.id_log, [name for name, _ in report.identity or []])
            explained = [(name, reasons(ident, logs[name])) for name, ident in report.identity or [] if name in logs]
    except EvaluationInputError as exc:
        raise CliError(str(exc)) from exc
    if args.json:
        out = report.to_dict()
        if explained is not None:
            out["why"] = {name: [r.to_dict() for r in rs] for name, rs in explained}
        print(json.dumps(out, indent=2, allow_nan=False))
    else:
        print(format_table(report))
        if args.identity:
            print("\n" + format_identity(report))
        if explained is not None:
            print("\n" + format_reasons(explained))
    if args.plot is not None:
        _plot(args, args.plot)
    return 0


def _plot(args: argparse.Namespace, out: Path) -> None:
    """Evaluate again, keeping each frame's events, and draw the plot."""
    from tools.evaluation.plot import PlotUnavailable, SequencePlot, plot_sequences

    threshold = default_threshold(args.fmt) if args.threshold is None else args.threshold
    ignore = None if args.gt_ignore is None else Path(args.gt_ignore)
    panels = []
    for seq in find_sequences(Path(args.gt), Path(args.tracks), ignore):
        gt = read_table(seq.gt, args.fmt, ground_truth=True, dims=args.dims or 2)
        hyp = read_table(seq.tracks, args.fmt, ground_truth=False, dims=args.dims or 2)
        ign = read_table(seq.ignore, args.fmt, ground_truth=True, dims=args.dims or 2) if seq.ignore else None
        panel = SequencePlot(seq.name, gt, hyp)
        panel.result = evaluate_tables(gt, hyp, args.fmt, threshold, ignore=ign, on_frame=panel.on_frame)
        panels.append(panel)
    try:
        written = plot_sequences(panels, out)
    except PlotUnavailable as exc:
        raise CliError(str(exc)) from exc
    print(f"plot: {written}", file=sys.stderr if args.json else sys.stdout)
