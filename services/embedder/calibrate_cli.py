"""``perception calibrate-embedder``: distance distributions and suggested tracker thresholds."""

from __future__ import annotations

import argparse
import json
from pathlib import Path

import numpy as np

from common.runtime.cli_util import CliError
from services.embedder.core.calibration import PERCENTILES, calibrate
from services.embedder.jsonl import crops_of_line, read_lines
from services.embedder.flags import add_backend_arguments, backend_from_config, config_from_args

DESCRIPTION = """\
Measure a descriptor model on labelled crops and suggest its tracker thresholds.

Input: detection JSON lines (as from 'perception detect') whose detections carry a
"person_id"; detections without one are ignored. Every pair of crops is compared:
same-person and different-person distances are summarised by percentiles, with the
pair AUC and rank-1, and thresholds are suggested:
  t_upper   = 99th percentile of same-person distances   (1 % of true matches vetoed)
  t_lower   = 1st percentile of different-person distances (1 % of strangers accepted
              on appearance alone)
  t_recover = 5th percentile of different-person distances, within [t_lower, t_upper]
(if the two sets do not overlap, the gap between them is used). Put them in the
embedder's settings (embedder.thresholds) so every model card carries them."""


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--detections", required=True, metavar="LABELLED.jsonl",
                        help="detection lines whose detections carry a person_id")
    parser.add_argument("--json", action="store_true", help="print the result as JSON")
    add_backend_arguments(parser)


def main(args: argparse.Namespace) -> int:
    backend = backend_from_config(config_from_args(args))
    base = Path(args.detections).resolve().parent
    vectors, labels = [], []
    for n, line in read_lines(args.detections):
        labelled = [i for i, d in enumerate(line.get("detections", [])) if isinstance(d, dict) and "person_id" in d]
        if not labelled:
            continue
        sub = {"image": line["image"], "detections": [line["detections"][i] for i in labelled]}
        crops, kept = crops_of_line(sub, f"{args.detections}:{n}", base)
        if crops:
            vectors.append(backend.embed(crops))
            labels += [str(sub["detections"][k]["person_id"]) for k in kept]
    if not labels:
        raise CliError(f"{args.detections}: no usable detection carries a \"person_id\"")
    labs = np.array(labels)
    if len(set(labels)) < 2 or len(labs) == len(set(labels)):
        raise CliError(f"{args.detections}: need at least two people and one person seen twice "
                       f"(got {len(labels)} crops of {len(set(labels))} people)")
    card = backend.card
    cal = calibrate(np.concatenate(vectors), labs, card.metric)
    lo, hi, rec = (round(t, 3) for t in cal.thresholds)
    if args.json:
        print(json.dumps({"model": card.name, "metric": card.metric, "crops": len(labs), "people": len(set(labels)),
                          "pairs": {"same": len(cal.same), "different": len(cal.different)},
                          "percentiles": {"p": list(PERCENTILES), **cal.percentiles()},
                          "auc": cal.auc, "rank1": cal.rank1,
                          "thresholds": {"t_lower": lo, "t_upper": hi, "t_recover": rec}}, indent=2))
        return 0
    pct = cal.percentiles()
    print(f"model {card.name} ({card.dim}-D, {card.metric}): {len(labs)} crops of {len(set(labels))} people, "
          f"{len(cal.same)} same-person and {len(cal.different)} different-person pairs")
    print(f"{'percentile':>10} " + " ".join(f"{p:>7}" for p in PERCENTILES))
    for name in ("same", "different"):
        print(f"{name:>10} " + " ".join(f"{v:7.3f}" for v in pct[name]))
    print(f"pair AUC {cal.auc:.3f}   rank-1 {cal.rank1:.3f}")
    if card.thresholds:
        print("the model card now says: t_lower {:.3f}  t_upper {:.3f}  t_recover {:.3f}".format(*card.thresholds))
    print(f"suggested:                t_lower {lo:.3f}  t_upper {hi:.3f}  t_recover {rec:.3f}")
    print(f"\nembedder:\n  thresholds: {{t_lower: {lo}, t_upper: {hi}, t_recover: {rec}}}")
    return 0
