"""Pipeline benchmark: the whole system on a fixed simulated scenario.

    python benchmarks/pipeline.py [--scenario still] [--duration 30] [--fps 10] [--width 320 --height 240]

Runs `perception demo --json` (router, four services and simulator as separate processes)
and prints the sustained frame rate, the latency from the camera frame's stamp to each
stage's output (p50/p95; the tracker's row is end to end), the CPU use per service and
the tracking metrics of the run.
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import subprocess
import sys


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--scenario", default="still")
    ap.add_argument("--duration", type=float, default=30.0)
    ap.add_argument("--fps", type=float, default=10.0)
    ap.add_argument("--width", type=int, default=320)
    ap.add_argument("--height", type=int, default=240)
    args = ap.parse_args()
    cmd = [sys.executable, "-m", "perception", "-q", "demo", "--json", "--no-view", "--scenario", args.scenario,
           "--duration", str(args.duration), "--fps", str(args.fps), "--width", str(args.width), "--height", str(args.height)]
    res = subprocess.run(cmd, capture_output=True, text=True, env={**os.environ, "RUST_LOG": "error"})
    if res.returncode != 0:
        print(res.stderr, file=sys.stderr)
        return res.returncode
    out = json.loads(res.stdout[res.stdout.index("{"):])
    print(f"# Pipeline benchmark\n\nmachine: {platform.node()}, {os.cpu_count()} cores, {platform.machine()}, "
          f"Python {platform.python_version()}")
    print(f"scenario {args.scenario}, {args.width}x{args.height} at {args.fps:g} fps, {args.duration:g} s, "
          f"all processes on this machine\n")
    print("| stage | messages | sustained rate (Hz) | latency from frame stamp p50 (ms) | p95 (ms) | CPU (% of a core) |")
    print("|---|---|---|---|---|---|")
    for stage, s in out["pipeline"].items():
        rate = f"{s['rate_hz']:.1f}" if s["rate_hz"] else "-"
        p50 = f"{s['latency_p50_ms']:.1f}" if s["latency_p50_ms"] is not None else "-"
        p95 = f"{s['latency_p95_ms']:.1f}" if s["latency_p95_ms"] is not None else "-"
        cpu = out["cpu_percent"].get(stage)
        print(f"| {stage} | {s['messages']:.0f} | {rate} | {p50} | {p95} | {cpu if cpu is not None else '-'} |")
    o = out["overall"]
    print(f"\nMOTA {100 * o['mota']:.1f} %, MOTP {o['motp']:.3f} m, IDSW {o['id_switches']}, "
          f"recall errors {o['recall_errors']}, objects {o['objects']}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
