"""Embedder throughput: descriptors/s and ms per frame for 1, 4 and 16 crops per frame.

Backends: ``colour``; ``onnx`` with a conv net of Re-ID size built here (random weights,
256x128 input, 512-D); and the exported MobileNetV2 (``perception export-embedder``)
when it is present. Crops are synthetic pedestrians of 60 to 200 px height, so the
resize cost is included. Prints median and p95 per frame.

    .venv/bin/python benchmarks/embedder.py [--repeats 30] [--threads 0]
    .venv/bin/python benchmarks/embedder.py --reid [--pets-step 5] [--sim-seconds 90]

``--reid`` measures Re-ID instead (``benchmarks/reid_data.py``): rank-1, mAP and pair AUC
with same-person crops under 5 s apart left out of each query's gallery,

* on ``pets09_dev`` ground-truth crops (every ``--pets-step``-th frame), the ``colour``
  descriptor beside the 6-stripe HSV-histogram + Bhattacharyya anchor computed here;
* on the simulated apartment (three scenarios, one frame a second, people at least 60 %
  visible, each box the person's visible pixels widened by 15 %), ``colour`` with and
  without the depth mask the embedder applies when frames carry depth.
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

from common.runtime.progress import Bar, progress_bar  # noqa: E402
from services.embedder.core.backend import Backend  # noqa: E402
from services.embedder.core.colour import ColourDescriptor  # noqa: E402
from services.embedder.core.depth_mask import DepthMaskParams, depth_masks  # noqa: E402
from tests.fixtures.embedder_synthetic import random_outfit, render_person  # noqa: E402


def crops(n: int, rng: np.random.Generator) -> list[np.ndarray]:
    out = []
    for _ in range(n):
        h = int(rng.integers(60, 200))
        out.append(render_person(random_outfit(rng), rng, size=(h, max(h // 2, 8))))
    return out


CROPS_PER_FRAME = (1, 4, 16)


def measure(backend: Backend, per_frame: int, repeats: int, rng: np.random.Generator,
            bar: Bar | None = None) -> tuple[float, float]:
    """(median, p95) ms per frame of ``per_frame`` crops over ``repeats`` frames after one warm-up;
    ``bar`` counts every frame."""
    frames = [crops(per_frame, rng) for _ in range(4)]
    backend.embed(frames[0])  # warm-up
    times = []
    for i in range(repeats):
        t0 = time.perf_counter()
        backend.embed(frames[i % len(frames)])
        times.append((time.perf_counter() - t0) * 1e3)
        if bar is not None:
            bar.update()
    return float(np.median(times)), float(np.percentile(times, 95))


SIM_SCENARIOS = ("still", "moving-head", "changing-clothes-out-of-view")


def reid(pets_step: int, sim_seconds: float) -> None:
    """Print the Re-ID tables (see the module docstring)."""
    from benchmarks.reid_data import (bhattacharyya_matrix, euclidean_matrix, hsv_stripes_anchor, pets_crops,
                                      reid_scores, sim_crops)

    shared = Path(os.environ.get("PERCEPTION_SHARED_DATA", Path(__file__).resolve().parents[2] / "shared" / "data"))
    colour = ColourDescriptor()
    card = colour.card
    print("| data | descriptor | crops | people | rank-1 | mAP | AUC |")
    print("|---|---|---:|---:|---:|---:|---:|")
    root = shared / "pets09_dev"
    if (root / "gt.txt").is_file():
        c = pets_crops(root, step=pets_step)
        n, k = len(c.images), len(set(c.ids.tolist()))
        a = reid_scores(bhattacharyya_matrix(hsv_stripes_anchor(c.images)), c.ids, c.times_s)
        print(f"| pets09_dev, every {pets_step}th frame | anchor: 6-stripe HSV 8x4x4, Bhattacharyya | {n} | {k} | "
              f"{a.rank1:.3f} | {a.mAP:.3f} | {a.auc:.3f} |")
        e = reid_scores(euclidean_matrix(colour.embed(c.images)), c.ids, c.times_s)
        print(f"| pets09_dev, every {pets_step}th frame | {card.name} ({card.dim}-D) | {n} | {k} | "
              f"{e.rank1:.3f} | {e.mAP:.3f} | {e.auc:.3f} |", flush=True)
    else:
        print(f"(pets09_dev not found in {root})")
    params = DepthMaskParams(depth_unit_m=1.0)  # sim_crops gives metres
    for name in SIM_SCENARIOS:
        c = sim_crops(name, seconds=sim_seconds, fps=1.0)
        assert c.depths is not None
        masks = [depth_masks(d, [(0, 0, d.shape[1], d.shape[0])], params)[0][0] for d in c.depths]
        n, k = len(c.images), len(set(c.ids.tolist()))
        a = reid_scores(bhattacharyya_matrix(hsv_stripes_anchor(c.images)), c.ids, c.times_s)
        print(f"| sim {name}, {sim_seconds:g} s | anchor | {n} | {k} | {a.rank1:.3f} | {a.mAP:.3f} | {a.auc:.3f} |")
        for label, m in (("no mask", None), ("depth mask", masks)):
            e = reid_scores(euclidean_matrix(colour.embed(c.images, masks=m)), c.ids, c.times_s)
            print(f"| sim {name}, {sim_seconds:g} s | {card.name}, {label} ({sum(x is not None for x in masks)} "
                  f"masked) | {n} | {k} | {e.rank1:.3f} | {e.mAP:.3f} | {e.auc:.3f} |" if m is not None else
                  f"| sim {name}, {sim_seconds:g} s | {card.name}, {label} | {n} | {k} | {e.rank1:.3f} | "
                  f"{e.mAP:.3f} | {e.auc:.3f} |", flush=True)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--repeats", type=int, default=30)
    parser.add_argument("--threads", type=int, default=0, help="onnxruntime intra-op threads (0: default)")
    parser.add_argument("--providers", default=None, metavar="P1,P2",
                        help="onnxruntime execution providers for the onnx rows (default: TensorRT, CUDA, CPU as "
                             "available); rows on CPU alone are added beside them when these are not CPU")
    parser.add_argument("--model", default=None, metavar="FILE.onnx",
                        help="also time this Re-ID model (input (N, 3, 256, 128))")
    parser.add_argument("--reid", action="store_true", help="Re-ID accuracy instead of speed")
    parser.add_argument("--pets-step", type=int, default=5, help="--reid: every n-th pets09_dev frame")
    parser.add_argument("--sim-seconds", type=float, default=90.0, help="--reid: seconds per simulated scenario")
    args = parser.parse_args()
    if args.reid:
        reid(max(args.pets_step, 1), args.sim_seconds)
        return
    from services.embedder.config import OnnxConfig, with_sidecar
    from services.embedder.core.onnx_model import OnnxEmbedder, OnnxParams
    from services.embedder.export_cli import default_model_path

    backends: list[tuple[str, Backend]] = [(f"colour ({ColourDescriptor.card.dim}-D)", ColourDescriptor())]
    chosen = tuple(x.strip() for x in args.providers.split(",") if x.strip()) if args.providers else None
    runs = [chosen] if chosen in (None, ("CPUExecutionProvider",)) else [chosen, ("CPUExecutionProvider",)]

    def onnx_rows(name: str, **params: object) -> None:
        for providers in runs:
            backends.append((name, OnnxEmbedder(OnnxParams(**params, providers=providers,  # type: ignore[arg-type]
                                                           intra_op_threads=args.threads))))

    tmp = tempfile.TemporaryDirectory()
    try:
        from tests.fixtures.embedder_onnx_models import conv_model

        onnx_rows("onnx conv net 256x128, 512-D", path=str(conv_model(Path(tmp.name) / "reid_like.onnx")))
    except ImportError:
        print("(onnx package missing: the test-built graph is skipped; pip install -e '.[test]')")
    if args.model:
        onnx_rows(f"onnx {Path(args.model).name}", path=args.model)
    exported = default_model_path()
    if exported.is_file():
        o = with_sidecar(OnnxConfig(path=str(exported)))
        onnx_rows(f"onnx MobileNetV2 {o.input_size[0]}x{o.input_size[1]}, 1280-D", path=o.path, name=o.name,
                  input_size=o.input_size)
    else:
        print(f"(exported MobileNetV2 not found at {exported}: run 'perception export-embedder')")
    rng = np.random.default_rng(0)
    print(f"machine: {platform.machine()}, {os.cpu_count()} CPUs, {platform.processor() or platform.platform()}")
    print("\n| backend | provider | crops/frame | ms/frame median | ms/frame p95 | descriptors/s |")
    print("|---|---|---|---|---|---|")
    with progress_bar(len(backends) * len(CROPS_PER_FRAME) * args.repeats, desc="embedder", unit="frame") as bar:
        for name, backend in backends:
            for n in CROPS_PER_FRAME:
                med, p95 = measure(backend, n, args.repeats, rng, bar)
                provider = getattr(backend, "providers", ["numpy/cv2"])[0]
                print(f"| {name} | {provider} | {n} | {med:.2f} | {p95:.2f} | {n / med * 1e3:.0f} |", flush=True)
    tmp.cleanup()


if __name__ == "__main__":
    main()
