"""Tracking quality: this project's tracker side by side with two plain trackers, on the same data.

    python benchmarks/quality.py [--quick] [--only kitti,pets,pets-gt,pets-live,sim] [--json FILE] [--cache-dir DIR]
                                 [--data DIR]
                                 [--scenarios NAME,...] [--sim-seconds S] [--refresh-sim]

Trackers (each takes a :class:`~services.tracker.offline.Detections` object and returns
rows ``(frame, stamp, id, x, y, z)``):

- this project's tracker, through ``services.tracker.offline.track_config``: one row per
  profile of ``TrackerConfig.profile`` (``robust``, ``thesis``) when the config has that
  field, else one row with the defaults, labelled ``default``. Every row it reports is
  judged (the robust profile also reports tracks coasting through a short miss).
- ``kalman-baseline``: the "50-line baseline" written below (:class:`KalmanBaseline`),
  a constant-velocity Kalman filter on (x, y) with Hungarian assignment on Euclidean
  distance gated at 1 m, confirmed after 3 consecutive hits, deleted after 3 missed
  frames, reporting confirmed tracks in the frames they are matched. Its settings were
  chosen once, a priori, and are not tuned on this data.
- ``norfair``: norfair 2.3.0's ``Tracker`` with its defaults, except Euclidean distance
  on (x, y) with a 1 m threshold and ``initialization_delay=2``, which confirms a track at
  its third consecutive hit as every other tracker here does (norfair's default,
  ``hit_counter_max // 2`` = 7 frames, is meant for 30 fps video; at these 10 fps it holds
  every track back 0.7 s: KITTI score >= 2.683 MOTA 0.456 instead of 0.511). Only the
  tracks matched to a detection in the frame are reported (matched-only output).
  Skipped, with the reason printed, when norfair is not installed. norfair 2.3.0 pins
  numpy < 2 and its filterpy pulls matplotlib, so it is installed without its
  dependencies (the ``bench`` extra cannot say that)::

      .venv/bin/pip install --no-deps norfair==2.3.0 filterpy==1.4.5

  what it imports at run time (numpy, scipy, rich) is already installed by the project.

Data (``../shared/data``, or ``$PERCEPTION_SHARED_DATA``; nothing is downloaded):

1. ``kitti_ped_dev``: KITTI tracking pedestrians, 7 sequences of real 3-D detections
   (PointRCNN). Judged per sequence and summed, with score >= 2.683 and with no score
   cut. Positions only, so every tracker runs position-only.
2. ``pets09_dev`` (skipped with ``--quick``): the whole chain on real video. The
   project's HOG detector (upsample 2.25) -> the colour embedder -> the ground plane
   through ``ground_homography.json`` (foot point: the bottom centre of the box; the
   localizer core's ``foot_points`` and ``FloorHomography``) ->
   each tracker. The project's tracker gets the colour descriptors (embedding model
   ``colour``, thresholds from TrackerConfig's defaults); the two baselines get the
   positions only; the project's robust profile runs once more as the site would be configured
   (the camera's floor view and deploy/presets/pets-site.yaml, an open place's ID-memory prior). Detections and
   descriptors are cached under ``--cache-dir``
   (default ``benchmarks/.cache/``), keyed by a hash of the detector's and embedder's code and
   settings and the frames, so only the first run pays the ~1-2 minutes of detection.
3. ``pets-gt`` (skipped with ``--quick``): the same 400 frames with the ground truth's boxes as
   perfect detections (``benchmarks/pets_gt.py``: the ``conf`` 1 boxes, the people the judge
   counts, described by the colour embedder and placed on the ground by the same foot point and
   homography): the tracker alone. The project's profiles run twice, with the descriptors and
   positions only (``, no appearance``), on the same positions, so the difference is what
   appearance, the ID memory included, adds or costs.
4. ``sim``: the simulated apartment, the 8 camera scenarios of ``tools/simulator`` (all but
   ``guided-tour``, the laser's; ``--scenarios`` runs it too) for 60 s each
   (``--sim-seconds``; 10 s with ``--quick``) at 10 fps, 320x240, seed 0: the scenario runs
   once through ``tools.demo.inprocess.run_chain`` (the real depth detector, localizer and
   colour embedder) and what reaches its tracker is captured and cached under
   ``--cache-dir`` (``benchmarks/quality_sim.py``). The first run takes 20-30 s per
   scenario on the 2-core VM, about 3 minutes for the 8; a cached rerun only tracks.
   The project's profiles are replayed on it through the core as the tracker service
   feeds it (covariances, descriptors, position-only frames); the baselines get the
   positions. Judged as the demo's Table II: the simulator's counted people, a match is a
   full (x, y, z) distance < 1 m, no ignore regions. Each scenario is judged alone; the
   overall row sums them. The capture run's own (in-chain) tracker, the robust profile,
   is judged too, and its MOTA is shown next to the offline replay's as a check that the
   replay is the tracker the demo runs.

5. ``laser``: what the base laser adds (``benchmarks/quality_laser.py``): every scenario with the
   simulator's 2-D laser on, through ``run_chain`` twice, the camera alone and the camera with the
   laser node's people fused, both judged over everyone the camera or the laser could see (all
   round the robot), 30 s each (``--sim-seconds``; 10 s with ``--quick``), with the ID switches
   of the person the robot guides or follows. Not cached: about 20 s per scenario here.

Judging (KITTI, PETS): ``tools/evaluation`` (CLEAR MOT as py-motmetrics, IDF1) on the ground plane
(x, y) with a 1 m gate. Ignore regions (KITTI's ``gt_ignore_SEQ.csv``, PETS's
``conf = 0`` rows) are passed to the evaluation when its ``evaluate_tables`` takes an
``ignore`` argument; otherwise they are left out of the ground truth, a track on them
counts as a false positive, and a note says so. HOTA is shown when the evaluation computes
it. The identity per person (``tools/evaluation/identity.py``, as ``perception evaluate
--identity``) follows: returns after 10 or more frames out of the ground truth, true,
missed and false recoveries (false: an ID matched earlier to another person; newcomers
given such an ID in brackets), and track IDs covering two or more people (5 frames
each); every dataset, the simulator included. frames/s is the tracker's own time (no file reading, no judging) over
every frame from the first to the last detection.
"""

from __future__ import annotations

import os

# The trackers' matrices are small: one BLAS thread is fastest and fairest on a shared machine.
# Only when run as a script (before numpy loads); a test importing this module leaves its environment alone.
if __name__ == "__main__":
    for _var in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
        os.environ.setdefault(_var, "1")

import argparse  # noqa: E402
import hashlib  # noqa: E402
import inspect  # noqa: E402
import json  # noqa: E402
import platform  # noqa: E402
import subprocess  # noqa: E402
import sys  # noqa: E402
import time  # noqa: E402
from dataclasses import dataclass, field  # noqa: E402
from pathlib import Path  # noqa: E402
from typing import Callable  # noqa: E402

import numpy as np  # noqa: E402
from scipy.optimize import linear_sum_assignment  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
if str(ROOT) not in sys.path:
    sys.path.insert(0, str(ROOT))

from benchmarks import pets_gt, quality_sim  # noqa: E402
from common.runtime.progress import Bar, progress_bar  # noqa: E402
from services.localizer.core import FloorHomography, foot_points  # noqa: E402
from services.localizer.config import LocalizerConfig  # noqa: E402
from services.tracker.config import TrackerConfig  # noqa: E402
from services.tracker.core.types import IdDecision  # noqa: E402
from services.tracker.core.view import FloorView  # noqa: E402
from services.tracker.presets import load_preset  # noqa: E402
from services.tracker.offline import Detections, Row, frame_stamps, read_detections, track_config  # noqa: E402
from tools.evaluation.evaluate import evaluate_tables  # noqa: E402
from tools.evaluation.identity import DEFAULT_GAP, DEFAULT_MIN_FRAMES, Identity, IdentityCollector  # noqa: E402
from tools.evaluation.why import false_by_decision, reasons  # noqa: E402
from tools.evaluation.metrics import ClearMot  # noqa: E402
from tools.evaluation.readers import TrackTable  # noqa: E402
from tools.simulator.static_map import write_apartment_map  # noqa: E402

SHARED = Path(os.environ.get("PERCEPTION_SHARED_DATA", ROOT.parent / "shared" / "data"))
DEFAULT_CACHE = ROOT / "benchmarks" / ".cache"
#: KITTI's score cut of the data README's reference figures (log-odds confidence).
KITTI_SCORE_CUT = 2.683
GATE_M = 1.0
PROFILES = ("robust", "thesis")
PETS_UPSAMPLE = 2.25
PETS_PERSON_Z = 0.9  # the data README: a box becomes a 3-D person at (x, y, 0.9)
PETS_FPS = 10.0
PETS_GT_SCALE = 0.625  # gt.txt boxes are in 768x576 pixels, the frames 480x360 (unused for judging)


# ------------------------------------------------------------------------------------
# Trackers: name + run(dets) -> rows (frame, stamp, id, x, y, z)
# ------------------------------------------------------------------------------------

@dataclass(frozen=True)
class TrackerAdapter:
    """A tracker to compare; ``config`` is set for this project's tracker (the simulator replays it)."""

    name: str
    run: Callable[[Detections], list[Row]]
    uses_appearance: bool = False
    config: TrackerConfig | None = None


def has_profiles() -> bool:
    """Whether TrackerConfig has the ``profile`` setting yet."""
    return "profile" in TrackerConfig.model_fields


#: What KITTI's detector scores mean (the data README: a log-odds confidence, "about 2.7
#: and above is a confident detection"), told to the robust profile as a user tells it
#: their detector's calibration: P(person) = sigmoid(score), and detections below the
#: confident level may keep a track alive but never start one. The thesis profile and
#: the baselines have no such setting.
KITTI_SCORES = {"center": 0.0, "scale": 1.0, "birth_score": 2.683}


def project_configs(scores: dict[str, float] | None = None) -> list[tuple[str, TrackerConfig]]:
    """(label, config) per profile of TrackerConfig, or [("default", TrackerConfig())] without profiles.

    ``scores``: the detector's score calibration for the robust profile (``robust.scores``).
    """
    if has_profiles():
        out = []
        for name in PROFILES:
            settings: dict[str, object] = {"profile": name, "memory_path": None}
            if name == "robust" and scores is not None:
                settings["robust"] = {"scores": scores}
            out.append((name, TrackerConfig.model_validate(settings)))
        return out
    return [("default", TrackerConfig(memory_path=None))]


def project_adapter(label: str, config: TrackerConfig, embedding_model: str | None = "colour") -> TrackerAdapter:
    """This project's tracker with ``config``; descriptors, when the detections have them, as ``embedding_model``."""

    def run(dets: Detections) -> list[Row]:
        return track_config(dets, config, embedding_model if dets.descriptors is not None else None)

    return TrackerAdapter(label, run, uses_appearance=True, config=config)


def project_adapters(scores: dict[str, float] | None = None) -> list[TrackerAdapter]:
    return [project_adapter(label, cfg) for label, cfg in project_configs(scores)]


#: PETS09 as its site would be configured: the camera's floor view (``perception track
#: --floor-view``) and what the place is, the tracker preset (``perception track --preset``) of a
#: public square, where people who walk out of the image seldom turn straight back.
PETS_SITE_PRESET = "pets-site"


def pets_site_adapter(root: Path) -> TrackerAdapter:
    """The robust profile with PETS09's floor view and the preset :data:`PETS_SITE_PRESET`."""
    meta = json.loads((root / "ground_homography.json").read_text())
    view = FloorView(np.asarray(meta["H"], float), *meta["image_size"])
    config = TrackerConfig.model_validate({**load_preset(PETS_SITE_PRESET), "profile": "robust", "memory_path": None})

    def run(dets: Detections) -> list[Row]:
        return track_config(dets, config, "colour" if dets.descriptors is not None else None, view=view)

    return TrackerAdapter("robust, floor view, open place", run, uses_appearance=True, config=config)


#: The simulator's robot as its site would configure it: its map of the apartment (the laser's).
SIM_MAP_LABEL = "robust, the robot's static map"


def sim_map_adapter(cache_dir: Path) -> TrackerAdapter:
    """The robust profile given the simulated apartment's static map (``perception simulate
    --write-map``, written into ``cache_dir``): no track is born on a wall or a door jamb."""
    path = cache_dir / "apartment_map.yaml"
    write_apartment_map(path)
    config = TrackerConfig.model_validate({"profile": "robust", "memory_path": None,
                                           "robust": {"static_map": {"path": str(path)}}})
    return project_adapter(SIM_MAP_LABEL, config)


def _positions_only(dets: Detections) -> Detections:
    return Detections(dets.frames, dets.stamps, dets.positions, dets.scores, None)


def _frames(dets: Detections) -> list[tuple[int, float, int, int]]:
    """(frame, stamp, first row, end row) for every frame from the first to the last detection."""
    frames, stamps = frame_stamps(dets)
    starts = np.searchsorted(dets.frames, frames, side="left")
    ends = np.searchsorted(dets.frames, frames, side="right")
    return list(zip(frames.tolist(), stamps.tolist(), starts.tolist(), ends.tolist()))


class KalmanBaseline:
    """Constant-velocity Kalman filter (x, y, vx, vy) + Hungarian on Euclidean distance, gated at 1 m.

    A track is born from every unmatched detection, confirmed after ``n_init`` consecutive
    hits (a tentative track that misses is deleted) and deleted after more than
    ``max_misses`` missed frames in a row. Confirmed tracks are reported, at their
    filtered position, in the frames where they are matched. Settings were chosen once
    (pedestrian-like acceleration noise, 0.25 m measurement noise), not tuned on data.
    """

    def __init__(self, gate_m: float = GATE_M, n_init: int = 3, max_misses: int = 3, sigma_r: float = 0.25,
                 sigma_a: float = 1.0, sigma_v0: float = 1.5) -> None:
        self.gate, self.n_init, self.max_misses = gate_m, n_init, max_misses
        self.R = np.eye(2) * sigma_r**2
        self.sigma_a, self.P0 = sigma_a, np.diag([sigma_r**2, sigma_r**2, sigma_v0**2, sigma_v0**2])
        self.H = np.hstack([np.eye(2), np.zeros((2, 2))])
        self.tracks: list[dict] = []  # id, x (4,), P (4, 4), hits, misses, confirmed, z
        self.next_id, self.last_stamp = 1, None

    def _predict(self, dt: float) -> None:
        F = np.eye(4)
        F[0, 2] = F[1, 3] = dt
        G = np.array([[dt**2 / 2, 0], [0, dt**2 / 2], [dt, 0], [0, dt]])
        Q = G @ G.T * self.sigma_a**2
        for t in self.tracks:
            t["x"], t["P"] = F @ t["x"], F @ t["P"] @ F.T + Q

    def update(self, stamp: float, xyz: np.ndarray) -> list[tuple[int, float, float, float]]:
        self._predict(0.0 if self.last_stamp is None else stamp - self.last_stamp)
        self.last_stamp = stamp
        pred = np.array([t["x"][:2] for t in self.tracks]).reshape(-1, 2)
        dist = np.linalg.norm(pred[:, None, :] - xyz[None, :, :2], axis=2)
        rows, cols = linear_sum_assignment(np.where(dist < self.gate, dist, 1e6)) if dist.size else ([], [])
        pairs = [(r, c) for r, c in zip(rows, cols) if dist[r, c] < self.gate]
        out, matched_t, matched_d = [], {r for r, _ in pairs}, {c for _, c in pairs}
        for r, c in pairs:
            t = self.tracks[r]
            S = self.H @ t["P"] @ self.H.T + self.R
            K = t["P"] @ self.H.T @ np.linalg.inv(S)
            t["x"] = t["x"] + K @ (xyz[c, :2] - self.H @ t["x"])
            t["P"] = (np.eye(4) - K @ self.H) @ t["P"]
            t["hits"], t["misses"], t["z"] = t["hits"] + 1, 0, float(xyz[c, 2])
            t["confirmed"] |= t["hits"] >= self.n_init
            if t["confirmed"]:
                out.append((t["id"], float(t["x"][0]), float(t["x"][1]), t["z"]))
        for r, t in enumerate(self.tracks):
            if r not in matched_t:
                t["misses"] += 1
        self.tracks = [t for r, t in enumerate(self.tracks) if r in matched_t
                       or (t["confirmed"] and t["misses"] <= self.max_misses)]
        for c in range(len(xyz)):
            if c not in matched_d:
                x0 = np.array([xyz[c, 0], xyz[c, 1], 0.0, 0.0])
                self.tracks.append({"id": self.next_id, "x": x0, "P": self.P0.copy(), "hits": 1, "misses": 0,
                                    "confirmed": self.n_init <= 1, "z": float(xyz[c, 2])})
                self.next_id += 1
        return out


def run_kalman_baseline(dets: Detections) -> list[Row]:
    tracker = KalmanBaseline()
    rows: list[Row] = []
    for frame, stamp, a, b in _frames(dets):
        for tid, x, y, z in tracker.update(stamp, dets.positions[a:b]):
            rows.append((frame, stamp, tid, x, y, z))
    return rows


def norfair_missing() -> str | None:
    """None when norfair can be imported, else why not."""
    try:
        import norfair  # noqa: F401
    except Exception as exc:  # ImportError, or a broken install
        return (f"norfair is not installed ({type(exc).__name__}: {exc}); "
                "install it with: .venv/bin/pip install --no-deps norfair==2.3.0 filterpy==1.4.5")
    return None


def run_norfair(dets: Detections) -> list[Row]:
    """norfair 2.3.0: Euclidean distance on (x, y) gated at 1 m, confirmed at the 3rd consecutive hit
    (``initialization_delay=2``: the hit counter starts at 1 and gains 1 per matched frame), other
    settings its defaults; matched-only output."""
    from norfair import Detection, Tracker

    tracker = Tracker(distance_function="euclidean", distance_threshold=GATE_M, initialization_delay=2)
    rows: list[Row] = []
    for frame, stamp, a, b in _frames(dets):
        xyz = dets.positions[a:b]
        current = [Detection(points=p[None, :2].copy(), data=float(p[2])) for p in xyz]
        seen = {id(d) for d in current}
        for obj in tracker.update(current):
            if id(obj.last_detection) in seen:  # matched in this frame
                x, y = (float(v) for v in obj.estimate[0])
                rows.append((frame, stamp, int(obj.id), x, y, float(obj.last_detection.data)))
    return rows


def all_trackers() -> tuple[list[TrackerAdapter], list[str]]:
    """The trackers to compare, and notes on the ones left out."""
    trackers = project_adapters() + [TrackerAdapter("kalman-baseline", run_kalman_baseline)]
    notes = []
    if not has_profiles():
        notes.append("TrackerConfig has no 'profile' yet: this project's tracker runs with its defaults ('default')")
    missing = norfair_missing()
    if missing is None:
        trackers.append(TrackerAdapter("norfair", run_norfair))
    else:
        notes.append(f"norfair skipped: {missing}")
    return trackers, notes


# ------------------------------------------------------------------------------------
# Judging
# ------------------------------------------------------------------------------------

def ignore_supported() -> bool:
    """Whether the evaluation API takes ignore regions (``evaluate_tables(..., ignore=...)``)."""
    return "ignore" in inspect.signature(evaluate_tables).parameters


IGNORE_NOTE = ("ignore regions are NOT applied: tools.evaluation.evaluate_tables has no 'ignore' argument yet, "
               "so tracks on don't-care people count as false positives")


def rows_table(rows: list[Row]) -> TrackTable:
    if not rows:
        return TrackTable.from_arrays(np.zeros(0, np.int64), np.zeros(0, np.int64), np.zeros((0, 2)))
    arr = np.asarray([r[:6] for r in rows], dtype=np.float64)  # the project's rows also carry a status
    return TrackTable.from_arrays(arr[:, 0].astype(np.int64), arr[:, 2].astype(np.int64), arr[:, 3:5])


def judge(gt: TrackTable, rows: list[Row], ignore: TrackTable | None = None) -> ClearMot:
    """CLEAR MOT and IDF1 on the ground plane, 1 m gate; ``ignore`` passed on when the evaluation takes it."""
    return judge_identity(gt, rows, ignore)[0]


def judge_identity(gt: TrackTable, rows: list[Row], ignore: TrackTable | None = None) -> tuple[ClearMot, Identity]:
    """:func:`judge`, and the identity per person from the same matching (default gap and blip size)."""
    params = inspect.signature(evaluate_tables).parameters
    collect = IdentityCollector()
    extra: dict[str, object] = {"on_frame": collect}
    if ignore is not None and len(ignore) and "ignore" in params:
        extra["ignore"] = ignore
    if "hota" in params:  # HOTA when the evaluation can compute it on request
        extra["hota"] = True
    result = evaluate_tables(gt, rows_table(rows), "tracks", GATE_M, **extra)  # type: ignore[arg-type]
    return result, collect.result(gt.frames, gt.ids)


@dataclass
class Sequence:
    name: str
    dets: Detections
    gt: TrackTable
    ignore: TrackTable | None


@dataclass
class Score:
    """One tracker on one dataset: the summed result, the per-sequence ones, tracker time and frames
    (``parts``: tracker seconds and frames per sequence)."""

    result: ClearMot
    sequences: list[tuple[str, ClearMot]]
    seconds: float
    frames: int
    parts: list[tuple[float, int]] = field(default_factory=list)
    identities: list[Identity] = field(default_factory=list)  # per sequence, in the order of ``sequences``
    #: this project's tracker in the simulator: its false recoveries by who made them (the ID memory,
    #: a hand-over, the association continuing a track), from its ID decisions (tools/evaluation/why.py)
    false_causes: dict[str, int] | None = None

    @property
    def identity(self) -> Identity:
        """The identity measures summed over the sequences."""
        return Identity.combine(self.identities)

    @property
    def fps(self) -> float:
        return self.frames / self.seconds if self.seconds > 0 else float("inf")


def score(tracker: TrackerAdapter, sequences: list[Sequence], bar: Bar | None = None) -> Score:
    """Run ``tracker`` on every sequence (timed), judge each, sum; ``bar`` counts the sequences done."""
    parts, times, identities = [], [], []
    for seq in sequences:
        dets = seq.dets if tracker.uses_appearance else _positions_only(seq.dets)
        t0 = time.perf_counter()
        rows = tracker.run(dets)
        times.append((time.perf_counter() - t0, len(frame_stamps(seq.dets)[0])))
        result, identity = judge_identity(seq.gt, rows, seq.ignore)
        parts.append((seq.name, result))
        identities.append(identity)
        if bar is not None:
            bar.update()
    return Score(ClearMot.combine(r for _, r in parts), parts, sum(t for t, _ in times), sum(n for _, n in times),
                 times, identities)


# ------------------------------------------------------------------------------------
# KITTI pedestrians
# ------------------------------------------------------------------------------------

def _gt_csv(path: Path) -> TrackTable:
    data = np.loadtxt(path, delimiter=",", skiprows=1, ndmin=2)
    if data.size == 0:
        return TrackTable.from_arrays(np.zeros(0, np.int64), np.zeros(0, np.int64), np.zeros((0, 2)))
    return TrackTable.from_arrays(data[:, 0].astype(np.int64), data[:, 1].astype(np.int64), data[:, 2:4])


def select(dets: Detections, mask: np.ndarray) -> Detections:
    return Detections(dets.frames[mask], dets.stamps[mask], dets.positions[mask], dets.scores[mask],
                      None if dets.descriptors is None else dets.descriptors[mask])


def load_kitti(root: Path, min_score: float | None) -> list[Sequence]:
    """The KITTI sequences of ``root`` (``dets_SEQ.csv``, ``gt_SEQ.csv``, ``gt_ignore_SEQ.csv``), score-cut."""
    out = []
    for det_path in sorted(root.glob("dets_*.csv")):
        seq = det_path.stem.removeprefix("dets_")
        dets = read_detections(det_path)
        if min_score is not None:
            dets = select(dets, dets.scores >= min_score)
        ignore_path = root / f"gt_ignore_{seq}.csv"
        out.append(Sequence(seq, dets, _gt_csv(root / f"gt_{seq}.csv"),
                            _gt_csv(ignore_path) if ignore_path.is_file() else None))
    if not out:
        raise FileNotFoundError(f"no dets_SEQ.csv in {root}")
    return out


# ------------------------------------------------------------------------------------
# PETS09: HOG -> colour embedder -> ground plane, cached
# ------------------------------------------------------------------------------------

def pets_settings() -> tuple[object, object]:
    from services.detector.config import DetectorConfig
    from services.embedder.config import EmbedderConfig

    return (DetectorConfig.model_validate({"backend": "hog", "hog": {"upsample": PETS_UPSAMPLE}}), EmbedderConfig())


#: The code whose change invalidates the cached PETS detections, descriptors and ground positions.
PETS_CODE = ("services/detector/core", "services/detector/config.py", "services/embedder/core",
             "services/embedder/config.py", "services/localizer/core/floor.py",
             "services/localizer/core/homography.py", "services/localizer/config.py")


def pets_cache_key(root: Path) -> str:
    """Hash of the detector and embedder settings and code, the homography, the frames and OpenCV's version."""
    import cv2

    det_cfg, emb_cfg = pets_settings()
    frames = sorted((root / "frames").glob("frame_*.jpg"))
    desc = {
        "version": 2,
        "code": quality_sim.hash_code(PETS_CODE),
        "detector": det_cfg.model_dump(mode="json"),  # type: ignore[attr-defined]
        "embedder": emb_cfg.model_dump(mode="json"),  # type: ignore[attr-defined]
        "homography": json.loads((root / "ground_homography.json").read_text())["H"],
        "frames": [(p.name, p.stat().st_size) for p in frames],
        "opencv": cv2.__version__,
        "z": PETS_PERSON_Z, "fps": PETS_FPS,
    }
    return hashlib.sha256(json.dumps(desc, sort_keys=True).encode()).hexdigest()[:16]


def to_ground(H: np.ndarray, boxes: np.ndarray, detector: str = "hog") -> np.ndarray:
    """(N, 2) ground-plane positions of the boxes' foot points (bottom centre, less the
    ``detector``'s foot bias) through ``H``: the localizer's own foot point and floor homography
    (what ``perception localizer --floor-homography`` does with a frame without depth, less its
    checks: no box is dropped)."""
    p = LocalizerConfig().floor_params(detector)
    pixels, _ = foot_points(boxes, bias=(p.foot_bias_u, p.foot_bias_v))
    return FloorHomography(H).to_floor(pixels)[0]


def detect_pets(root: Path, log: Callable[[str], None] = print) -> Detections:
    """Detect and embed every frame (slow: ~1-2 minutes for 400 frames)."""
    import cv2

    from services.detector.config import build_detector
    from services.embedder.config import build_backend
    from services.embedder.core.backend import crop_boxes

    det_cfg, emb_cfg = pets_settings()
    detector, embedder = build_detector(det_cfg), build_backend(emb_cfg)  # type: ignore[arg-type]
    H = np.asarray(json.loads((root / "ground_homography.json").read_text())["H"], np.float64)
    frames, stamps, pos, scores, descs = [], [], [], [], []
    paths = sorted((root / "frames").glob("frame_*.jpg"))
    t0 = time.perf_counter()
    with progress_bar(len(paths), desc="pets09 detect", unit="frame") as bar:
        for k, path in enumerate(paths):
            frame = int(path.stem.split("_")[1])
            bgr = cv2.imread(str(path))
            if bgr is None:
                raise OSError(f"cannot read {path}")
            rgb = cv2.cvtColor(bgr, cv2.COLOR_BGR2RGB)
            boxes, conf = detector.detect(rgb)
            crops, kept = crop_boxes(rgb, boxes)
            if len(kept):
                d = embedder.embed(crops)
                g = to_ground(H, np.asarray(boxes, np.float64)[kept])
                frames.append(np.full(len(kept), frame, np.int64))
                stamps.append(np.full(len(kept), (frame - 1) / PETS_FPS))
                pos.append(np.column_stack([g, np.full(len(kept), PETS_PERSON_Z)]))
                scores.append(np.asarray(conf, np.float64)[kept])
                descs.append(np.asarray(d, np.float32))
            bar.update()
            if (k + 1) % 100 == 0:
                log(f"  pets09: detected {k + 1}/{len(paths)} frames ({time.perf_counter() - t0:.0f} s)")
    return Detections(np.concatenate(frames), np.concatenate(stamps), np.concatenate(pos), np.concatenate(scores),
                      np.concatenate(descs))


def pets_detections(root: Path, cache_dir: Path, log: Callable[[str], None] = print) -> Detections:
    """The PETS detections with descriptors, from the cache when its key matches."""
    path = cache_dir / f"pets09_dev_hog_colour_{pets_cache_key(root)}.npz"
    if path.is_file():
        log(f"  pets09: detections from cache {path}")
        return pets_gt.load_detections(path)
    log("  pets09: detecting and embedding (first run; cached afterwards)")
    return pets_gt.store_detections(detect_pets(root, log), path)


def pets_live_section(root: Path, cache_dir: Path) -> str:
    """The same frames through the live services: ``benchmarks/pets_live.py``'s table (run as its
    own process: it builds on this module's chain and judge)."""
    n = len(list((root / "frames").glob("frame_*.jpg")))
    cmd = [sys.executable, str(ROOT / "benchmarks" / "pets_live.py"), "--frames", str(n), "--data", str(root.parent),
           "--cache-dir", str(cache_dir)]
    done = subprocess.run(cmd, capture_output=True, text=True, cwd=ROOT, check=False)
    if done.returncode != 0:
        return f"PETS09 through the live services failed (exit {done.returncode}):\n{done.stderr[-3000:]}"
    return done.stdout.rstrip()


def pets_truth(root: Path, n_frames: int) -> tuple[TrackTable, TrackTable]:
    """The ground truth of frames 1 to ``n_frames`` on the ground plane: the ``conf`` 1 rows (the
    people judged) and the ``conf`` 0 rows (ignore regions)."""
    gt = np.loadtxt(root / "gt.txt", delimiter=",", ndmin=2)
    gt = gt[gt[:, 0] <= n_frames]
    care = gt[:, 6] > 0
    table = TrackTable.from_arrays(gt[care, 0].astype(np.int64), gt[care, 1].astype(np.int64), gt[care, 7:9])
    ignore = TrackTable.from_arrays(gt[~care, 0].astype(np.int64), gt[~care, 1].astype(np.int64), gt[~care, 7:9])
    return table, ignore


def load_pets(root: Path, cache_dir: Path, log: Callable[[str], None] = print, boxes: str = "hog") -> list[Sequence]:
    """One sequence: HOG+colour detections (``boxes`` "hog") or the ground truth's boxes (``boxes``
    "gt", ``benchmarks/pets_gt.py``), ground truth (conf 1 rows) and its conf 0 rows as ignore."""
    table, ignore = pets_truth(root, len(list((root / "frames").glob("frame_*.jpg"))))
    dets = pets_detections(root, cache_dir, log) if boxes == "hog" else pets_gt.pets_gt_detections(
        root, cache_dir, log, care_only=True)
    return [Sequence("S2L1-0001-0400", dets, table, ignore)]


def without_appearance(trackers: list[TrackerAdapter]) -> list[TrackerAdapter]:
    """The project's trackers of ``trackers`` again, given the positions only (``, no appearance``)."""
    return [TrackerAdapter(f"{t.name}, no appearance", t.run, uses_appearance=False, config=t.config)
            for t in trackers if t.config is not None]


# ------------------------------------------------------------------------------------
# The simulated apartment: run_chain's inputs to the tracker, captured and cached
# ------------------------------------------------------------------------------------

def score_sim(tracker: TrackerAdapter, captures: list[quality_sim.Capture], bar: Bar | None = None) -> Score:
    """``tracker`` on every captured scenario (timed), judged as the demo's Table II, summed.

    This project's tracker (``config`` set) is replayed as the service runs it; the
    others get the positions. frames/s counts every frame the tracker was given.
    ``bar`` counts the scenarios done.
    """
    parts, times, identities, causes = [], [], [], []
    for cap in captures:
        dets = None if tracker.config is not None else _positions_only(quality_sim.detections(cap))
        decisions: list[tuple[int, IdDecision]] = []
        t0 = time.perf_counter()
        if dets is None:
            rows = quality_sim.replay(cap, tracker.config,  # type: ignore[arg-type]
                                      lambda seq, r: decisions.extend((seq, d) for d in r.id_decisions))
        else:
            rows = tracker.run(dets)
        times.append((time.perf_counter() - t0, cap.frames))
        collect = IdentityCollector()
        parts.append((cap.name, quality_sim.judge_demo(cap, rows, on_frame=collect)))
        identities.append(collect.result(cap.gt_seq, cap.gt_id))
        causes.append(false_by_decision(reasons(identities[-1], decisions)))
        if bar is not None:
            bar.update()
    explained = tracker.config is not None  # the project's profiles explain their IDs (the baselines do not)
    by_cause = {k: sum(c[k] for c in causes) for k in causes[0]} if explained and causes else None
    return Score(ClearMot.combine(r for _, r in parts), parts, sum(t for t, _ in times), sum(n for _, n in times),
                 times, identities, by_cause)


def chain_check(captures: list[quality_sim.Capture], replayed: Score | None) -> list[dict[str, object]]:
    """Per scenario: the capture run's in-chain tracker against its offline replay (MOTA, IDF1, IDSW).

    ``replayed``: the same profile's offline Score. The in-chain figures are compared only
    while the tracker's code and settings are those of the capture run (``tracker_key``).
    """
    key = quality_sim.chain_tracker_key()
    out: list[dict[str, object]] = []
    for k, cap in enumerate(captures):
        chain = cap.meta["chain"]
        row: dict[str, object] = {"scenario": cap.name, "profile": chain["profile"], "chain": chain}
        if replayed is not None and chain["tracker_key"] == key:
            r = replayed.sequences[k][1]
            row["replay"] = {"mota": r.mota, "idf1": r.idf1, "id_switches": r.id_switches}
            row["same"] = bool(np.isclose(r.mota, chain["mota"]) and np.isclose(r.idf1, chain["idf1"])
                               and r.id_switches == chain["id_switches"])
        out.append(row)
    return out


def format_chain_check(rows: list[dict[str, object]]) -> str:
    lines = ["replay check: the capture run's in-chain tracker vs the offline replay of the same profile on its inputs",
             "", "| scenario | profile | in-chain MOTA | replay MOTA | in-chain IDF1 | replay IDF1 | same |",
             "|---|---|---|---|---|---|---|"]
    for row in rows:
        chain, rep = row["chain"], row.get("replay")
        assert isinstance(chain, dict)
        if isinstance(rep, dict):
            cells = [_f(chain["mota"]), _f(rep["mota"]), _f(chain["idf1"]), _f(rep["idf1"]),
                     "yes" if row["same"] else "NO"]
        else:
            cells = [_f(chain["mota"]), "-", _f(chain["idf1"]), "-", "not compared: the tracker changed since the "
                     "capture (--refresh-sim)"]
        lines.append(f"| {row['scenario']} | {row['profile']} | " + " | ".join(cells) + " |")
    return "\n".join(lines)


# ------------------------------------------------------------------------------------
# Output
# ------------------------------------------------------------------------------------

def machine() -> str:
    model = platform.processor() or platform.machine()
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                model = line.split(":", 1)[1].strip()
                break
    except OSError:
        pass
    return (f"{model}, {os.cpu_count()} CPUs, {platform.machine()}, Python {platform.python_version()}, "
            f"numpy {np.__version__}")


def _f(x: float, digits: int = 3) -> str:
    return f"{x:.{digits}f}" if np.isfinite(x) else "-"


def format_false_causes(scores: dict[str, Score]) -> str:
    """Who made this project's trackers' false recoveries: the ID memory's decision, or the
    association continuing a track (tools/evaluation/why.py; ``perception evaluate --identity
    --id-log`` says which, person by person)."""
    lines = [f"{name}: {s.identity.false_recoveries} false recoveries, {s.false_causes['memory']} given by the ID "
             f"memory's decision, {s.false_causes['handover']} by a hand-over, {s.false_causes['association']} by the "
             "association continuing a track" for name, s in scores.items() if s.false_causes is not None]
    return "(" + "; ".join(lines) + ")" if lines else ""


def format_scores(title: str, scores: dict[str, Score]) -> str:
    hota = any(np.isfinite(getattr(s.result, "hota", float("nan"))) for s in scores.values())
    head = ["tracker", "MOTA", "IDF1", "IDSW", "recall err", "misses", "FP", "MOTP (m)"]
    head += ["HOTA"] * hota + IDENTITY_HEAD + ["frames/s"]
    lines = [f"### {title}", "", "| " + " | ".join(head) + " |", "|" + "---|" * len(head)]
    for name, s in scores.items():
        r = s.result
        cells = [name, _f(r.mota), _f(r.idf1), str(r.id_switches), str(r.recall_errors), str(r.misses),
                 str(r.false_positives), _f(r.motp)]
        cells += [_f(getattr(r, "hota", float("nan")))] * hota + identity_cells(s.identity) + [f"{s.fps:,.0f}"]
        lines.append("| " + " | ".join(cells) + " |")
    objects = next(iter(scores.values())).result.objects if scores else 0
    lines.append(f"\n({objects} ground-truth objects; {next(iter(scores.values())).frames if scores else 0} frames)")
    lines.append(IDENTITY_NOTE)
    return "\n".join(lines)


#: The identity per person (tools/evaluation/identity.py) beside IDF1 and HOTA.
IDENTITY_HEAD = ["returns (unmatched)", "true rec", "missed rec", "false rec (new)", "shared IDs"]
IDENTITY_NOTE = (f"(identity per person: a return is a person back after >= {DEFAULT_GAP} frames out of the ground truth "
                 "(in brackets those never matched on their return); "
                 "true rec: first matched with their own earlier ID, missed rec: with a fresh ID, false rec: "
                 "with an ID matched earlier to another person, newcomers' in brackets; shared IDs: track IDs "
                 f"matched >= {DEFAULT_MIN_FRAMES} frames to each of two or more people)")


def identity_cells(i: Identity) -> list[str]:
    return [f"{i.returns} ({i.unmatched_returns})", str(i.true_recoveries), str(i.missed_recoveries),
            f"{i.false_recoveries} ({i.false_newcomers})", str(i.shared_tracks)]


def format_sequences(title: str, scores: dict[str, Score]) -> str:
    """One row per sequence and tracker, then the overall row (sums over the sequences) of each tracker."""
    head = ["sequence", "tracker", "objects", "MOTA", "IDF1", "IDSW", "recall err", "misses", "FP", "MOTP (m)", "HOTA",
            *IDENTITY_HEAD, "frames/s"]
    lines = [f"### {title}", "", "| " + " | ".join(head) + " |", "|" + "---|" * len(head)]

    def cells(seq: str, name: str, r: ClearMot, identity: Identity, seconds: float, frames: int) -> str:
        fps = f"{frames / seconds:,.0f}" if seconds > 0 else "-"
        row = [seq, name, str(r.objects), _f(r.mota), _f(r.idf1), str(r.id_switches), str(r.recall_errors),
               str(r.misses), str(r.false_positives), _f(r.motp), _f(getattr(r, "hota", float("nan"))),
               *identity_cells(identity), fps]
        return "| " + " | ".join(row) + " |"

    names = [n for n, _ in next(iter(scores.values())).sequences] if scores else []
    for k, seq in enumerate(names):
        for name, s in scores.items():
            seconds, frames = s.parts[k] if s.parts else (0.0, 0)
            identity = s.identities[k] if s.identities else Identity()
            lines.append(cells(seq, name, s.sequences[k][1], identity, seconds, frames))
    for name, s in scores.items():
        lines.append(cells("**overall**", name, s.result, s.identity, s.seconds, s.frames))
    lines.append(IDENTITY_NOTE)
    return "\n".join(lines)


def run_dataset(sequences: list[Sequence], trackers: list[TrackerAdapter], desc: str = "track") -> dict[str, Score]:
    """Every tracker on every sequence; on a terminal a bar named ``desc`` counts the (tracker, sequence) runs."""
    with progress_bar(len(trackers) * len(sequences), desc=desc, unit="run") as bar:
        return {t.name: score(t, sequences, bar) for t in trackers}


def score_dict(s: Score) -> dict[str, object]:
    seqs: dict[str, dict[str, object]] = {n: r.to_dict() for n, r in s.sequences}
    for (n, _), (seconds, frames) in zip(s.sequences, s.parts):
        seqs[n].update(tracker_seconds=seconds, frames=frames, frames_per_s=frames / seconds if seconds > 0 else None)
    for (n, _), identity in zip(s.sequences, s.identities):
        seqs[n]["identity"] = identity.to_dict()
    overall = s.result.to_dict()
    overall["identity"] = {k: v for k, v in s.identity.to_dict().items() if k not in ("coverage", "events")}
    if s.false_causes is not None:
        overall["identity"]["false_by"] = s.false_causes
    return {"overall": overall, "sequences": seqs, "tracker_seconds": s.seconds, "frames": s.frames,
            "frames_per_s": s.fps}


DATASETS = ("kitti", "pets", "pets-gt", "pets-live", "sim", "laser")
SIM_QUICK_SECONDS = 10.0


def _names(text: str, allowed: list[str] | tuple[str, ...], what: str) -> list[str]:
    names = [n.strip() for n in text.split(",") if n.strip()]
    unknown = [n for n in names if n not in allowed]
    if unknown or not names:
        raise argparse.ArgumentTypeError(f"unknown {what} {', '.join(unknown) or repr(text)}; "
                                         f"choose from {', '.join(allowed)}")
    return names


def run_sim(scenarios: list[str], seconds: float, cache_dir: Path, trackers: list[TrackerAdapter],
            refresh: bool = False) -> tuple[str, dict[str, Score], list[dict[str, object]]]:
    """The simulator section: (title, scores per tracker, the in-chain replay check)."""
    quality_sim.chain_tracker_key()  # the tracker's code as imported, before any file may change
    captures = [quality_sim.load_capture(name, seconds, cache_dir, refresh=refresh) for name in scenarios]
    title = (f"Simulated apartment, {len(scenarios)} scenarios x {seconds:g} s at {quality_sim.SIM_FPS:g} fps: "
             "depth detector -> localizer -> colour embedder (run_chain), judged as the demo's Table II")
    with progress_bar(len(trackers) * len(captures), desc="sim track", unit="run") as bar:
        scores = {t.name: score_sim(t, captures, bar) for t in trackers}
    check = chain_check(captures, scores.get(quality_sim.CHAIN_PROFILE))
    return title, scores, check


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--quick", action="store_true",
                        help=f"no PETS; the simulator {SIM_QUICK_SECONDS:g} s per scenario")
    parser.add_argument("--only", type=lambda t: _names(t, DATASETS, "dataset"), default=list(DATASETS),
                        metavar="NAMES", help=f"comma-separated datasets to run, of {','.join(DATASETS)} (default all)")
    parser.add_argument("--scenarios", type=lambda t: _names(t, quality_sim.scenario_names(True), "scenario"),
                        default=None, metavar="NAMES", help="comma-separated simulator scenarios (default the 8 camera scenarios; the laser rows: all 9)")
    parser.add_argument("--sim-seconds", type=float, default=None, metavar="S",
                        help=f"simulated seconds per scenario (default {quality_sim.SIM_SECONDS:g}, "
                             f"{SIM_QUICK_SECONDS:g} with --quick)")
    parser.add_argument("--refresh-sim", action="store_true",
                        help="run the simulator chain again instead of reading its cached capture (the in-chain "
                             "check then compares with the tracker as it is now)")
    parser.add_argument("--json", type=Path, metavar="FILE", help="also write every figure as JSON")
    parser.add_argument("--data", type=Path, default=SHARED, help=f"shared data folder (default {SHARED})")
    parser.add_argument("--cache-dir", type=Path, default=DEFAULT_CACHE,
                        help=f"where PETS detections and simulator captures are cached (default {DEFAULT_CACHE})")
    args = parser.parse_args(argv)
    if args.sim_seconds is not None and not args.sim_seconds > 0:
        parser.error(f"--sim-seconds must be > 0, got {args.sim_seconds:g}")

    trackers, notes = all_trackers()
    if not ignore_supported():
        notes.append(IGNORE_NOTE)
    print("# Tracking quality\n")
    print(f"machine: {machine()}")
    print(f"trackers: {', '.join(t.name for t in trackers)}; KITTI and PETS judged on (x, y) with a {GATE_M:g} m "
          "gate, the simulator as the demo's Table II (x, y, z) < 1 m\n")
    for note in notes:
        print(f"note: {note}")
    print()

    tables: dict[str, dict[str, Score]] = {}
    kitti = args.data / "kitti_ped_dev"
    if "kitti" not in args.only:
        print("KITTI skipped (--only)\n")
    elif kitti.is_dir():
        for label, cut in ((f"score >= {KITTI_SCORE_CUT}", KITTI_SCORE_CUT), ("no score cut", None)):
            title = f"KITTI pedestrians dev (7 sequences, summed), {label}"
            calibrated = project_adapters(KITTI_SCORES) + [t for t in trackers if t.name not in PROFILES]
            tables[title] = run_dataset(load_kitti(kitti, cut), calibrated, desc=f"kitti {'cut' if cut is not None else 'no cut'}")
            print(format_scores(title, tables[title]) + "\n")
    else:
        print(f"KITTI skipped: {kitti} not found\n")

    pets = args.data / "pets09_dev"
    if "pets" not in args.only:
        print("PETS09 skipped (--only)\n")
    elif args.quick:
        print("PETS09 skipped (--quick)\n")
    elif pets.is_dir():
        title = "PETS09-S2L1 frames 1-400: HOG -> colour embedder -> ground plane"
        ours = [t for t in trackers if t.config is not None] + [pets_site_adapter(pets)]
        tables[title] = run_dataset(load_pets(pets, args.cache_dir), trackers + ours[-1:] + without_appearance(ours),
                                    desc="pets09 track")
        print(format_scores(title, tables[title]))
        print("(the project's tracker uses the colour descriptors, and positions only in the rows ', no appearance'; "
              "kalman-baseline and norfair positions only; 'floor view, open place': the camera's view and the site's "
              "settings, the pets-site preset)\n")
    else:
        print(f"PETS09 skipped: {pets} not found\n")

    if "pets-gt" not in args.only or args.quick:
        print("PETS09 with the ground-truth boxes skipped (--only or --quick)\n")
    elif pets.is_dir():
        title = "PETS09-S2L1 frames 1-400: the ground truth's boxes -> colour embedder -> ground plane"
        ours = [t for t in trackers if t.config is not None] + [pets_site_adapter(pets)]
        tables[title] = run_dataset(load_pets(pets, args.cache_dir, boxes="gt"),
                                    ours + without_appearance(ours) + [t for t in trackers if t.config is None],
                                    desc="pets09 gt track")
        print(format_scores(title, tables[title]))
        print("(perfect detections: the conf 1 boxes of gt.txt; the rows ', no appearance' are the same trackers on the "
              "same positions without descriptors)\n")

    if "pets-live" in args.only and not args.quick and pets.is_dir():
        print(pets_live_section(pets, args.cache_dir) + "\n")

    sim: dict[str, object] = {}
    if "sim" not in args.only:
        print("Simulator skipped (--only)\n")
    else:
        seconds = args.sim_seconds or (SIM_QUICK_SECONDS if args.quick else quality_sim.SIM_SECONDS)
        scenarios = args.scenarios or quality_sim.scenario_names()
        t0 = time.perf_counter()
        args.cache_dir.mkdir(parents=True, exist_ok=True)
        title, scores, check = run_sim(scenarios, seconds, args.cache_dir, trackers + [sim_map_adapter(args.cache_dir)],
                                       args.refresh_sim)
        tables[title] = scores
        print(format_sequences(title, scores) + "\n")
        print(format_false_causes(scores) + "\n")
        print(format_chain_check(check) + "\n")
        sim = {"scenarios": scenarios, "seconds": seconds, "fps": quality_sim.SIM_FPS, "size": quality_sim.SIM_SIZE,
               "seed": quality_sim.SIM_SEED, "judge": "counted people, (x, y, z) distance < 1 m (the demo's Table II)",
               "chain_check": check, "wall_seconds": time.perf_counter() - t0}

    laser: list[dict[str, object]] = []
    if "laser" not in args.only:
        print("Laser skipped (--only)\n")
    else:
        from benchmarks import quality_laser

        scenarios = args.scenarios or quality_sim.scenario_names(True)
        laser = quality_laser.run(scenarios, args.sim_seconds or (SIM_QUICK_SECONDS if args.quick else 30.0))
        print(quality_laser.format_rows(laser) + "\n")

    if args.json:
        args.json.write_text(json.dumps({
            "machine": machine(), "gate_m": GATE_M, "ignore_applied": ignore_supported(), "notes": notes,
            "datasets": {title: {name: score_dict(s) for name, s in t.items()} for title, t in tables.items()},
            "simulator": sim, "laser": laser,
        }, indent=1))
        print(f"wrote {args.json}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
