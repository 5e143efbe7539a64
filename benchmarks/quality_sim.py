"""The simulated apartment in the tracking-quality benchmark (``benchmarks/quality.py``).

Each scenario runs once through ``tools.demo.inprocess.run_chain`` (simulator -> depth
detector -> localizer -> colour embedder -> tracker on one in-memory bus, every frame
processed, deterministic). What reaches the tracker is captured from the bus: per frame
the stamp, the localized positions, covariances and scores, and the embeddings (model
name, dimension, metric). The capture is cached under the cache folder, keyed by the
scenario, duration, frame rate, image size, seed, the nodes' settings and a hash of the
simulator's, the three nodes' and ``common``'s code, so a rerun only tracks and judges.

The trackers are then run offline on the captured inputs:

- this project's profiles through the core (``TrackerConfig.build_tracker`` and
  ``update``), fed exactly as ``TrackerService._update`` feeds them: stamps in seconds
  since the first frame, the detections' covariances when the profile uses them (plus
  the service's 1e-6 m^2 on the diagonal), the descriptors of a frame whose embeddings
  were published (NaN rows where the embedder gave none), position-only before the first
  embeddings message (the service learns the model's thresholds and metric from its model
  card). ``services/tracker/offline.track`` cannot do this: it passes no covariances.
- the position-only baselines on :func:`detections` (positions and scores).

Judging is the demo's Table II (``tools.demo.scoring.score_rows``): the simulator's
counted people (at least 25 % visible) of every frame, matched on the Euclidean distance
of the full (x, y, z) positions < 1 m; the torso centre is the ground truth's position.
"""

from __future__ import annotations

import functools
import hashlib
import json
import logging
import math
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Callable

import numpy as np

from common.runtime.progress import progress_bar
from common.messages.schemas import Embeddings, LocalizedDetections, Message, PeopleGroundTruth, Tracks
from services.tracker.config import TrackerConfig
from services.tracker.convert import descriptors_for, positions_of
from services.tracker.core.types import FrameResult
from services.tracker.core.view import FieldOfView
from services.tracker.core.types import FrameInput  # noqa: E402
from services.tracker.intake import R_EPS
from services.tracker.offline import Detections, Row
from tools.evaluation.evaluate import evaluate_tables
from tools.evaluation.metrics import ClearMot, FrameEvents
from tools.evaluation.readers import TrackTable

__all__ = ["CHAIN_PROFILE", "Capture", "SIM_FPS", "SIM_SECONDS", "capture", "chain_tracker_key", "detections",
           "judge_demo", "load_capture", "replay", "scenario_names"]

log = logging.getLogger(__name__)

ROOT = Path(__file__).resolve().parents[1]
SIM_FPS = 10.0
SIM_SECONDS = 60.0
SIM_SIZE = (320, 240)  # run_chain's default, as the README's "Results on the simulated apartment"
SIM_SEED = 0
SIM_DETECTOR = "depth"
#: The profile of the tracker inside the capture run; its figures check the offline replay.
CHAIN_PROFILE = "robust"
#: The code whose changes change what reaches the tracker.
INPUT_CODE = ("common", "services/detector", "services/localizer", "services/embedder", "tools/simulator",
              "tools/demo/inprocess.py")


#: Scenarios the camera's rows leave out by default: ``guided-tour`` is the laser's (its person
#: walks behind the robot, out of the head camera's view; the laser rows judge it), and the
#: published "8 scenarios" figures stay comparable. ``--scenarios`` still runs it.
LASER_SCENARIOS = ("guided-tour",)


def scenario_names(all_of_them: bool = False) -> list[str]:
    """The simulator's scenarios the camera's rows run by default (``all_of_them``: every one)."""
    from tools.simulator.core.scenarios import SCENARIOS

    return [s for s in SCENARIOS if all_of_them or s not in LASER_SCENARIOS]


@dataclass
class Capture:
    """What reached the tracker in one run of a scenario, and its ground truth.

    Frames (F,), one per LocalizedDetections message, in publishing order: ``seq`` int64
    (the camera frame), ``stamp_ns`` int64, ``has_embeddings`` bool (an Embeddings message
    of that frame was published). Detections (M,): ``det_frame`` int64 (index into the
    frames), ``positions`` (M, 3) map frame in m, ``covs`` (M, 3, 3) m^2, ``scores`` (M,),
    ``descriptors`` (M, D) float32 (NaN rows: none for that detection). Ground truth (G,):
    ``gt_seq`` int64, ``gt_id`` int64, ``gt_pos`` (G, 3), the counted people of every
    frame. The camera's view per frame (as the localizer sends it; NaN where it sent none):
    ``view_pose`` (F, 4, 4) camera -> map, ``view_k`` (F, 3, 3), ``view_size`` (F, 2)
    width, height, ``view_range`` (F,) m. ``meta``: scenario, seconds, fps, simulated frames, the embedding model (name,
    dim, metric), the seq of the first embeddings message and the in-chain tracker's figures.
    """

    seq: np.ndarray
    stamp_ns: np.ndarray
    has_embeddings: np.ndarray
    det_frame: np.ndarray
    positions: np.ndarray
    covs: np.ndarray
    scores: np.ndarray
    descriptors: np.ndarray
    statures: np.ndarray
    gt_seq: np.ndarray
    gt_id: np.ndarray
    gt_pos: np.ndarray
    view_pose: np.ndarray
    view_k: np.ndarray
    view_size: np.ndarray
    view_range: np.ndarray
    meta: dict[str, Any]

    ARRAYS = ("seq", "stamp_ns", "has_embeddings", "det_frame", "positions", "covs", "scores", "descriptors", "statures",
              "gt_seq", "gt_id", "gt_pos", "view_pose", "view_k", "view_size", "view_range")

    def view(self, k: int) -> FieldOfView | None:
        """The camera's view at frame ``k`` (None where the localizer sent none)."""
        if not np.isfinite(self.view_range[k]):
            return None
        w, h = (int(v) for v in self.view_size[k])
        return FieldOfView(self.view_pose[k], self.view_k[k], w, h, float(self.view_range[k]))

    @property
    def name(self) -> str:
        return str(self.meta["scenario"])

    @property
    def frames(self) -> int:
        """Frames the tracker was given (localized frames)."""
        return len(self.seq)


# ------------------------------------------------------------------------------------
# Capture: run_chain once, keep what the tracker was sent
# ------------------------------------------------------------------------------------

class _Recorder:
    """run_chain's ``record`` callback: keeps the messages by kind."""

    def __init__(self) -> None:
        self.localized: list[LocalizedDetections] = []
        self.embeddings: dict[tuple[int, str, int], Embeddings] = {}
        self.groundtruth: list[PeopleGroundTruth] = []
        self.tracks: list[Tracks] = []

    def __call__(self, msg: Message) -> None:
        if isinstance(msg, LocalizedDetections):
            self.localized.append(msg)
        elif isinstance(msg, Embeddings):
            self.embeddings[msg.header.join_key] = msg
        elif isinstance(msg, PeopleGroundTruth):
            self.groundtruth.append(msg)
        elif isinstance(msg, Tracks):
            self.tracks.append(msg)


def _to_capture(rec: _Recorder, meta: dict[str, Any]) -> Capture:
    cards = [e.model for e in rec.embeddings.values()]
    dim = cards[0].dim if cards else 0
    seq, stamp, has_emb, det_frame, pos, covs, scores, descs, statures = [], [], [], [], [], [], [], [], []
    n = len(rec.localized)
    view_pose, view_k = np.full((n, 4, 4), np.nan), np.full((n, 3, 3), np.nan)
    view_size, view_range = np.zeros((n, 2), np.int64), np.full(n, np.nan)
    for k, loc in enumerate(rec.localized):
        if loc.view is not None:
            view_pose[k], view_k[k] = loc.view.camera_to_frame, loc.view.K
            view_size[k], view_range[k] = (loc.view.width, loc.view.height), loc.view.max_range_m
        emb = rec.embeddings.get(loc.header.join_key)
        seq.append(loc.header.seq)
        stamp.append(loc.header.stamp_ns)
        has_emb.append(emb is not None)
        p, c = positions_of(loc)
        det_frame += [k] * len(p)
        pos.append(p)
        covs.append(c)
        scores += [d.score for d in loc.detections]
        statures += [np.nan if d.stature_m is None else d.stature_m for d in loc.detections]
        descs.append(descriptors_for(loc, emb) if emb is not None else np.full((len(p), dim), np.nan, np.float32))
    gt = [(g.header.seq, p.id, p.position) for g in rec.groundtruth for p in g.counted()]
    meta = {**meta, "simulated_frames": len(rec.groundtruth),
            "model": {"name": cards[0].name, "dim": dim, "metric": cards[0].metric} if cards else None,
            "first_embeddings_seq": min((key[2] for key in rec.embeddings), default=None)}
    return Capture(
        seq=np.asarray(seq, np.int64), stamp_ns=np.asarray(stamp, np.int64), has_embeddings=np.asarray(has_emb, bool),
        det_frame=np.asarray(det_frame, np.int64),
        positions=np.concatenate(pos) if pos else np.zeros((0, 3)),
        covs=np.concatenate(covs) if covs else np.zeros((0, 3, 3)), scores=np.asarray(scores, np.float64),
        descriptors=np.concatenate(descs) if descs else np.zeros((0, dim), np.float32),
        statures=np.asarray(statures, np.float64),
        gt_seq=np.asarray([g[0] for g in gt], np.int64), gt_id=np.asarray([g[1] for g in gt], np.int64),
        gt_pos=np.asarray([g[2] for g in gt], np.float64).reshape(-1, 3),
        view_pose=view_pose, view_k=view_k, view_size=view_size, view_range=view_range, meta=meta)


def hash_code(paths: tuple[str, ...]) -> str:
    """The first 16 hex digits of a hash of the files (and their names) under ``paths``, for cache keys."""
    h = hashlib.sha256()
    for rel in paths:
        base = ROOT / rel
        for f in sorted([base] if base.is_file() else base.rglob("*.py")):
            h.update(str(f.relative_to(ROOT)).encode())
            h.update(f.read_bytes())
    return h.hexdigest()[:16]


def _chain_config() -> TrackerConfig:
    return TrackerConfig.model_validate({"profile": CHAIN_PROFILE, "memory_path": None})


@functools.lru_cache(maxsize=1)
def chain_tracker_key() -> str:
    """Hash of the tracker's code and the in-chain tracker's settings: the in-chain figures hold while it matches.

    Computed once per process (call it before tracking): the code this process runs is
    the code it imported, even if the files change during the run.
    """
    text = hash_code(("services/tracker",)) + _chain_config().model_dump_json()
    return hashlib.sha256(text.encode()).hexdigest()[:16]


def cache_key(scenario: str, seconds: float, fps: float) -> str:
    """Hash of everything that decides the tracker's inputs: the run, the nodes' settings, their code, versions."""
    import cv2

    from services.detector.config import DetectorConfig
    from services.embedder.config import EmbedderConfig
    from services.localizer.config import LocalizerConfig

    desc = {
        "version": 1, "scenario": scenario, "seconds": seconds, "fps": fps, "size": SIM_SIZE, "seed": SIM_SEED,
        "detector": DetectorConfig(backend=SIM_DETECTOR).model_dump(mode="json"),  # type: ignore[arg-type]
        "localizer": LocalizerConfig().model_dump(mode="json"), "embedder": EmbedderConfig().model_dump(mode="json"),
        "code": hash_code(INPUT_CODE), "numpy": np.__version__, "opencv": cv2.__version__,
    }
    return hashlib.sha256(json.dumps(desc, sort_keys=True).encode()).hexdigest()[:16]


def capture(scenario: str, seconds: float, fps: float = SIM_FPS) -> Capture:
    """Run ``scenario`` through run_chain (the in-chain tracker: :data:`CHAIN_PROFILE`) and capture its inputs.

    On a terminal a bar counts the simulated frames (one ground truth message each).
    """
    from tools.demo.inprocess import run_chain

    rec = _Recorder()
    t0 = time.perf_counter()
    with progress_bar(math.ceil(seconds * fps), desc=f"capture {scenario}", unit="frame") as bar:
        def record(msg: Message) -> None:
            rec(msg)
            if isinstance(msg, PeopleGroundTruth):
                bar.update()

        result = run_chain(scenario, duration_s=seconds, fps=fps, width=SIM_SIZE[0], height=SIM_SIZE[1], seed=SIM_SEED,
                           tracker=_chain_config(), detector=SIM_DETECTOR, record=record)
    overall = result.report["overall"]
    chain = {"profile": CHAIN_PROFILE, "tracker_key": chain_tracker_key(), "seconds": time.perf_counter() - t0,
             **{k: overall[k] for k in ("mota", "idf1", "id_switches", "false_positives", "misses", "objects")}}
    return _to_capture(rec, {"scenario": scenario, "seconds": seconds, "fps": fps, "chain": chain})


def load_capture(scenario: str, seconds: float, cache_dir: Path, fps: float = SIM_FPS,
                 log_line: Callable[[str], None] = print, refresh: bool = False) -> Capture:
    """The capture of ``scenario``, from the cache when its key matches (unless ``refresh``), else run and cached."""
    path = cache_dir / f"sim_{scenario}_{seconds:g}s_{fps:g}fps_{cache_key(scenario, seconds, fps)}.npz"
    if path.is_file() and not refresh:
        with np.load(path) as z:
            return Capture(**{k: z[k] for k in Capture.ARRAYS}, meta=json.loads(str(z["meta"])))
    t0 = time.perf_counter()
    cap = capture(scenario, seconds, fps)
    log_line(f"  simulator: {scenario} {seconds:g} s captured in {time.perf_counter() - t0:.0f} s "
             f"(cached as {path.name})")
    cache_dir.mkdir(parents=True, exist_ok=True)
    tmp = path.with_suffix(".tmp.npz")
    np.savez_compressed(tmp, **{k: getattr(cap, k) for k in Capture.ARRAYS}, meta=np.array(json.dumps(cap.meta)))
    tmp.replace(path)
    return cap


# ------------------------------------------------------------------------------------
# Offline: the project's core fed as the service feeds it, and the baselines' input
# ------------------------------------------------------------------------------------

def replay(cap: Capture, config: TrackerConfig,
           on_result: Callable[[int, FrameResult], None] | None = None) -> list[Row]:
    """This project's tracker on the captured inputs, as TrackerService._update runs it; rows as
    ``offline.track``. ``on_result(seq, result)``: each frame's result (e.g. its ID decisions)."""
    model = cap.meta["model"]
    thresholds = config.thresholds(model["name"]) if model else None
    tracker = config.build_tracker(None)
    first_emb = cap.meta["first_embeddings_seq"]
    have_thresholds = False
    use_cov = config.uses_detection_covariance
    bounds = np.searchsorted(cap.det_frame, np.arange(cap.frames + 1), side="left")
    epoch = int(cap.stamp_ns[0]) if cap.frames else 0
    rows: list[Row] = []
    for k in range(cap.frames):
        seq = int(cap.seq[k])
        if not have_thresholds and thresholds is not None and first_emb is not None and seq >= first_emb:
            config.apply_thresholds(tracker, thresholds, model["metric"])  # the service, at the first model card
            have_thresholds = True
        a, b = bounds[k], bounds[k + 1]
        if cap.has_embeddings[k] and have_thresholds:
            desc: np.ndarray | None = cap.descriptors[a:b]
        elif a == b and have_thresholds:
            desc = np.zeros((0, 1), np.float32)
        else:
            desc = None
        stamp = (int(cap.stamp_ns[k]) - epoch) / 1e9
        covs = cap.covs[a:b] + R_EPS if use_cov else None  # as the service converts them
        try:
            result = tracker.step(stamp, FrameInput.of(cap.positions[a:b], desc, covs, cap.scores[a:b], view=cap.view(k),
                                                       statures=cap.statures[a:b]))
        except (ValueError, np.linalg.LinAlgError) as exc:  # the service counts and skips such a frame
            log.error("frame %d could not be tracked: %s", seq, exc)
            continue
        if on_result is not None:
            on_result(seq, result)
        for view in tracker.reported(result):
            x, y, z = view.mean[:3].tolist()
            rows.append((seq, stamp, view.id, x, y, z, view.status.value))
    return rows


def detections(cap: Capture) -> Detections:
    """The captured detections as ``offline.Detections`` (frame = the camera frame's seq, stamp in s)."""
    frames = cap.seq[cap.det_frame]
    stamps = (cap.stamp_ns[cap.det_frame] - (cap.stamp_ns[0] if cap.frames else 0)) / 1e9
    return Detections(frames, stamps, cap.positions, cap.scores, cap.descriptors)


def judge_demo(cap: Capture, rows: list[Row], on_frame: Callable[[int, FrameEvents], None] | None = None) -> ClearMot:
    """The demo's Table II judge (``score_rows``): counted people, full (x, y, z) distance < 1 m.

    ``on_frame``: passed on to ``evaluate_tables`` (e.g. an ``IdentityCollector``).
    """
    gt = TrackTable.from_arrays(cap.gt_seq, cap.gt_id, cap.gt_pos)
    if rows:
        arr = np.asarray([r[:6] for r in rows], np.float64)
        hyp = TrackTable.from_arrays(arr[:, 0].astype(np.int64), arr[:, 2].astype(np.int64), arr[:, 3:6])
    else:
        hyp = TrackTable.from_arrays(np.zeros(0, np.int64), np.zeros(0, np.int64), np.zeros((0, 3)))
    return evaluate_tables(gt, hyp, on_frame=on_frame)
