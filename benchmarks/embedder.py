"""Embedder throughput: descriptors/s and ms per frame for 1, 4 and 16 crops per frame.

Backends: ``colour``; ``onnx`` with a conv net of Re-ID size built here (random weights,
256x128 input, 512-D); and the exported MobileNetV2 (``perception export-embedder``)
when it is present. Crops are synthetic pedestrians of 60 to 200 px height, so the
resize cost is included. Prints median and p95 per frame.

    .venv/bin/python benchmarks/embedder.py [--repeats 30] [--threads 0]
"""

from __future__ import annotations

import argparse
import os
import platform
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))  # the repository root, for tests.fixtures

from services.embedder.core.backend import Backend  # noqa: E402
from services.embedder.core.colour import ColourDescriptor  # noqa: E402
from tests.fixtures.embedder_synthetic import random_outfit, render_person  # noqa: E402


def crops(n: int, rng: np.random.Generator) -> list[np.ndarray]:
    out = []
    for _ in range(n):
        h = int(rng.integers(60, 200))
        out.append(render_person(random_outfit(rng), rng, size=(h, max(h // 2, 8))))
    return out


def measure(backend: Backend, per_frame: int, repeats: int, rng: np.random.Generator) -> tuple[float, float]:
    frames = [crops(per_frame, rng) for _ in range(4)]
    backend.embed(frames[0])  # warm-up
    times = []
    for i in range(repeats):
        t0 = time.perf_counter()
        backend.embed(frames[i % len(frames)])
        times.append((time.perf_counter() - t0) * 1e3)
    return float(np.median(times)), float(np.percentile(times, 95))


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--repeats", type=int, default=30)
    parser.add_argument("--threads", type=int, default=0, help="onnxruntime intra-op threads (0: default)")
    args = parser.parse_args()
    from services.embedder.config import OnnxConfig, with_sidecar
    from services.embedder.core.onnx_model import OnnxEmbedder, OnnxParams
    from services.embedder.export_cli import default_model_path

    backends: list[tuple[str, Backend]] = [("colour (128-D)", ColourDescriptor())]
    tmp = tempfile.TemporaryDirectory()
    try:
        from tests.fixtures.embedder_onnx_models import conv_model

        path = conv_model(Path(tmp.name) / "reid_like.onnx")
        backends.append(("onnx conv net 256x128, 512-D", OnnxEmbedder(OnnxParams(path=str(path),
                                                                                  intra_op_threads=args.threads))))
    except ImportError:
        print("(onnx package missing: the test-built graph is skipped; pip install -e '.[test]')")
    exported = default_model_path()
    if exported.is_file():
        o = with_sidecar(OnnxConfig(path=str(exported)))
        backends.append((f"onnx MobileNetV2 {o.input_size[0]}x{o.input_size[1]}, 1280-D",
                         OnnxEmbedder(OnnxParams(path=o.path, name=o.name, input_size=o.input_size,
                                                 intra_op_threads=args.threads))))
    else:
        print(f"(exported MobileNetV2 not found at {exported}: run 'perception export-embedder')")
    rng = np.random.default_rng(0)
    providers = {name: getattr(b, "providers", ["numpy/cv2"])[0] for name, b in backends}
    print(f"machine: {platform.machine()}, {os.cpu_count()} CPUs, {platform.processor() or platform.platform()}")
    print("\n| backend | provider | crops/frame | ms/frame median | ms/frame p95 | descriptors/s |")
    print("|---|---|---|---|---|---|")
    for name, backend in backends:
        for n in (1, 4, 16):
            med, p95 = measure(backend, n, args.repeats, rng)
            print(f"| {name} | {providers[name]} | {n} | {med:.2f} | {p95:.2f} | {n / med * 1e3:.0f} |", flush=True)
    tmp.cleanup()


if __name__ == "__main__":
    main()
