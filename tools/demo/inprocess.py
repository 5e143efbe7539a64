"""The demo's pipeline in one process, deterministic: simulator -> detector -> localizer ->
embedder -> tracker on the in-memory transport, each node polled in turn after every frame.

Nothing is dropped for timing (every frame is processed), so the result depends only on
the scenario, its seed and the settings: the way to compare tracker settings on the
simulated apartment quickly and reproducibly. ``perception demo`` runs the same nodes as
real processes over a real router, where a loaded machine may skip frames.

``record`` sees the tracker's inputs (localized detections and embeddings), the ground
truth and the tracker's output as they are published, e.g. to replay the tracker offline
on the same inputs (``benchmarks/quality_sim.py``).
"""

from __future__ import annotations

import tempfile
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Callable

from common.messages.keys import RELIABLE, Keys
from common.transport.memory import MemoryBus
from common.messages.schemas import Embeddings, LocalizedDetections, Message, PeopleGroundTruth, Tracks
from common.transport.base import Subscription
from services.attention.config import AttentionConfig
from services.attention.service import AttentionService
from services.detector.config import DetectorConfig
from services.detector.service import DetectorService
from services.embedder.config import EmbedderConfig
from services.embedder.service import EmbedderService
from services.localizer.config import LocalizerConfig
from services.localizer.service import LocalizerService
from services.laser.config import LaserConfig
from services.laser.service import LaserService
from services.tracker.config import TrackerConfig
from services.tracker.presets import load_preset
from services.tracker.service import TrackerService
from tools.demo.attention import AttentionScore, TruthTracks
from tools.demo.scoring import score_tracks
from tools.simulator.config import SimulatorConfig
from tools.simulator.core.cameras import BACK_CAMERA_OFFSET
from tools.simulator.core.render import default_camera
from tools.simulator.service import SimulatorService
from tools.simulator.static_map import write_apartment_map

__all__ = ["ChainResult", "SecondDetector", "run_chain"]


@dataclass(frozen=True)
class SecondDetector:
    """A second detector on the same camera (as in the TU Ilmenau framework: a fast one on
    every frame, a slow one a few times a second whose results arrive late). It runs on every
    ``every``-th frame and its localized results reach the tracker ``delay`` frames after
    their frame; it has no embedder, so the tracker fuses its boxes by position and IsPerson.
    ``stream`` defaults to ``head-{backend}``."""

    backend: str = "hog"
    every: int = 3
    delay: int = 2
    stream: str | None = None

    def __post_init__(self) -> None:
        if self.every < 1 or self.delay < 0:
            raise ValueError(f"every must be >= 1 and delay >= 0, got every={self.every}, delay={self.delay}")
        if self.delay >= 15:
            raise ValueError(f"delay {self.delay} frames is beyond the localizer's frame buffer (15)")

    def name(self, camera: str) -> str:
        return self.stream or f"{camera}-{self.backend}"


@dataclass
class ChainResult:
    """A run's scores (``report``, Table II's ``table``), its frames, the attention figures, and
    what was judged: the ground truth by frame seq and every published ``Tracks``."""

    report: dict[str, Any]
    table: str
    frames: int
    attention: dict[str, Any] | None = None
    truth: dict[int, PeopleGroundTruth] = field(default_factory=dict)
    tracks: list[Tracks] = field(default_factory=list)


def run_chain(scenario: str, *, duration_s: float = 30.0, fps: float = 10.0, width: int = 320, height: int = 240,
              seed: int = 0, tracker: TrackerConfig | None = None, detector: str = "depth",
              record: Callable[[Message], None] | None = None, plot: Path | None = None,
              attention: AttentionConfig | None = None, second: SecondDetector | None = None,
              back_camera: str | None = None, attention_truth: bool = False, laser: bool = False,
              fuse_laser: bool = True) -> ChainResult:
    """Run ``scenario`` through the four nodes and score the tracks (Table II).

    ``record``, if given, is called with every ``PeopleGroundTruth``, ``LocalizedDetections``,
    ``Embeddings`` and ``Tracks`` message of the run, after each simulated frame, each
    stream in the order it was published (ground truth, localized, embeddings, tracks).
    ``plot``, if given, is where the top-down plot of the run is drawn (PNG).
    ``attention``, if given, adds the attention node after the tracker and lets it steer the
    simulated head (closed loop, one frame of delay); the result then has the attention figures.
    ``second``, if given, adds a second detector on the camera (:class:`SecondDetector`): the
    tracker then reads every stream and scores the camera's frames' outputs.
    ``back_camera``, if given, names the simulator's second camera (on the base, looking
    backwards): it gets its own detector, localizer and embedder, and the tracker fuses both
    cameras (the ground truth then counts a person seen by either).
    ``attention_truth``: the attention node follows the ground truth's people
    (:class:`TruthTracks`, a perfect tracker) instead of the tracker's tracks: the loop
    without tracking errors (the tracks are still scored).
    ``laser``: the simulator's base laser (scans/front) and the ground truth of whom it could see;
    the laser node then finds people in its scans, none on the apartment's map (the robot's laser
    map: walls, chair and table legs), and the tracker fuses them (``fuse_laser``
    False: the tracker reads the camera alone, the same ground truth, for comparison). The tracks
    are then judged over everyone the robot's sensors could see (camera or laser), all round it.
    """
    keys = Keys(robot="inprocess")
    bus = MemoryBus()
    sim = SimulatorService(bus.transport(), keys, SimulatorConfig(
        scenario=scenario, seed=seed, fps=fps, width=width, height=height, duration_s=duration_s, start_ns=10**18,
        head_control=attention is not None, back_camera=back_camera, laser="front" if laser else None))
    # once per camera frame, as the demo: Table II scores every frame against its ground truth
    tracker_config = (tracker or TrackerConfig()).model_copy(update={"memory_path": None, "output_rate_hz": 0.0})
    if laser and not fuse_laser:
        tracker_config = tracker_config.model_copy(update={"lasers": []})
    camera = tracker_config.camera
    slow: list[tuple[int, Any]] = []  # (frame offset, node): the second detector's nodes
    if second is not None:
        stream = second.name(camera)
        tracker_config = tracker_config.model_copy(update={
            "camera": "*", "no_embeddings": [*tracker_config.no_embeddings, stream]})
        slow = [(0, DetectorService(bus.transport(), keys, DetectorConfig(
                    backend=second.backend, camera=camera, stream=stream))),  # type: ignore[arg-type]
                (second.delay, LocalizerService(bus.transport(), keys, LocalizerConfig(camera=camera, stream=stream)))]
    if back_camera is not None:  # the blind stretches between the views: the several-cameras preset, unless set
        preset = load_preset("several-cameras")["robust"]
        robust = {k: v for k, v in preset.items() if k not in tracker_config.robust.model_fields_set}
        tracker_config = tracker_config.model_copy(update={
            "camera": "*", "robust": tracker_config.robust.model_copy(update=robust)})
    nodes = [
        DetectorService(bus.transport(), keys, DetectorConfig(backend=detector)),  # type: ignore[arg-type]
        LocalizerService(bus.transport(), keys, LocalizerConfig()),
        EmbedderService(bus.transport(), keys, EmbedderConfig()),
        TrackerService(bus.transport(), keys, tracker_config),
    ]
    if back_camera is not None:  # its chain, before the tracker: one poll round carries a frame to it
        back_detector = DetectorConfig.model_validate({  # its floor plane from the mount: level, as high
            "backend": detector, "camera": back_camera,
            "depth": {"camera_height_m": BACK_CAMERA_OFFSET[2], "tilt_deg": 0.0}})
        nodes[3:3] = [DetectorService(bus.transport(), keys, back_detector),
                      LocalizerService(bus.transport(), keys, LocalizerConfig(camera=back_camera)),
                      EmbedderService(bus.transport(), keys, EmbedderConfig(camera=back_camera))]
    if laser and fuse_laser:  # before the tracker: one poll round carries a scan to it; with the robot's map
        with tempfile.TemporaryDirectory() as tmp:  # (its laser's: chair and table legs are on it)
            write_apartment_map(Path(tmp) / "map.yaml")
            nodes.insert(len(nodes) - 1, LaserService(bus.transport(), keys, LaserConfig(
                laser="front", static_map=Path(tmp) / "map.yaml")))
    if attention is not None:
        truth = TruthTracks(bus.transport(), keys) if attention_truth else None
        if truth is not None:
            nodes.append(truth)  # type: ignore[arg-type]
        nodes.append(AttentionService(bus.transport(), keys, attention, tracks_key=truth.key if truth else None))
    looked = AttentionScore(default_camera(width, height)) if attention is not None else None
    watcher = bus.transport()
    gt_sub = watcher.subscribe(keys.groundtruth(), PeopleGroundTruth, RELIABLE)
    tracks_sub = watcher.subscribe(keys.tracks(), Tracks, RELIABLE)
    taps: list[Subscription[Any]] = [] if record is None else [
        watcher.subscribe(keys.localized(camera), LocalizedDetections, RELIABLE),
        watcher.subscribe(keys.embeddings(camera), Embeddings, RELIABLE)]
    gt: dict[int, PeopleGroundTruth] = {}
    hyp: list[Tracks] = []
    clock = 0.0
    while not sim.done:
        published = sim.step()
        if looked is not None:
            for _, msg in published:
                looked.add(msg)
        clock += 1.0 / fps
        frame = sim.seq - 1
        for offset, node in slow:  # the slow detector on every `every`-th frame, its results `delay` late
            if second is not None and frame - offset >= 0 and (frame - offset) % second.every == 0:
                node.poll(clock)
        for node in nodes:
            node.poll(clock)
        # a second round lets the tracker see the embeddings the embedders just published
        for node in nodes[2:]:
            node.poll(clock)
        while (g := gt_sub.try_recv()) is not None:
            gt[g.msg.header.seq] = g.msg
            if record is not None:
                record(g.msg)
        if record is not None:
            for tap in taps:
                while (m := tap.try_recv()) is not None:
                    record(m.msg)
        while (t := tracks_sub.try_recv()) is not None:
            hyp.append(t.msg)
            if record is not None:
                record(t.msg)
    for node in nodes + [n for _, n in slow]:
        node.close()
    for tap in taps:
        tap.close()
    # with several streams, the output of the camera's frame: with a back camera (same stamps,
    # "back" sorts before "head") it is the one after both cameras' frames of the tick
    several = second is not None or back_camera is not None or laser
    report, table = score_tracks(gt, hyp, scenario, plot, source=camera if several else None,
                                 truth="around" if laser else "camera")
    if looked is not None:
        report["attention"] = looked.report()
    return ChainResult(report, table, sim.seq, report.get("attention"), gt, hyp)
