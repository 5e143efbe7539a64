"""Throughput of ``perception evaluate``: the metrics core and the whole command, in frames/s.

Synthetic sequences: N people on random walks; the "tracker" output is the ground truth
plus 0.15 m noise, with 5 % of detections dropped, 0.5 false positives per frame and an
ID change every ~200 frames. Run: ``.venv/bin/python benchmarks/evaluation.py``.
"""

from __future__ import annotations

import argparse
import contextlib
import io
import platform
import statistics
import tempfile
import time
from pathlib import Path

import numpy as np

from common.runtime.progress import Bar, progress_bar
from perception.cli import main as perception
from tools.evaluation.distances import euclidean_distances
from tools.evaluation.evaluate import evaluate_tables
from tools.evaluation.metrics import ClearMotAccumulator
from tools.evaluation.readers import TrackTable


def synthetic(people: int, frames: int, seed: int = 0) -> tuple[TrackTable, TrackTable]:
    rng = np.random.default_rng(seed)
    pos = rng.uniform(0, 4.0 * np.sqrt(people), (people, 2))
    ids = np.arange(people)
    gt_rows, hyp_rows = [], []
    for f in range(frames):
        pos += rng.normal(0, 0.05, pos.shape)
        ids = np.where(rng.random(people) < 1 / 200, ids + 1000, ids)
        gt_rows += [(f, i, x, y) for i, (x, y) in enumerate(pos)]
        keep = rng.random(people) > 0.05
        noisy = pos + rng.normal(0, 0.15, pos.shape)
        hyp_rows += [(f, h, x, y) for h, (x, y), k in zip(ids, noisy, keep) if k]
        for k in range(rng.poisson(0.5)):
            hyp_rows.append((f, 10**6 + f * 10 + k, *rng.uniform(0, 4.0 * np.sqrt(people), 2)))
    g, h = np.array(gt_rows), np.array(hyp_rows)
    return (TrackTable.from_arrays(g[:, 0], g[:, 1], g[:, 2:]), TrackTable.from_arrays(h[:, 0], h[:, 1], h[:, 2:]))


def per_frame_times(gt: TrackTable, hyp: TrackTable) -> list[float]:
    """Seconds per frame of distance matrix + accumulator update."""
    acc = ClearMotAccumulator(1.0, inclusive=False)
    gs, hs = gt.frame_slices(), hyp.frame_slices()
    times = []
    for f in sorted(gs):
        g, h = gs[f], hs.get(f, slice(0, 0))
        t0 = time.perf_counter()
        acc.update(gt.ids[g], hyp.ids[h], euclidean_distances(gt.values[g], hyp.values[h]))
        times.append(time.perf_counter() - t0)
    t0 = time.perf_counter()
    acc.result()
    times[-1] += time.perf_counter() - t0
    return times


def write_csv(table: TrackTable, path: Path, tracks: bool) -> None:
    with path.open("w") as f:
        f.write("frame,stamp,id,x,y,z\n" if tracks else "frame,id,x,y,z\n")
        for fr, i, (x, y) in zip(table.frames, table.ids, table.values):
            f.write(f"{fr},{fr / 30:.3f},{i},{x:.3f},{y:.3f},1.0\n" if tracks else f"{fr},{i},{x:.3f},{y:.3f},1.0\n")


PEOPLE = (1, 10, 50)


def bench_people(people: int, frames: int, repeats: int, bar: Bar) -> tuple[np.ndarray, list[float], list[float]]:
    """Per-frame update time (median, p95) in us, core frames/s and CLI frames/s for ``people``;
    ``bar`` counts the ``3 * repeats`` runs."""
    gt, hyp = synthetic(people, frames)
    times = []
    for _ in range(repeats):
        times += per_frame_times(gt, hyp)
        bar.update()
    core = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        evaluate_tables(gt, hyp)
        core.append(frames / (time.perf_counter() - t0))
        bar.update()
    with tempfile.TemporaryDirectory() as tmp:
        g_path, h_path = Path(tmp) / "gt.csv", Path(tmp) / "tracks.csv"
        write_csv(gt, g_path, tracks=False)
        write_csv(hyp, h_path, tracks=True)
        cli = []
        for _ in range(repeats):
            t0 = time.perf_counter()
            with contextlib.redirect_stdout(io.StringIO()):
                perception(["-q", "evaluate", "--gt", str(g_path), "--tracks", str(h_path)])
            cli.append(frames / (time.perf_counter() - t0))
            bar.update()
    return np.quantile(times, [0.5, 0.95]) * 1e6, core, cli


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--frames", type=int, default=1000, help="frames per sequence (default 1000)")
    parser.add_argument("--repeats", type=int, default=3)
    args = parser.parse_args()
    print(f"machine: {platform.processor() or platform.machine()}, python {platform.python_version()}")
    print(f"{'people':>6}  {'frames':>6}  {'update median (us)':>18}  {'update p95 (us)':>15}  "
          f"{'core (frames/s)':>15}  {'CLI incl. CSV (frames/s)':>24}")
    with progress_bar(len(PEOPLE) * 3 * args.repeats, desc="evaluation", unit="run") as bar:
        for people in PEOPLE:
            q, core, cli = bench_people(people, args.frames, args.repeats, bar)
            print(f"{people:>6}  {args.frames:>6}  {q[0]:>18.1f}  {q[1]:>15.1f}  {statistics.median(core):>15.0f}  "
                  f"{statistics.median(cli):>24.0f}")


if __name__ == "__main__":
    main()
