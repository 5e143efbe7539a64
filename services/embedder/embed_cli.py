"""``perception embed``: add appearance descriptors to detection JSON lines, offline."""

from __future__ import annotations

import argparse
import json
import sys
from dataclasses import asdict
from pathlib import Path
from typing import Any, TextIO

from common.runtime.progress import progress
from services.embedder.core.backend import Card
from services.embedder.flags import add_backend_arguments, backend_from_config, config_from_args
from services.embedder.jsonl import crops_of_line, read_lines

DESCRIPTION = """\
Read the JSON lines written by 'perception detect'
  {"image": path, "detections": [{"bbox_xyxy": [x0, y0, x1, y1], "score": s, ...}]}
and write the same lines with an "embedding": [floats] on every detection (null for a
box that is empty once clamped to the image) and a "model" object with the model card
(name, dim, metric, input_size, normalized, thresholds). Other keys are kept as they are.
All boxes of an image are described in one backend call."""


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("detections", metavar="DETS.jsonl", help="detections from 'perception detect'")
    parser.add_argument("--output", "-o", default=None, metavar="OUT.jsonl", help="output file (default stdout)")
    parser.add_argument("--decimals", type=int, default=6, help="digits kept per descriptor value (default 6)")
    add_backend_arguments(parser)


def card_json(card: Card) -> dict[str, Any]:
    out = asdict(card)
    out["input_size"] = list(card.input_size) if card.input_size else None
    t = card.thresholds
    out["thresholds"] = {"t_lower": t[0], "t_upper": t[1], "t_recover": t[2]} if t else None
    return out


def main(args: argparse.Namespace) -> int:
    backend = backend_from_config(config_from_args(args))
    model = card_json(backend.card)
    base = Path(args.detections).resolve().parent
    out: TextIO = open(args.output, "w") if args.output else sys.stdout
    try:
        for n, line in progress(read_lines(args.detections), desc="embed", unit="image"):
            crops, kept = crops_of_line(line, f"{args.detections}:{n}", base)
            vectors = backend.embed(crops)
            for det in line.get("detections", []):
                det["embedding"] = None
            for row, i in enumerate(kept):
                line["detections"][i]["embedding"] = [round(float(v), args.decimals) for v in vectors[row]]
            line["model"] = model
            out.write(json.dumps(line) + "\n")
    finally:
        if out is not sys.stdout:
            out.close()
    return 0
