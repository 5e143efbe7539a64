"""Time per frame of the localizer for 1, 10 and 30 boxes on 640x480 depth; prints median and p95.

Rows:
* ``core``: depth percentile per box, rays (with plumb_bob undistortion or without),
  covariances, transform lookup through map <- odom <- base_link <- camera with
  interpolation, and the rotation into the map frame.
* ``service``: the whole path of one frame through LocalizerService on the in-memory
  transport: decoding the RGBDFrame and Detections, the core, building and encoding
  LocalizedDetections (the frame's RGB payload included in the decode).

Run: ``.venv/bin/python benchmarks/localizer.py [--repeats N]``
"""

from __future__ import annotations

import argparse
import os
import platform
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from common.geometry.transforms import PinholeCamera, TransformBuffer  # noqa: E402
from common.geometry.messages import add_batch  # noqa: E402
from common.messages.keys import RELIABLE, Keys  # noqa: E402
from common.transport.memory import MemoryBus  # noqa: E402
from common.runtime.progress import Bar, progress_bar  # noqa: E402
from common.messages.schemas import (  # noqa: E402
    Detection,
    Detections,
    LocalizedDetections,
    RGBDFrame,
    TransformBatch,
)
from services.localizer.config import LocalizerConfig  # noqa: E402
from services.localizer.core import LocalizerParams, localize  # noqa: E402
from services.localizer.service import LocalizerService  # noqa: E402
from tests.fixtures import localizer_scene as scene  # noqa: E402
from tests.fixtures.localizer_synthetic import Person, render_depth  # noqa: E402

K = np.array([[525.0, 0.0, 319.5], [0.0, 525.0, 239.5], [0.0, 0.0, 1.0]])
PLUMB_BOB = np.array([-0.28, 0.09, 0.001, -0.0005, -0.01])


def random_boxes(n: int, rng: np.random.Generator) -> np.ndarray:
    """(n, 4) person-sized boxes inside a 640x480 image."""
    w = rng.uniform(50, 130, n)
    h = rng.uniform(150, 380, n)
    x1 = rng.uniform(0, 640 - w)
    y1 = rng.uniform(0, 480 - h)
    return np.column_stack([x1, y1, x1 + w, y1 + h])


def stats(samples: list[float]) -> tuple[float, float]:
    a = np.array(samples) * 1e3
    return float(np.median(a)), float(np.percentile(a, 95))


def bench_core(n: int, camera: PinholeCamera, repeats: int, bar: Bar) -> tuple[float, float]:
    """(median, p95) ms of the core on one frame with ``n`` boxes; ``bar`` counts the frames."""
    rng = np.random.default_rng(n)
    people = [Person((float(x), 0.1, float(z))) for x, z in zip(rng.uniform(-1.5, 1.5, 4), rng.uniform(2, 6, 4))]
    depth = np.round(render_depth(camera, people) * 1000).astype(np.uint16)
    buf = TransformBuffer()
    add_batch(buf, scene.tf_static(), static=True)
    for k in range(-10, 11):
        add_batch(buf, scene.tf(scene.T0 + k * scene.S // 10))
    params = LocalizerParams()
    times = []
    for _ in range(repeats):
        boxes = random_boxes(n, rng)
        stamp = scene.T0 + int(rng.uniform(-0.9, 0.9) * scene.S)
        t0 = time.perf_counter()
        loc = localize(depth, camera, boxes, params)
        tf = buf.lookup("map", "camera", stamp)
        loc.transformed(tf, "map")
        times.append(time.perf_counter() - t0)
        bar.update()
    return stats(times)


def bench_service(n: int, repeats: int, bar: Bar) -> tuple[float, float]:
    """(median, p95) ms of one service step with ``n`` boxes; ``bar`` counts the frames."""
    rng = np.random.default_rng(100 + n)
    bus = MemoryBus()
    keys = Keys()
    service = LocalizerService(bus.transport(), keys, LocalizerConfig())
    client = bus.transport()
    frames = client.publisher(keys.frames("head"), RGBDFrame, RELIABLE)
    dets = client.publisher(keys.detections("head"), Detections, RELIABLE)
    tf = client.publisher(keys.tf(), TransformBatch, RELIABLE)
    client.publisher(keys.tf_static(), TransformBatch, RELIABLE).put(scene.tf_static())
    out = client.subscribe(keys.localized("head"), LocalizedDetections, RELIABLE)
    people = [Person((0.0, 0.1, 3.0)), Person((1.0, 0.0, 4.5))]
    times = []
    for seq in range(1, repeats + 1):
        f = scene.frame(seq, people)
        d = Detections(
            header=f.header,
            image_width=640,
            image_height=480,
            detections=[Detection(index=i, bbox_xyxy=tuple(b), score=0.9) for i, b in enumerate(random_boxes(n, rng))],
        )
        tf.put(scene.tf(f.header.stamp_ns - scene.S // 20))
        tf.put(scene.tf(f.header.stamp_ns + scene.S // 20))
        frames.put(f)
        dets.put(d)
        t0 = time.perf_counter()
        published = service.poll(time.monotonic())
        times.append(time.perf_counter() - t0)
        assert len(published) == 1 and out.try_recv() is not None
        bar.update()
    return stats(times)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--repeats", type=int, default=200)
    args = parser.parse_args()
    print(
        f"machine: {platform.machine()} {platform.processor() or ''}, {os.cpu_count()} CPUs, Python {platform.python_version()}, "
        f"numpy {np.__version__}"
    )
    print("| path | boxes | median ms/frame | p95 ms/frame |")
    print("|---|---|---|---|")
    cameras = (
        ("core, pinhole", PinholeCamera(K, 640, 480)),
        ("core, plumb_bob", PinholeCamera(K, 640, 480, PLUMB_BOB)),
    )
    boxes, service_repeats = (1, 10, 30), max(20, args.repeats // 2)
    total = len(boxes) * (len(cameras) * args.repeats + service_repeats)
    with progress_bar(total, desc="localizer", unit="frame") as bar:
        for label, camera in cameras:
            for n in boxes:
                med, p95 = bench_core(n, camera, args.repeats, bar)
                print(f"| {label} | {n} | {med:.2f} | {p95:.2f} |", flush=True)
        for n in boxes:
            med, p95 = bench_service(n, service_repeats, bar)
            print(f"| service step (decode + core + encode) | {n} | {med:.2f} | {p95:.2f} |", flush=True)


if __name__ == "__main__":
    main()
