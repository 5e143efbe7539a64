"""``perception train-legs``: train the leg classifier on the labelled dev scans."""

from __future__ import annotations

import argparse
import hashlib
import os
import time
from pathlib import Path

from common.runtime.cli_util import CliError
from services.laser.model_file import DEFAULT_MODEL, write_model

DESCRIPTION = """\
Train the laser leg detector's classifier (boosted trees over each segment's shape) on the
labelled scans of --data/laser_legs (Leigh et al.'s leg_tracker training bags: the scans with
labelled legs and the empty rooms; see that folder's README), and write it as JSON to --out
(default: the model shipped in the package, services/laser/legs_model.json). Deterministic: the
same data gives the same file to the byte; the file records the sha256 of every bag it read.
--split train trains on the benchmark's train split only (benchmarks/legs.py judges that one
on the test split)."""


def _default_data() -> Path:
    env = os.environ.get("PERCEPTION_SHARED_DATA")
    return Path(env) if env else Path(__file__).resolve().parents[3] / "shared" / "data"


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("--data", type=Path, default=None,
                   help="the folder holding laser_legs/ (default: $PERCEPTION_SHARED_DATA, else ../shared/data)")
    p.add_argument("--out", type=Path, default=DEFAULT_MODEL, help="where to write the model (default: %(default)s)")
    p.add_argument("--split", choices=("all", "train"), default="all", help="which dev scans (default: all)")


def main(args: argparse.Namespace) -> int:
    from services.laser.training import train_model

    folder = (args.data or _default_data()) / "laser_legs"
    if not folder.is_dir():
        raise CliError(f"no dev scans at {folder}: give --data, the folder that holds laser_legs/")
    t0 = time.perf_counter()
    try:
        model, meta = train_model(folder, args.split)
    except (OSError, ValueError) as exc:
        raise CliError(f"cannot train on {folder}: {exc}") from exc
    args.out.parent.mkdir(parents=True, exist_ok=True)
    write_model(args.out, model, meta)
    digest = hashlib.sha256(args.out.read_bytes()).hexdigest()
    print(f"{args.out}: {len(model.leaf)} trees of depth {model.depth} from {meta['positives']} legs and "
          f"{meta['negatives']} other segments ({args.split} split, {time.perf_counter() - t0:.1f} s), sha256 {digest[:16]}")
    return 0
