"""Simulator frame rate: rendering (RGB + depth + ground truth) and the full message path.

Prints, per scenario and resolution, the median and p95 time per frame and the frames/s
of (a) the core (render + ground truth) and (b) a published frame (core + messages +
msgpack encoding). Three people; ``still`` (static camera: the background is cached)
and ``moving-base`` (every frame renders the whole apartment).

It then reports how often OpenCV's HOG people detector (default people SVM, 640x480)
finds the simulated people: (a) one person standing in the open at 2.5-5 m, four
facings x four outfits x standing/mid-stride; (b) scenario frames, every standing person
with >= 90 % of the body visible at 2-5 m (a hit = a HOG box containing the torso centre).

    python benchmarks/simulator.py [--frames 60] [--no-hog]
"""

from __future__ import annotations

import argparse
import platform
import time

import cv2
import numpy as np

from common.messages.codec import encode
from common.messages.keys import Keys
from common.runtime.progress import Bar, progress, progress_bar
from tools.simulator.config import SimulatorConfig
from tools.simulator.core.apartment import default_apartment
from tools.simulator.core.body import PersonPose, body_ellipsoids
from common.geometry.poses import OPTICAL_FROM_BODY, make_pose, planar_pose, rot_y
from tools.simulator.core.render import Renderer, default_camera
from tools.simulator.core.scenarios import SCENARIOS, build_world
from tools.simulator.core.simulation import Simulation
from tools.simulator.core.wardrobe import OUTFITS
from tools.simulator.source import SimulatedStream


def _stream(scenario: str, width: int, height: int) -> SimulatedStream:
    cfg = SimulatorConfig(scenario=scenario, width=width, height=height, fps=15.0, start_ns=0, duration_s=0)
    stream = SimulatedStream(cfg, Keys())
    stream.messages(0)  # plans the first paths, builds the planner's grid
    return stream


def _measure(scenario: str, width: int, height: int, frames: int, bar: Bar) -> tuple[np.ndarray, np.ndarray]:
    """Milliseconds per frame: render + ground truth, and the published frame (+ messages + encoding).

    ``bar`` counts every frame (``2 * frames``)."""
    stream = _stream(scenario, width, height)
    core = []
    for seq in range(1, frames + 1):
        t0 = time.perf_counter()
        stream.simulation.frame(seq)
        core.append(time.perf_counter() - t0)
        bar.update()
    stream = _stream(scenario, width, height)
    full = []
    for seq in range(1, frames + 1):
        t0 = time.perf_counter()
        for _, msg in stream.messages(seq)[1]:
            encode(msg)
        full.append(time.perf_counter() - t0)
        bar.update()
    return np.array(core) * 1e3, np.array(full) * 1e3


def _hog() -> cv2.HOGDescriptor:
    hog = cv2.HOGDescriptor()
    hog.setSVMDetector(cv2.HOGDescriptor.getDefaultPeopleDetector())
    return hog


def _detect(hog: cv2.HOGDescriptor, rgb: np.ndarray) -> np.ndarray:
    rects, _ = hog.detectMultiScale(cv2.cvtColor(rgb, cv2.COLOR_RGB2BGR), winStride=(8, 8), padding=(8, 8), scale=1.05)
    return np.asarray(rects).reshape(-1, 4)


def _hit(rects: np.ndarray, u: float, v: float) -> bool:
    return bool(
        np.any(
            (rects[:, 0] <= u)
            & (u <= rects[:, 0] + rects[:, 2])
            & (rects[:, 1] <= v)
            & (v <= rects[:, 1] + rects[:, 3])
        )
    )


def hog_controlled() -> dict[float, float]:
    """Hit rate per distance for one person in the open (camera 1.23 m high, tilted 0.12 rad down)."""
    hog, intr = _hog(), default_camera(640, 480)
    renderer = Renderer(default_apartment(), intr, seed=0)
    cam = (
        planar_pose(0.6, 2.0, 0.0)
        @ make_pose(rot_y(0.12), (0.05, 0, 1.15))
        @ make_pose(OPTICAL_FROM_BODY, (0.06, 0, 0.08))
    )
    dists, facings, outfits = (2.5, 3.0, 4.0, 5.0), (np.pi, 0.0, np.pi / 2, np.pi - 0.8), range(0, 8, 2)
    gaits = ((0.0, 0.0), (1.0, 1.0))
    rates = {}
    with progress_bar(len(dists) * len(facings) * len(outfits) * len(gaits), desc="HOG, one person",
                      unit="image") as bar:
        for dist in dists:
            hits = []
            for facing in facings:
                for outfit in outfits:
                    for gait, phase in gaits:
                        pose = PersonPose(0.6 + dist, 2.0, facing, phase=phase, gait=gait)
                        out = renderer.render(cam, body_ellipsoids(1.75, pose, OUTFITS[outfit], 0))
                        hits.append(_hit(_detect(hog, out.rgb), intr.cx, intr.cy))
                        bar.update()
            rates[dist] = float(np.mean(hits))
    return rates


def hog_scenario(name: str, seeds: tuple[int, ...] = (0, 1, 2), step: int = 15) -> tuple[int, int, int, int]:
    """(people at 2-5 m, hits, people at 2.6-5 m, hits) over scenario frames at 640x480."""
    hog, intr = _hog(), default_camera(640, 480)
    n = h = n_far = h_far = 0
    seqs = range(0, int(SCENARIOS[name].duration_s * 15), step)
    with progress_bar(len(seeds) * len(seqs), desc=f"HOG, {name}", unit="frame") as bar:
        for seed in seeds:
            sim = Simulation(build_world(name, seed=seed), intr, fps=15.0, seed=seed)
            for seq in seqs:
                fd = sim.frame(seq)
                rects = None
                for p in fd.people:
                    c = np.linalg.inv(fd.map_camera) @ np.append(p.position, 1.0)
                    if p.posture != "standing" or p.visible_fraction < 0.9 or not 2.0 <= c[2] <= 5.0:
                        continue
                    rects = _detect(hog, fd.render.rgb) if rects is None else rects
                    ok = _hit(rects, intr.fx * c[0] / c[2] + intr.cx, intr.fy * c[1] / c[2] + intr.cy)
                    n, h = n + 1, h + ok
                    if c[2] >= 2.6:
                        n_far, h_far = n_far + 1, h_far + ok
                bar.update()
    return n, h, n_far, h_far


def groundtruth_stats(name: str, seed: int = 0, fps: float = 15.0) -> tuple[float, int, int, float, int]:
    """(duration s, frames, counted people instances, % frames with ground truth, ids) at 320x240."""
    world = build_world(name, seed=seed)
    sim = Simulation(world, default_camera(320, 240), fps=fps, seed=seed)
    frames = int(np.ceil(world.duration_s * fps))
    counted = [sum(p.counted for p in sim.frame(seq).people)
               for seq in progress(range(frames), total=frames, desc=f"ground truth, {name}", unit="frame")]
    return world.duration_s, frames, int(np.sum(counted)), 100.0 * float(np.mean(np.array(counted) > 0)), len(world.ids)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--frames", type=int, default=60)
    parser.add_argument("--no-hog", action="store_true", help="skip the HOG hit rates")
    parser.add_argument("--gt-stats", action="store_true", help="also print ground-truth statistics per scenario")
    args = parser.parse_args()
    print(
        f"machine: {platform.processor() or platform.machine()}, {platform.python_implementation()} "
        f"{platform.python_version()}, numpy {np.__version__}"
    )
    print(
        "| scenario | resolution | render+GT median ms | p95 ms | frames/s "
        "| published frame median ms | p95 ms | frames/s |"
    )
    print("|---|---|---|---|---|---|---|---|")
    cases = [(scenario, size) for scenario in ("still", "moving-base") for size in ((320, 240), (640, 480))]
    with progress_bar(len(cases) * 2 * args.frames, desc="simulator", unit="frame") as bar:
        for scenario, (width, height) in cases:
            core, full = _measure(scenario, width, height, args.frames, bar)
            print(
                f"| {scenario} | {width}x{height} | {np.median(core):.1f} | {np.percentile(core, 95):.1f} | "
                f"{1e3 / np.median(core):.0f} | {np.median(full):.1f} | {np.percentile(full, 95):.1f} | "
                f"{1e3 / np.median(full):.0f} |"
            )
    if args.gt_stats:
        print("\nGround truth per scenario (seed 0, 15 fps), like the thesis dataset's Table I:")
        print("| sequence | duration s | frames | people instances | % frames with ground truth | IDs |")
        print("|---|---|---|---|---|---|")
        for name in SCENARIOS:
            dur, frames, inst, pct, ids = groundtruth_stats(name)
            print(f"| {name} | {dur:.1f} | {frames} | {inst} | {pct:.1f} | {ids} |")
    if args.no_hog:
        return
    print("\nHOG (OpenCV default people detector), one person in the open, 640x480:")
    print("| distance m | hit rate |\n|---|---|")
    for dist, rate in hog_controlled().items():
        print(f"| {dist:.1f} | {rate:.0%} |")
    print("\nHOG on scenario frames (standing, >= 90 % visible), 640x480, seeds 0-2:")
    print("| scenario | people 2-5 m | hit rate | people 2.6-5 m | hit rate |\n|---|---|---|---|---|")
    for name in ("still", "moving-head", "moving-base"):
        n, h, n_far, h_far = hog_scenario(name)
        print(f"| {name} | {n} | {h / max(n, 1):.0%} | {n_far} | {h_far / max(n_far, 1):.0%} |")


if __name__ == "__main__":
    main()
