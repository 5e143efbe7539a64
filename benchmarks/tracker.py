"""Tracker benchmark: time of one update vs people x gallery size, and `perception track` throughput.

Run: ``.venv/bin/python benchmarks/tracker.py`` (a few minutes on a 2-core VM;
``--reps`` trades precision for time). Prints median and p95 in milliseconds.
``--without classifier posture`` times the robust profile with those per-track filters off,
to show what they cost beyond the association, the Kalman filter and the galleries.

``perception track`` is timed on synthetic files with embeddings and, position-only, on
the KITTI dev split (``kitti_ped_dev`` of the shared data, skipped when absent): as
``benchmarks/quality.py`` runs it (detections scoring at least 2.683, the robust profile
told KITTI's score calibration), the tracking alone (no process start, no file reading),
median of ``--kitti-reps`` passes over the 7 sequences.

``--map-sizes`` times what the robust tracker does with a robot's static map (``robust.static_map``):
taking a map of N x N cells of 5 cm (walls every 2.5 and 3.5 m, 2000 posts: the post filter has
work) as it comes in (slam_toolbox republishes a growing map every few seconds), and the birth
check of a frame's 3 new detections against it.

Each case starts a tracker with ``people`` Confirmed tracks and fills their galleries
(``gallery`` descriptors of dimension 128) by as many updates, then times updates in which
every person is detected again with a fresh descriptor, i.e. steady state: the association
over full galleries, one Kalman update per track and one gallery insertion with pruning.
The tracker is driven through its interface only (``TrackerCore``), as the service drives it.
"""

from __future__ import annotations

import os

# The tracker's matrices are small: one BLAS thread is fastest, and on a shared machine
# several threads make the tail latency explode. Set before numpy is imported.
for _var in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")

import argparse  # noqa: E402
import logging  # noqa: E402
import platform  # noqa: E402
import sys  # noqa: E402
import tempfile  # noqa: E402
import time  # noqa: E402
from dataclasses import replace  # noqa: E402
from pathlib import Path  # noqa: E402

import numpy as np  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
if str(ROOT) not in sys.path:  # this checkout's code, not an installed one's
    sys.path.insert(0, str(ROOT))

from benchmarks.quality import SHARED  # noqa: E402
from common.runtime.progress import Bar, progress_bar  # noqa: E402
from services.tracker.config import PROFILES, TrackerConfig  # noqa: E402
from services.tracker.offline import frame_stamps, read_detections, track, write_tracks  # noqa: E402
from services.tracker.core.types import FrameInput  # noqa: E402

DIM = 128
FPS = 30.0
OFFLINE_PEOPLE = (3, 10)  # people in the `perception track` throughput files


def make_people(n: int, rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray]:
    """Looks (n, DIM) unit vectors and positions (n, 3) on a grid 1.5 m apart."""
    looks = rng.normal(size=(n, DIM))
    looks /= np.linalg.norm(looks, axis=1, keepdims=True)
    side = int(np.ceil(np.sqrt(n)))
    pos = np.array([[1.5 * (i % side), 1.5 * (i // side), 1.0] for i in range(n)])
    return looks, pos


def observe(looks: np.ndarray, pos: np.ndarray, rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray]:
    desc = looks + rng.normal(scale=0.01, size=looks.shape)
    desc /= np.linalg.norm(desc, axis=1, keepdims=True)
    return pos + rng.normal(scale=0.01, size=pos.shape), desc.astype(np.float32)


def bench_update(people: int, gallery: int, reps: int, config: TrackerConfig) -> tuple[float, float]:
    """(median, p95) in ms of one update with ``people`` tracks holding full galleries."""
    rng = np.random.default_rng(people * 1000 + gallery)
    sized = config.model_copy(update={"robust": config.robust.model_copy(update={"gallery_size": gallery}),
                                      "thesis": config.thesis.model_copy(update={"gallery_size": gallery})})
    tracker = sized.build_tracker(config.thresholds("colour"))
    looks, pos = make_people(people, rng)
    t = 0.0
    # confirm every person, then fill every gallery to capacity with views of its person
    for _ in range(sized.profile_config.n_init + gallery):
        tracker.step(t, FrameInput.of(*observe(looks, pos, rng)))
        t += 1 / FPS
    times = []
    for _ in range(reps):
        frame = observe(looks, pos, rng)
        start = time.perf_counter()
        tracker.step(t, FrameInput.of(*frame))
        times.append(time.perf_counter() - start)
        t += 1 / FPS
    assert len(tracker.live_ids()) == people, "benchmark scenario lost tracks"
    ms = np.array(times) * 1e3
    return float(np.median(ms)), float(np.percentile(ms, 95))


def bench_offline(people: int, frames: int, config: TrackerConfig, tmp: Path) -> tuple[float, float]:
    """(frames/s of the tracking alone, frames/s including reading and writing the CSVs)."""
    rng = np.random.default_rng(1)
    looks, pos = make_people(people, rng)
    lines = ["frame,stamp,x,y,z,score," + ",".join(f"e{i}" for i in range(DIM))]
    for k in range(frames):
        p, d = observe(looks, pos + np.array([0.01 * k, 0.0, 0.0]), rng)
        for j in range(people):
            lines.append(f"{k},{k / FPS:.6f},{p[j, 0]:.4f},{p[j, 1]:.4f},{p[j, 2]:.4f},0.9," + ",".join(f"{v:.5f}" for v in d[j]))
    src, out = tmp / "dets.csv", tmp / "tracks.csv"
    src.write_text("\n".join(lines) + "\n")
    start = time.perf_counter()
    dets = read_detections(src)
    t_track = time.perf_counter()
    rows = track(dets, config.build_tracker(config.thresholds("colour")))
    t_done = time.perf_counter()
    write_tracks(out, rows)
    end = time.perf_counter()
    return frames / (t_done - t_track), frames / (end - start)


def bench_kitti(profile: str, reps: int, data: Path) -> float | None:
    """Median frames/s of tracking the KITTI dev split position-only, as quality.py does; None without it."""
    from benchmarks.quality import KITTI_SCORE_CUT, KITTI_SCORES, load_kitti

    root = data / "kitti_ped_dev"
    if not root.is_dir():
        return None
    seqs = [replace(s.dets, descriptors=None) for s in load_kitti(root, KITTI_SCORE_CUT)]
    frames = sum(len(frame_stamps(d)[0]) for d in seqs)
    config = TrackerConfig.model_validate({"profile": profile, "memory_path": None,
                                           **({"robust": {"scores": KITTI_SCORES}} if profile == "robust" else {})})
    rates = []
    for _ in range(reps):
        start = time.perf_counter()
        for dets in seqs:
            track(dets, config.build_tracker(None))
        rates.append(frames / (time.perf_counter() - start))
    return float(np.median(rates))


def bench_static_map(sizes: list[int], reps: int = 5) -> None:
    """Median ms to take an N x N map (``ObstacleMap.from_occupied`` as the tracker does, posts under
    0.3 m left out) and µs for the birth check of 3 detections, per size in ``sizes``."""
    from common.geometry.occupancy import ObstacleMap

    rng = np.random.default_rng(0)
    for n in sizes:
        occupied = np.zeros((n, n), bool)
        occupied[::50, :], occupied[:, ::70] = True, True
        occupied[rng.integers(0, n, 2000), rng.integers(0, n, 2000)] = True
        takes = []
        for _ in range(reps):
            start = time.perf_counter()
            obstacles = ObstacleMap.from_occupied(occupied, 0.05, (0.0, 0.0, 0.0), 0.3)
            takes.append(time.perf_counter() - start)
        points = rng.uniform(0.0, n * 0.05, (3, 2))
        checks = []
        for _ in range(200):
            start = time.perf_counter()
            obstacles.blocked(points, 0.1)
            checks.append(time.perf_counter() - start)
        print(f"static map {n} x {n} cells of 5 cm ({n * 0.05:g} m square): taken in {np.median(takes) * 1e3:.1f} ms, "
              f"{obstacles.occupied.nbytes / 2**20:.1f} MiB; birth check of 3 detections {np.median(checks) * 1e6:.0f} µs")


def bench_profile(profile: str, args: argparse.Namespace, bar: Bar) -> None:
    """The update table and the ``perception track`` throughput of one profile; ``bar`` counts the cases."""
    config = TrackerConfig(memory_path=None, profile=profile)
    off = args.without if profile == "robust" else []
    if off:  # what the per-track filters beyond association cost: time the update without them
        config = config.model_copy(update={"robust": config.robust.model_copy(update={
            k: getattr(config.robust, k).model_copy(update={"enabled": False}) for k in off})})
    print(f"\nprofile {profile}" + (f", without {' and '.join(off)}" if off else "") + "\n")
    print("| people | " + " | ".join(f"gallery {g}" for g in args.gallery) + " |")
    print("|---:|" + "---:|" * len(args.gallery))
    for n in args.people:
        cells = []
        for g in args.gallery:
            med, p95 = bench_update(n, g, args.reps, config)
            cells.append(f"{med:.3f} / {p95:.3f}")
            bar.update()
        print(f"| {n} | " + " | ".join(cells) + " |", flush=True)
    print()
    with tempfile.TemporaryDirectory() as tmp:
        for people in OFFLINE_PEOPLE:
            core_fps, total_fps = bench_offline(people, args.offline_frames, config, Path(tmp))
            bar.update()
            print(f"perception track ({profile}), {people} people, {args.offline_frames} frames with {DIM}-D "
                  f"embeddings: {core_fps:.0f} frames/s tracking, {total_fps:.0f} frames/s including CSV read/write")
    kitti = bench_kitti(profile, args.kitti_reps, args.data)  # a few seconds: not a case of the bar
    print(f"perception track ({profile}), KITTI dev split position-only (score >= 2.683): "
          + (f"{kitti:,.0f} frames/s tracking" if kitti is not None else f"skipped, no {args.data / 'kitti_ped_dev'}"))


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--reps", type=int, default=60, help="timed updates per case (default 60)")
    parser.add_argument("--people", type=int, nargs="+", default=[1, 5, 10, 20, 50])
    parser.add_argument("--gallery", type=int, nargs="+", default=[10, 100, 500])
    parser.add_argument("--offline-frames", type=int, default=600, help="frames of the `track` throughput file")
    parser.add_argument("--profiles", nargs="+", default=list(PROFILES), choices=PROFILES, help="tracker profiles to time")
    parser.add_argument("--kitti-reps", type=int, default=7, help="passes over the KITTI dev split (default 7)")
    parser.add_argument("--data", type=Path, default=SHARED, help=f"shared data folder (default {SHARED})")
    parser.add_argument("--without", nargs="+", default=[], choices=("classifier", "posture"),
                        help="robust: time it with these per-track filters off (Basso/Munaro's online classifiers, "
                             "the TU Ilmenau posture and orientation filters), to see what they cost")
    parser.add_argument("--map-sizes", type=int, nargs="*", default=[400, 2000, 4000], metavar="N",
                        help="static maps of N x N cells to time taking and checking (none: skip)")
    args = parser.parse_args()
    logging.basicConfig(level=logging.WARNING)
    print(f"tracker update, ms (median / p95), {DIM}-D descriptors, {args.reps} updates per case")
    print(f"machine: {platform.machine()}, {os.cpu_count()} CPUs, python {platform.python_version()}, numpy {np.__version__}, "
          f"BLAS threads {os.environ['OPENBLAS_NUM_THREADS']}")
    cases = len(args.profiles) * (len(args.people) * len(args.gallery) + len(OFFLINE_PEOPLE))
    with progress_bar(cases, desc="tracker", unit="case") as bar:
        for profile in args.profiles:
            bench_profile(profile, args, bar)
    if args.map_sizes:
        print()
        bench_static_map(args.map_sizes)


if __name__ == "__main__":
    main()
