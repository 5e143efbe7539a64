"""Simulator frame rate: rendering (RGB + depth + ground truth) and the full message path.

Prints, per scenario and resolution, the median and p95 time per frame and the frames/s
of (a) the core (render + ground truth) and (b) a published frame (core + messages +
msgpack encoding). Three people; ``still`` (static camera: the background is cached)
and ``moving-base`` (every frame renders the whole apartment).

    python benchmarks/simulator.py [--frames 60]
"""

from __future__ import annotations

import argparse
import platform
import time

import numpy as np

from common.codec import encode
from common.keys import Keys
from services.simulator.config import SimulatorConfig
from services.simulator.source import SimulatedStream


def _stream(scenario: str, width: int, height: int) -> SimulatedStream:
    cfg = SimulatorConfig(scenario=scenario, width=width, height=height, fps=15.0, start_ns=0, duration_s=0)
    stream = SimulatedStream(cfg, Keys())
    stream.messages(0)  # plans the first paths, builds the planner's grid
    return stream


def _measure(scenario: str, width: int, height: int, frames: int) -> tuple[np.ndarray, np.ndarray]:
    """Milliseconds per frame: render + ground truth, and the published frame (+ messages + encoding)."""
    stream = _stream(scenario, width, height)
    core = []
    for seq in range(1, frames + 1):
        t0 = time.perf_counter()
        stream.simulation.frame(seq)
        core.append(time.perf_counter() - t0)
    stream = _stream(scenario, width, height)
    full = []
    for seq in range(1, frames + 1):
        t0 = time.perf_counter()
        for _, msg in stream.messages(seq)[1]:
            encode(msg)
        full.append(time.perf_counter() - t0)
    return np.array(core) * 1e3, np.array(full) * 1e3


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--frames", type=int, default=60)
    args = parser.parse_args()
    print(f"machine: {platform.processor() or platform.machine()}, {platform.python_implementation()} "
          f"{platform.python_version()}, numpy {np.__version__}")
    print("| scenario | resolution | render+GT median ms | p95 ms | frames/s | published frame median ms | p95 ms | frames/s |")
    print("|---|---|---|---|---|---|---|---|")
    for scenario in ("still", "moving-base"):
        for width, height in ((320, 240), (640, 480)):
            core, full = _measure(scenario, width, height, args.frames)
            print(f"| {scenario} | {width}x{height} | {np.median(core):.1f} | {np.percentile(core, 95):.1f} | "
                  f"{1e3 / np.median(core):.0f} | {np.median(full):.1f} | {np.percentile(full, 95):.1f} | "
                  f"{1e3 / np.median(full):.0f} |")


if __name__ == "__main__":
    main()
