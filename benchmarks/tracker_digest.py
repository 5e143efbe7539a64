"""A digest of every tracker output that ``benchmarks/quality.py`` judges: a refactor's check.

    python benchmarks/tracker_digest.py [--only kitti,pets,pets-gt,sim] [--out FILE] [--compare FILE]

Runs ``benchmarks/quality.py`` (its data, its trackers, its settings) and, instead of trusting
the printed figures to the third decimal, hashes the rows of every tracker on every sequence
(frame, stamp, ID and position, exact floats) as they reach the judge, in the order the
benchmark runs them. ``--out`` writes the digests as JSON lines; ``--compare FILE`` exits 1
naming every run whose rows differ from ``FILE``'s (a change meant to keep the tracker's
behaviour, such as a restructuring, must differ nowhere). The PETS detections and the
simulator captures come from quality.py's cache (``benchmarks/.cache``), so a second run only
tracks.
"""

from __future__ import annotations

import argparse
import contextlib
import hashlib
import io
import json
import os
import sys
from pathlib import Path
from typing import Any

if __name__ == "__main__":
    for _var in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
        os.environ.setdefault(_var, "1")

ROOT = Path(__file__).resolve().parents[1]
if str(ROOT) not in sys.path:
    sys.path.insert(0, str(ROOT))

from benchmarks import quality, quality_sim  # noqa: E402


def digest(rows: list[Any]) -> str:
    """A hash of ``rows`` exact to the bit (floats by their repr)."""
    return hashlib.sha256(repr([tuple(r) for r in rows]).encode()).hexdigest()[:16]


def run(only: str) -> list[dict[str, Any]]:
    """quality.py's runs of ``only``, each judged sequence's rows as a digest, in order."""
    out: list[dict[str, Any]] = []
    judge_identity, judge_demo = quality.judge_identity, quality_sim.judge_demo

    def on_identity(gt: Any, rows: list[Any], ignore: Any = None) -> Any:
        out.append({"k": len(out), "kind": "table", "rows": len(rows), "digest": digest(rows)})
        return judge_identity(gt, rows, ignore)

    def on_demo(cap: Any, rows: list[Any], on_frame: Any = None) -> Any:
        out.append({"k": len(out), "kind": f"sim {cap.name}", "rows": len(rows), "digest": digest(rows)})
        return judge_demo(cap, rows, on_frame=on_frame)

    quality.judge_identity, quality_sim.judge_demo = on_identity, on_demo
    try:
        with contextlib.redirect_stdout(io.StringIO()):
            quality.main(["--only", only])
    finally:
        quality.judge_identity, quality_sim.judge_demo = judge_identity, judge_demo
    return out


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--only", default="kitti,pets,pets-gt,sim", help="quality.py's datasets (default all but pets-live)")
    parser.add_argument("--out", type=Path, help="write the digests here (JSON lines)")
    parser.add_argument("--compare", type=Path, help="a file written by --out: exit 1 where the rows differ")
    args = parser.parse_args(argv)
    runs = run(args.only)
    text = "".join(json.dumps(r) + "\n" for r in runs)
    if args.out:
        args.out.write_text(text)
    print(f"{len(runs)} runs digested")
    if args.compare is None:
        return 0
    before = [json.loads(line) for line in args.compare.read_text().splitlines() if line.strip()]
    if len(before) != len(runs):
        print(f"{len(runs)} runs here, {len(before)} in {args.compare}: not the same benchmark")
        return 1
    differ = [(a, b) for a, b in zip(before, runs) if a["digest"] != b["digest"]]
    for a, b in differ:
        print(f"run {a['k']} ({a['kind']}): {a['rows']} rows {a['digest']} -> {b['rows']} rows {b['digest']}")
    print("identical" if not differ else f"{len(differ)} of {len(runs)} runs differ")
    return 1 if differ else 0


if __name__ == "__main__":
    raise SystemExit(main())
