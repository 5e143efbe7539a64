"""Pipeline benchmark: the whole system on a fixed simulated scenario.

    python benchmarks/pipeline.py [--scenario still] [--duration 30] [--fps 10] [--width 320 --height 240] [--no-hd]

Runs `perception demo --json` (router, four services and simulator as separate processes)
and prints the sustained frame rate, the latency from the camera frame's stamp to each
stage's output (p50/p95; the tracker's row is end to end), the CPU use per service and
the tracking metrics of the run. Then, unless ``--no-hd``, the same at the camera's own
size and rate, 640x480 and 30 fps (the README's "the demo at 640×480 and 30 fps" row): the
rate the pipeline sustains and the tracker's latency. The machine's load average is printed
before each run: other work on it lowers the rates.
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import subprocess
import sys
from typing import Any

HD = (640, 480, 30.0)


def demo(scenario: str, duration: float, fps: float, width: int, height: int) -> dict[str, Any] | None:
    """`perception demo --json`'s report, or None (its stderr printed) if it failed."""
    cmd = [sys.executable, "-m", "perception", "-q", "demo", "--json", "--no-view", "--scenario", scenario,
           "--duration", str(duration), "--fps", str(fps), "--width", str(width), "--height", str(height)]
    res = subprocess.run(cmd, capture_output=True, text=True, env={**os.environ, "RUST_LOG": "error"})
    if res.returncode != 0:
        print(res.stderr, file=sys.stderr)
        return None
    out: dict[str, Any] = json.loads(res.stdout[res.stdout.index("{"):])
    return out


def table(out: dict[str, Any], scenario: str, duration: float, fps: float, width: int, height: int, load: str) -> None:
    print(f"scenario {scenario}, {width}x{height} at {fps:g} fps, {duration:g} s, all processes on this machine "
          f"(load average before: {load})\n")
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


def _load() -> str:
    return ", ".join(f"{x:.2f}" for x in os.getloadavg())


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--scenario", default="still")
    ap.add_argument("--duration", type=float, default=30.0)
    ap.add_argument("--fps", type=float, default=10.0)
    ap.add_argument("--width", type=int, default=320)
    ap.add_argument("--height", type=int, default=240)
    ap.add_argument("--no-hd", action="store_true", help="skip the 640x480, 30 fps run")
    args = ap.parse_args()
    print(f"# Pipeline benchmark\n\nmachine: {platform.node()}, {os.cpu_count()} cores, {platform.machine()}, "
          f"Python {platform.python_version()}")
    runs = [(args.fps, args.width, args.height)]
    if not args.no_hd and (args.width, args.height, args.fps) != HD:
        runs.append((HD[2], HD[0], HD[1]))
    for k, (fps, width, height) in enumerate(runs):
        load = _load()
        out = demo(args.scenario, args.duration, fps, width, height)
        if out is None:
            return 1
        if k == 0:
            print()
            table(out, args.scenario, args.duration, fps, width, height, load)
        else:
            t, d = out["pipeline"]["tracker"], out["pipeline"]["detector"]
            print(f"\n## the demo at {width}x{height} and {fps:g} fps (load average before: {load})\n")
            print("| stage | sustained rate (Hz) | latency p50 / p95 (ms) | CPU (% of a core) |")
            print("|---|---|---|---|")
            for name, s in (("detector (depth)", d), ("tracker", t)):
                cpu = out["cpu_percent"].get(name.split()[0])
                print(f"| {name} | {s['rate_hz']:.1f} | {s['latency_p50_ms']:.0f} / {s['latency_p95_ms']:.0f} | "
                      f"{cpu if cpu is not None else '-'} |")
    return 0


if __name__ == "__main__":
    sys.exit(main())
