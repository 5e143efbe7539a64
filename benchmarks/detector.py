"""Detector backends: ms per frame at 640x480 and 320x240, median and p95; HOG's accuracy on pets09_dev.

    python benchmarks/detector.py [--repeats 30] [--backends hog,depth,...]
    python benchmarks/detector.py --pets [--pets-step 1]   # accuracy only
    python benchmarks/detector.py --sim [--sim-frames 24] [--against REV]   # depth, the simulator's frames

``--pets``: the HOG backend on the 400 frames of ``../shared/data/pets09_dev`` (every
``--pets-step``-th), scored by ``benchmarks/detector_accuracy.py``: PASCAL-VOC AP at
IoU >= 0.5 and the foot-point error on the ground plane through the homography. The
raw windows are computed once per upsampling factor at the lowest threshold of the
table, and each row's settings turn them into boxes (``HogDetector.boxes_from_windows``),
so the rows differ only in what they name. "window fit 0.6 x 0.8, no voting" are the
settings before the boxes were fitted to the person.

``--sim``: the depth backend on the simulator's own 640x480 frames, every scenario
(``benchmarks/detector_sim.py``): its core and the detector service's whole step per frame,
median and p95 per scenario and overall; ``--against REV`` also runs the core as it was at
git revision REV on the same frames, interleaved, and compares their detections.

Inputs: a PETS09 frame resized to each size when ../shared/data is present (else a
rendered scene) for the RGB backends; a rendered floor + people + table scene for
``depth``. No model is downloaded: ``yolo-onnx`` runs a graph built here (strided
convolutions on a 640x640 input and three heads concatenated to the YOLOv8 output
shape (1, 84, 8400), random weights), and ``darknet`` a YOLOv3-tiny-shaped cfg at
416x416 with random weights. They measure the pipeline cost (letterbox, inference,
decoding, NMS) of networks of that size, not accuracy.
"""

from __future__ import annotations

import argparse
import os
import sys
import tempfile
import time
from pathlib import Path
from typing import Callable

if "--sim" in sys.argv:  # as the demo runs the detector process (numpy's BLAS on one thread)
    os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")
    os.environ.setdefault("OMP_NUM_THREADS", "1")

import numpy as np  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

import cv2  # noqa: E402

from common.runtime.progress import Bar, progress, progress_bar  # noqa: E402
from services.detector.core.darknet import DarknetDetector, DarknetParams  # noqa: E402
from services.detector.core.depth import DepthClusterDetector, DepthParams  # noqa: E402
from services.detector.core.hog import HogDetector, HogParams  # noqa: E402
from services.detector.core.yolo_onnx import YoloOnnxDetector, YoloParams  # noqa: E402
from tests.fixtures.detector_synthetic import Block, render_depth, scene_intrinsics  # noqa: E402

SIZES = ((640, 480), (320, 240))
SHARED = Path(os.environ.get("PERCEPTION_SHARED_DATA", ROOT.parent / "shared" / "data"))


def yolo_v8_like_onnx(path: Path, seed: int = 0) -> Path:
    """Backbone of stride-2 3x3 convs (16..256 channels) and 1x1 heads at strides 8/16/32 -> (1, 84, 8400)."""
    from onnx import TensorProto, helper, numpy_helper

    rng = np.random.default_rng(seed)
    inits, nodes = [], []

    def conv(x: str, cin: int, cout: int, k: int, stride: int, name: str, bias: float = 0.0, act: bool = True) -> str:
        w = (rng.normal(size=(cout, cin, k, k)) * np.sqrt(2.0 / (cin * k * k))).astype(np.float32)
        inits.append(numpy_helper.from_array(w, f"{name}_w"))
        inits.append(numpy_helper.from_array(np.full(cout, bias, np.float32), f"{name}_b"))
        nodes.append(helper.make_node("Conv", [x, f"{name}_w", f"{name}_b"], [f"{name}_c"], kernel_shape=[k, k],
                                      strides=[stride, stride], pads=[k // 2] * 4))
        if not act:
            return f"{name}_c"
        nodes.append(helper.make_node("Relu", [f"{name}_c"], [name]))
        return name

    x, cin = "images", 3
    feats = {}
    for i, cout in enumerate((16, 32, 64, 128, 256)):  # strides 2, 4, 8, 16, 32
        x = conv(x, cin, cout, 3, 2, f"b{i}")
        x = conv(x, cout, cout, 3, 1, f"b{i}x")
        cin = cout
        feats[2 ** (i + 1)] = (x, cout)
    heads = []
    for stride in (8, 16, 32):
        f, c = feats[stride]
        h = conv(f, c, 84, 1, 1, f"head{stride}", bias=-6.0, act=False)
        inits.append(numpy_helper.from_array(np.array([1, 84, -1], np.int64), f"shape{stride}"))
        nodes.append(helper.make_node("Reshape", [h, f"shape{stride}"], [f"flat{stride}"]))
        heads.append(f"flat{stride}")
    nodes.append(helper.make_node("Concat", heads, ["cat"], axis=2))
    nodes.append(helper.make_node("Sigmoid", ["cat"], ["output0"]))
    graph = helper.make_graph(nodes, "yolo_v8_like", [helper.make_tensor_value_info("images", TensorProto.FLOAT, [1, 3, 640, 640])],
                              [helper.make_tensor_value_info("output0", TensorProto.FLOAT, [1, 84, 8400])], initializer=inits)
    model = helper.make_model(graph, opset_imports=[helper.make_opsetid("", 13)])
    model.ir_version = 8
    path.write_bytes(model.SerializeToString())
    return path


def yolov3_tiny_like_darknet(folder: Path, seed: int = 0) -> tuple[Path, Path]:
    """A YOLOv3-tiny-shaped cfg (416x416, 80 classes, two YOLO heads) with random weights."""
    rng = np.random.default_rng(seed)
    lines = ["[net]", "width=416", "height=416", "channels=3", ""]
    weights: list[np.ndarray] = []
    channels = [3]

    def conv(filters: int, size: int, bn: bool = True, act: str = "leaky", bias: float = 0.0) -> None:
        lines.extend(["[convolutional]", f"batch_normalize={int(bn)}", f"filters={filters}", f"size={size}", "stride=1",
                      "pad=1", f"activation={act}", ""])
        cin = channels[-1]
        if bn:
            weights.extend([np.zeros(filters), np.ones(filters), np.zeros(filters), np.ones(filters)])
        else:
            weights.append(np.full(filters, bias))
        weights.append(rng.normal(size=filters * cin * size * size) * np.sqrt(2.0 / (cin * size * size)))
        channels.append(filters)

    def other(text: str, out_channels: int) -> None:
        lines.extend([*text.split("\n"), ""])
        channels.append(out_channels)

    yolo = "[yolo]\nmask={mask}\nanchors=10,14,23,27,37,58,81,82,135,169,344,319\nclasses=80\nnum=6"
    for i, f in enumerate((16, 32, 64, 128, 256, 512)):
        conv(f, 3)
        other(f"[maxpool]\nsize=2\nstride={2 if i < 5 else 1}", f)
    conv(1024, 3)
    conv(256, 1)
    conv(512, 3)
    conv(255, 1, bn=False, act="linear", bias=-6.0)
    other(yolo.format(mask="3,4,5"), 255)
    other("[route]\nlayers=-4", 256)
    conv(128, 1)
    other("[upsample]\nstride=2", 128)
    other("[route]\nlayers=-1,8", 128 + 256)
    conv(256, 3)
    conv(255, 1, bn=False, act="linear", bias=-6.0)
    other(yolo.format(mask="0,1,2"), 255)
    cfg = folder / "yolov3-tiny-like.cfg"
    cfg.write_text("\n".join(lines))
    path = folder / "yolov3-tiny-like.weights"
    header = np.array([0, 2, 0], np.int32).tobytes() + np.array([0], np.int64).tobytes()
    path.write_bytes(header + np.concatenate(weights).astype(np.float32).tobytes())
    return cfg, path


def rgb_frame(width: int, height: int) -> np.ndarray:
    frame = SHARED / "pets09" / "frame_0040.png"
    if frame.is_file():
        bgr = cv2.imread(str(frame))
        return cv2.cvtColor(cv2.resize(bgr, (width, height), interpolation=cv2.INTER_LINEAR), cv2.COLOR_BGR2RGB)
    return depth_scene(width, height)[0]


def depth_scene(width: int, height: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    K = scene_intrinsics(width, height)
    blocks = [Block(-0.8, 3.5, 0.5, 1.75, 0.3), Block(0.9, 4.5, 0.45, 1.6, 0.3), Block(0.0, 2.6, 1.0, 0.75, 0.6)]
    depth, rgb = render_depth(blocks, K, width, height, 1.2, 10.0)
    rng = np.random.default_rng(0)
    depth = depth + rng.normal(0, 0.005, depth.shape).astype(np.float32) * depth ** 2  # ~quadratic depth noise
    return rgb, depth, K


WARMUP = 2  # untimed frames before each row's timed ones


def measure(fn: Callable[[], object], repeats: int, bar: Bar | None = None) -> tuple[float, float]:
    """(median, p95) ms of ``fn`` over ``repeats`` calls after :data:`WARMUP`; ``bar`` counts every call."""
    for _ in range(WARMUP):
        fn()
        if bar is not None:
            bar.update()
    times = []
    for _ in range(repeats):
        start = time.perf_counter()
        fn()
        times.append((time.perf_counter() - start) * 1000.0)
        if bar is not None:
            bar.update()
    return float(np.median(times)), float(np.percentile(times, 95))


#: (label, HogParams) of the accuracy table; the old settings first.
PETS_ROWS: tuple[tuple[str, HogParams], ...] = (
    ("x2.25, window shrunk 0.6 x 0.8, no voting, threshold 1.0 (before)",
     HogParams(upsample=2.25, box_scale_x=0.6, box_scale_y=0.8, vote_iou=0.0)),
    ("x2.25, fit 0.5 x 0.75, no voting", HogParams(upsample=2.25, vote_iou=0.0)),
    ("x2.25, defaults (fit 0.5 x 0.75, voting 0.5, threshold 1.0)", HogParams(upsample=2.25)),
    ("x2.25, defaults, threshold 0.5", HogParams(upsample=2.25, hit_threshold=0.5)),
    ("x2.25, defaults, threshold 0", HogParams(upsample=2.25, hit_threshold=0.0)),
    ("x2.0, defaults", HogParams(upsample=2.0)),
    ("x2.0, defaults, threshold 0", HogParams(upsample=2.0, hit_threshold=0.0)),
)


def pets_accuracy(step: int) -> int:
    """Print the accuracy table of :data:`PETS_ROWS` on pets09_dev; 1 if the data is missing."""
    from benchmarks.detector_accuracy import load_truth, score_detections

    root = SHARED / "pets09_dev"
    if not (root / "gt.txt").is_file():
        print(f"pets09_dev not found in {root}")
        return 1
    truth = load_truth(root)
    paths = sorted((root / "frames").glob("frame_*.jpg"))[::step]
    frames = {int(p.stem.split("_")[1]): cv2.cvtColor(cv2.imread(str(p)), cv2.COLOR_BGR2RGB) for p in paths}
    windows: dict[float, dict[int, tuple[np.ndarray, np.ndarray]]] = {}
    ms: dict[float, float] = {}
    for up in sorted({params.upsample for _, params in PETS_ROWS}):
        lowest = min(params.hit_threshold for _, params in PETS_ROWS if params.upsample == up)
        det = HogDetector(HogParams(upsample=up))
        t0 = time.perf_counter()
        windows[up] = {f: det.windows(rgb, hit_threshold=lowest)
                       for f, rgb in progress(frames.items(), total=len(frames), desc=f"HOG x{up:g}", unit="frame")}
        ms[up] = (time.perf_counter() - t0) * 1e3 / len(frames)
    print(f"# HOG on pets09_dev: {len(frames)} frames of 480x360, AP at IoU >= 0.5 (conf-0 rows don't-care); "
          "foot-point error of the true positives on the ground plane through the homography")
    print("| settings | AP | precision | recall | foot error median m | mean m | window search ms/frame |")
    print("|---|---:|---:|---:|---:|---:|---:|")
    for label, params in PETS_ROWS:
        det = HogDetector(params)
        h, w = next(iter(frames.values())).shape[:2]
        dets = {f: det.boxes_from_windows(*windows[params.upsample][f], w, h) for f in frames}
        s = score_detections(truth, dets)
        print(f"| {label} | {s.ap:.3f} | {s.precision:.3f} | {s.recall:.3f} | {s.foot_median_m:.3f} | "
              f"{s.foot_mean_m:.3f} | {ms[params.upsample]:.0f} |", flush=True)
    return 0


def sim_table(args: argparse.Namespace) -> int:
    """Print the depth core's and the detector service's times on the simulator's frames."""
    import platform

    from benchmarks.detector_sim import (SIM_FPS, SIM_SIZE, compare, sim_frames, time_core, time_service,
                                         use_cpu_clock)
    from tools.simulator.core.scenarios import SCENARIOS

    use_cpu_clock(args.cpu_time)
    from services.detector.memory import keep_freed_memory

    kept = keep_freed_memory()  # as the detector process does

    names = args.scenarios.split(",") if args.scenarios else list(SCENARIOS)
    frames = {name: sim_frames(name, args.sim_frames) for name in progress(names, desc="frames", unit="scenario")}
    w, h = SIM_SIZE
    print(f"# depth detector on the simulator's frames: {args.sim_frames} per scenario, {w}x{h} at {SIM_FPS:g} fps; "
          f"{args.sim_passes} passes, {'CPU' if args.cpu_time else 'wall'} time; {platform.node()}, {os.cpu_count()} CPUs, Python {platform.python_version()}, "
          f"numpy {np.__version__}; freed memory kept: {'yes' if kept else 'no'}, as in the detector process")
    print("| scenario | frames | people boxes | core median ms | core p95 ms | service median ms | service p95 ms | "
          "service / core |")
    print("|---|---:|---:|---:|---:|---:|---:|---:|")
    all_core, all_node, all_inner = [], [], []
    for name in progress(names, desc="timing", unit="scenario"):
        group = frames[name]
        core = time_core(group, args.sim_passes)
        node, inner = time_service(group, args.sim_passes)
        all_core.append(core)
        all_node.append(node)
        all_inner.append(inner)
        print(f"| {name} | {len(group)} | {_boxes(group)} | {np.median(core):.1f} | {np.percentile(core, 95):.1f} | "
              f"{np.median(node):.1f} | {np.percentile(node, 95):.1f} | {node.sum() / inner.sum():.2f} |", flush=True)
    core, node, inner = (np.concatenate(a) for a in (all_core, all_node, all_inner))
    print(f"| **all** | {sum(len(g) for g in frames.values())} | | **{np.median(core):.1f}** | "
          f"{np.percentile(core, 95):.1f} | {np.median(node):.1f} | {np.percentile(node, 95):.1f} | "
          f"{node.sum() / inner.sum():.2f} |")
    if args.against:
        everything = [f for name in names for f in frames[name]]
        c = compare(everything, args.against)
        ratio = c.old_ms / c.new_ms
        print(f"\n# against {args.against}, paired (interleaved frame by frame): core median {np.median(c.old_ms):.1f} "
              f"-> {np.median(c.new_ms):.1f} ms, p95 {np.percentile(c.old_ms, 95):.1f} -> "
              f"{np.percentile(c.new_ms, 95):.1f} ms, speed-up per frame median {np.median(ratio):.2f}x "
              f"(p5 {np.percentile(ratio, 5):.2f}x)")
        print(f"detections: {c.identical} of {c.frames} frames identical (boxes and scores bit for bit); "
              f"largest box difference {c.max_box_px:.2g} px, score {c.max_score:.2g}; "
              f"frames with another count: {c.count_differs or 'none'}")
        if c.identical != c.frames:
            return 1
    return 0


def _boxes(frames: list) -> int:
    """The people the current core finds in ``frames`` (in order, one detector)."""
    from benchmarks.detector_sim import _depth_detector, _plane

    det, ground = _depth_detector()
    return sum(len(det.detect(f.rgb, f.depth, f.K, floor=_plane(f.floor, ground))[0]) for f in frames)


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--repeats", type=int, default=30)
    parser.add_argument("--backends", default="hog,hog-x2.25,depth,depth+hog,yolo-onnx,darknet")
    parser.add_argument("--pets", action="store_true", help="HOG's AP and foot-point error on pets09_dev instead")
    parser.add_argument("--pets-step", type=int, default=1, help="use every n-th pets09_dev frame")
    parser.add_argument("--sim", action="store_true", help="the depth backend on the simulator's frames instead")
    parser.add_argument("--sim-frames", type=int, default=24, help="--sim: frames per scenario, evenly spaced")
    parser.add_argument("--sim-passes", type=int, default=3, help="--sim: timed passes over the frames")
    parser.add_argument("--scenarios", default=None, help="--sim: comma-separated scenarios (default all)")
    parser.add_argument("--cpu-time", action="store_true",
                        help="--sim: time in this thread's CPU time instead of wall time (a machine others load)")
    parser.add_argument("--against", default=None, metavar="REV",
                        help="--sim: also the depth core at git revision REV, paired, and its detections compared")
    args = parser.parse_args()
    if args.pets:
        return pets_accuracy(max(args.pets_step, 1))
    if args.sim:
        return sim_table(args)
    wanted = args.backends.split(",")
    models = tempfile.TemporaryDirectory(prefix="detector-bench-")  # removed at exit
    tmp = Path(models.name)
    factories: dict[str, Callable[[], object]] = {
        "hog": lambda: HogDetector(),
        "hog-x2.25": lambda: HogDetector(HogParams(upsample=2.25)),
        "depth": lambda: DepthClusterDetector(DepthParams(camera_height_m=1.2, tilt_deg=10.0)),
        "depth+hog": lambda: DepthClusterDetector(DepthParams(camera_height_m=1.2, tilt_deg=10.0, hog_confirm=True,
                                                              hog_min_score=0.0)),
        "yolo-onnx": lambda: YoloOnnxDetector(YoloParams(model=yolo_v8_like_onnx(tmp / "v8like.onnx"),
                                                         providers=("CPUExecutionProvider",))),
        "darknet": lambda: DarknetDetector(DarknetParams(*yolov3_tiny_like_darknet(tmp))),
    }
    print(f"# detector backends, ms per frame over {args.repeats} frames ({os.cpu_count()} CPUs, "
          f"OpenCV {cv2.__version__}, {cv2.getNumThreads()} OpenCV threads)")
    print("| backend | input | median ms | p95 ms |")
    print("|---|---|---:|---:|")
    with progress_bar(len(wanted) * len(SIZES) * (WARMUP + args.repeats), desc="detector", unit="frame") as bar:
        for name in wanted:
            detector = factories[name]()
            for width, height in SIZES:
                if name.startswith("depth"):
                    rgb, depth, K = depth_scene(width, height)
                    run: Callable[[], object] = lambda: detector.detect(rgb, depth, K)  # noqa: E731
                else:
                    rgb = rgb_frame(width, height)
                    run = lambda: detector.detect(rgb)  # noqa: E731
                median, p95 = measure(run, args.repeats, bar)
                print(f"| {name} | {width}x{height} | {median:.1f} | {p95:.1f} |", flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
