"""The depth detector on the simulator's own frames (``benchmarks/detector.py --sim``).

Frames: every scenario of ``tools/simulator``, ``--sim-frames`` frames each (default 24),
evenly spaced over the scenario, rendered at 640x480 and 30 fps as ``perception demo --fps 30
--width 640 --height 480`` renders them. Each frame goes through the simulator's messages
and the detector service on the in-memory bus (encoding, decoding, the floor from the
transforms); the encoded frame and transform messages and the floor plane the service found
are kept, and the frame is decoded as the service decodes it. They are cached under ``benchmarks/.cache`` (git-ignored), keyed by the
scenario, the size, the frame rate, the sample and a hash of the simulator's and ``common``'s
code, so only the first run renders (about 2 minutes of CPU on the 2-core VM; 200 MB of cache).

Timed: the core (``DepthClusterDetector.detect``, the demo's settings, one detector per
scenario over its frames in order) and the service's whole step per frame
(``DetectorService.poll``: taking in the transforms, decoding the frame message, the floor
lookup, the core, building and publishing ``Detections``), median and p95 per scenario and
overall.

``--against REV``: the depth core as it was at git revision ``REV`` too (its
``services/detector/core`` files, read with ``git show``), interleaved frame by frame with the
current one on the same frames (paired timings, so a loaded machine slows both alike), and
every frame's boxes and scores compared.
"""

from __future__ import annotations

import dataclasses
import hashlib
import importlib
import subprocess
import sys
import tempfile
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
CACHE = ROOT / "benchmarks" / ".cache"
SIM_SIZE = (640, 480)
SIM_FPS = 30.0
#: The code whose changes change the frames (and what the service hands its core).
FRAME_CODE = ("tools/simulator", "common")

__all__ = ["SimFrame", "compare", "reference_core", "sim_frames", "time_core", "time_service", "use_cpu_clock"]


@dataclass
class SimFrame:
    """One frame as the detector service hands it to the core."""

    scenario: str
    seq: int
    rgb: np.ndarray  # (H, W, 3) uint8
    depth: np.ndarray  # (H, W) float32 metres, NaN invalid
    K: np.ndarray  # (3, 3)
    floor: tuple[np.ndarray, float] | None  # the floor plane from the transforms (normal, offset)
    message: bytes  # the encoded RGBDFrame (for the service's timing)
    tf: list[bytes]  # the encoded TransformBatch messages published with it (tf_static first)


def _code_hash() -> str:
    h = hashlib.sha1()
    for folder in FRAME_CODE:
        for path in sorted((ROOT / folder).rglob("*.py")):
            h.update(str(path.relative_to(ROOT)).encode())
            h.update(path.read_bytes())
    return h.hexdigest()[:16]


def _seqs(scenario: str, frames: int, fps: float) -> list[int]:
    from tools.simulator.core.scenarios import SCENARIOS

    total = int(SCENARIOS[scenario].duration_s * fps)
    return sorted({int((k + 0.5) * total / frames) for k in range(frames)})


def _render(scenario: str, seqs: list[int], width: int, height: int, fps: float) -> list[SimFrame]:
    """Frames ``seqs`` of ``scenario`` through the simulator's messages and the detector service."""
    from common.messages.codec import encode
    from common.messages.keys import FRAMES, RELIABLE, Keys
    from common.messages.schemas import RGBDFrame, TransformBatch
    from common.transport.memory import MemoryBus
    from services.detector.config import DetectorConfig, build_detector
    from services.detector.service import DetectorService
    from tools.simulator.config import SimulatorConfig
    from tools.simulator.messages import static_transforms
    from tools.simulator.source import SimulatedStream

    keys = Keys(robot="bench")
    bus = MemoryBus()
    pub = bus.transport()
    stream = SimulatedStream(SimulatorConfig(scenario=scenario, width=width, height=height, fps=fps, start_ns=10**18,
                                             duration_s=0), keys)
    detector = build_detector(DetectorConfig(backend="depth"))
    seen: list[tuple[Any, ...]] = []
    real = detector.detect

    def record(rgb: np.ndarray, depth: Any = None, camera: Any = None, floor: Any = None) -> Any:
        seen.append((rgb, depth, camera, floor))
        return real(rgb, depth, camera, floor=floor)

    detector.detect = record  # type: ignore[method-assign]
    node = DetectorService(bus.transport(), keys, DetectorConfig(backend="depth"), detector=detector)
    publishers = {keys.frames("head"): pub.publisher(keys.frames("head"), RGBDFrame, FRAMES),
                  keys.tf(): pub.publisher(keys.tf(), TransformBatch, RELIABLE),
                  keys.tf_static(): pub.publisher(keys.tf_static(), TransformBatch, RELIABLE)}
    out = []
    for seq in seqs:
        fd, pairs = stream.messages(seq)
        pairs = [(k, m) for k, m in pairs if k in publishers]
        if not any(k == keys.tf_static() for k, _ in pairs):
            pairs.insert(0, (keys.tf_static(), static_transforms(fd, stream.stamp_ns(seq), "head",
                                                                   stream.world.head_moves)))
        for key, msg in pairs:
            publishers[key].put(msg)
        seen.clear()
        node.poll(0.0)
        if len(seen) != 1:
            raise RuntimeError(f"{scenario} frame {seq}: the detector service did not run its core once")
        rgb, depth, K, floor = seen[0]
        out.append(SimFrame(scenario, seq, np.ascontiguousarray(rgb), depth, np.asarray(K, np.float64),
                            None if floor is None else (np.asarray(floor.normal, np.float64), float(floor.offset)),
                            encode(pairs[-1][1]), [encode(m) for k, m in pairs if k != keys.frames("head")]))
    node.close()
    return out


def _save(path: Path, frames: list[SimFrame]) -> None:
    """The encoded messages and the floors (the images are read back from the messages)."""
    def ragged(rows: list[Any]) -> np.ndarray:
        out = np.empty(len(rows), dtype=object)
        out[:] = rows
        return out

    np.savez_compressed(
        path, seq=np.array([f.seq for f in frames]), has_floor=np.array([f.floor is not None for f in frames]),
        floor_normal=np.stack([f.floor[0] if f.floor else np.zeros(3) for f in frames]),
        floor_offset=np.array([f.floor[1] if f.floor else 0.0 for f in frames]),
        message=ragged([np.frombuffer(f.message, np.uint8) for f in frames]),
        tf=ragged([ragged([np.frombuffer(t, np.uint8) for t in f.tf]) for f in frames]))


def _load(path: Path, scenario: str) -> list[SimFrame]:
    from common.messages.codec import decode
    from common.messages.schemas import RGBDFrame

    z = np.load(path, allow_pickle=True)
    out = []
    for i, seq in enumerate(z["seq"]):
        message = z["message"][i].tobytes()
        frame = decode(RGBDFrame, message)  # as the service decodes it
        assert frame.depth is not None
        floor = (z["floor_normal"][i], float(z["floor_offset"][i])) if z["has_floor"][i] else None
        out.append(SimFrame(scenario, int(seq), frame.rgb.to_array(), frame.depth.depth_m(),
                            np.asarray(frame.camera_info.K, np.float64), floor, message,
                            [t.tobytes() for t in z["tf"][i]]))
    return out


def sim_frames(scenario: str, frames: int, width: int = SIM_SIZE[0], height: int = SIM_SIZE[1],
               fps: float = SIM_FPS, cache: Path | None = CACHE) -> list[SimFrame]:
    """The sample of ``scenario``'s frames (rendered, or read from the cache)."""
    seqs = _seqs(scenario, frames, fps)
    key = hashlib.sha1(repr((seqs, width, height, fps, _code_hash())).encode()).hexdigest()[:16]
    path = None if cache is None else cache / f"detector_sim_{scenario}_{width}x{height}_{key}.npz"
    if path is not None and path.is_file():
        return _load(path, scenario)
    out = _render(scenario, seqs, width, height, fps)
    if path is not None:
        path.parent.mkdir(parents=True, exist_ok=True)
        _save(path, out)
        out = _load(path, scenario)  # exactly what a cached run reads
    return out


def _plane(floor: tuple[np.ndarray, float] | None, module: Any) -> Any:
    return None if floor is None else module.Plane(floor[0].copy(), floor[1])


def _depth_detector(core: str = "services.detector.core") -> tuple[Any, Any]:
    """A depth detector with the demo's settings from the core package ``core``, and its ground module."""
    depth = importlib.import_module(f"{core}.depth")
    ground = importlib.import_module(f"{core}.ground")
    from services.detector.config import DepthConfig

    known = {f.name for f in dataclasses.fields(depth.DepthParams)}  # an older core lacks the newer settings
    params = depth.DepthParams(**{k: (ground.GroundParams(**vars(v)) if k == "ground" else v)
                                  for k, v in vars(DepthConfig().params()).items() if k in known})
    return depth.DepthClusterDetector(params), ground


#: The clock of the timings: wall time, or with ``use_cpu_clock`` this thread's CPU time (the
#: code is single-threaded: on a machine other processes load, CPU time is what an idle one's
#: wall time would be, near enough).
clock = time.perf_counter


def use_cpu_clock(on: bool = True) -> None:
    global clock
    clock = time.thread_time if on else time.perf_counter


def time_core(frames: list[SimFrame], passes: int = 1) -> np.ndarray:
    """ms per frame of the current core over ``frames`` in order, ``passes`` times (a fresh detector each)."""
    times = []
    for _ in range(passes):
        det, ground = _depth_detector()
        det.detect(frames[0].rgb, frames[0].depth, frames[0].K, floor=_plane(frames[0].floor, ground))  # warm-up
        for f in frames:
            plane = _plane(f.floor, ground)
            t0 = clock()
            det.detect(f.rgb, f.depth, f.K, floor=plane)
            times.append((clock() - t0) * 1e3)
    return np.array(times)


def time_service(frames: list[SimFrame], passes: int = 1) -> tuple[np.ndarray, np.ndarray]:
    """ms per frame of the detector service's step (``poll``: transforms, decoding, floor, core,
    publishing) and of its core's ``detect`` within it, the frames' encoded messages on the
    in-memory bus."""
    from common.messages.keys import FRAMES, RELIABLE, Keys
    from common.messages.schemas import RGBDFrame, TransformBatch
    from common.transport.memory import MemoryBus
    from services.detector.config import DetectorConfig
    from services.detector.service import DetectorService

    keys = Keys(robot="bench")
    node_ms, core_ms = [], []
    for _ in range(passes):
        bus = MemoryBus()
        pub = bus.transport()
        frame_pub = pub.publisher(keys.frames("head"), RGBDFrame, FRAMES)
        tf_pub = pub.publisher(keys.tf(), TransformBatch, RELIABLE)
        static_pub = pub.publisher(keys.tf_static(), TransformBatch, RELIABLE)
        node = DetectorService(bus.transport(), keys, DetectorConfig(backend="depth"))
        inner: list[float] = []
        real = node.detector.detect

        def timed(*args: Any, _real: Any = real, **kwargs: Any) -> Any:
            t0 = clock()
            out = _real(*args, **kwargs)
            inner.append((clock() - t0) * 1e3)
            return out

        node.detector.detect = timed  # type: ignore[method-assign]
        sink = bus.transport().subscribe(keys.detections("head"), None, RELIABLE)
        for k, f in enumerate([frames[0], *frames]):
            static_pub.put_encoded(f.tf[0])
            for t in f.tf[1:]:
                tf_pub.put_encoded(t)
            frame_pub.put_encoded(f.message)
            t0 = clock()
            node.poll(0.0)
            elapsed = (clock() - t0) * 1e3
            if k:  # the first is a warm-up
                node_ms.append(elapsed)
                core_ms.append(inner[-1])
            while sink.try_recv_raw() is not None:
                pass
        node.close()
    return np.array(node_ms), np.array(core_ms)


#: the folders of :func:`reference_core`'s packages, kept while the process runs
_REFERENCE_DIRS: list[tempfile.TemporaryDirectory[str]] = []


def reference_core(rev: str) -> str:
    """The ``services/detector/core`` package at git revision ``rev``, importable under a name of
    its own (its imports of itself renamed); returns that name."""
    name = "_detector_core_" + hashlib.sha1(rev.encode()).hexdigest()[:8]
    if name in sys.modules:
        return name
    where = tempfile.TemporaryDirectory(prefix="detector-ref-")  # removed at exit
    _REFERENCE_DIRS.append(where)
    folder = Path(where.name) / name
    folder.mkdir()
    listing = subprocess.run(["git", "-C", str(ROOT), "ls-tree", "--name-only", f"{rev}:services/detector/core"],
                             check=True, capture_output=True, text=True).stdout.split()
    for file in listing:
        if file.endswith(".py"):
            text = subprocess.run(["git", "-C", str(ROOT), "show", f"{rev}:services/detector/core/{file}"],
                                  check=True, capture_output=True, text=True).stdout
            (folder / file).write_text(text.replace("services.detector.core.", f"{name}."))
    sys.path.insert(0, str(folder.parent))
    importlib.import_module(name)
    return name


@dataclass
class Comparison:
    frames: int
    identical: int  # frames whose boxes and scores are equal bit for bit
    max_box_px: float  # the largest box coordinate difference (px) among frames with the same count
    max_score: float
    count_differs: list[tuple[str, int, int, int]]  # (scenario, seq, old count, new count)
    old_ms: np.ndarray
    new_ms: np.ndarray


def compare(frames: list[SimFrame], rev: str) -> Comparison:
    """The core at ``rev`` and the current one on ``frames`` (each scenario's in order, a fresh
    detector per scenario), interleaved frame by frame: paired timings and the outputs compared."""
    ref = reference_core(rev)
    identical, max_box, max_score, differs = 0, 0.0, 0.0, []
    old_ms, new_ms = [], []
    by_scenario: dict[str, list[SimFrame]] = {}
    for f in frames:
        by_scenario.setdefault(f.scenario, []).append(f)
    for group in by_scenario.values():
        old, old_ground = _depth_detector(ref)
        new, new_ground = _depth_detector()
        for k, f in enumerate(group):
            runs = []
            for det, ground, sink in ((old, old_ground, old_ms), (new, new_ground, new_ms))[:: 1 if k % 2 else -1]:
                plane = _plane(f.floor, ground)
                t0 = clock()
                boxes, scores = det.detect(f.rgb, f.depth, f.K, floor=plane)
                sink.append((clock() - t0) * 1e3)
                runs.append((boxes, scores))
            (b_old, s_old), (b_new, s_new) = runs if k % 2 else runs[::-1]
            if b_old.shape == b_new.shape and np.array_equal(b_old, b_new) and np.array_equal(s_old, s_new):
                identical += 1
            elif b_old.shape == b_new.shape:
                max_box = max(max_box, float(np.abs(b_old - b_new).max(initial=0.0)))
                max_score = max(max_score, float(np.abs(s_old - s_new).max(initial=0.0)))
            else:
                differs.append((f.scenario, f.seq, len(b_old), len(b_new)))
    return Comparison(len(frames), identical, max_box, max_score, differs, np.array(old_ms), np.array(new_ms))
