"""TU Ilmenau's fusion in the tracker: two detectors on one camera (a fast one on every frame, a
slow one whose results arrive late, each with its own score model) and two cameras (one set
of tracks; a person seen by either camera stays reported). Core, then the service on the
in-memory transport."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from common.messages.keys import RELIABLE, Keys
from common.transport.memory import MemoryBus
from common.messages.schemas import (CameraView, Embeddings, FloorCameraView, Header, LocalizedDetection,
                                     LocalizedDetections, ModelCard, Tracks)
from services.tracker.config import ScoreConfig, TrackerConfig
from services.tracker.core.robust import RobustParams, RobustTracker, ScoreModel
from services.tracker.core.view import FieldOfView, FloorView, Views
from services.tracker.core.types import FrameInput
from services.tracker.service import TrackerService

KEYS = Keys(robot="fuse")
T0 = 1_700_000_000_000_000_000
PERIOD_NS = 66_666_667
K = np.array([[250.0, 0, 160], [0, 250.0, 120], [0, 0, 1]])


def _camera_to_map(yaw: float) -> np.ndarray:
    """A camera at the origin, 1 m up, looking along the map's direction ``yaw``."""
    c, s = np.cos(yaw), np.sin(yaw)
    forward, left = np.array([c, s, 0.0]), np.array([-s, c, 0.0])
    m = np.eye(4)
    m[:3, :3] = np.column_stack([-left, [0, 0, -1.0], forward])  # x right, y down, z forward
    m[:3, 3] = [0, 0, 1.0]
    return m


FRONT, BACK = _camera_to_map(0.0), _camera_to_map(np.pi)


def test_views_contain_a_point_any_camera_sees() -> None:
    front = FieldOfView(FRONT, K, 320, 240, 10.0)
    back = FieldOfView(BACK, K, 320, 240, 10.0)
    points = np.array([[3.0, 0.0, 1.0], [-3.0, 0.0, 1.0], [0.0, 3.0, 1.0]])
    assert front.contains(points).tolist() == [True, False, False]
    assert back.contains(points).tolist() == [False, True, False]
    assert Views((front, back)).contains(points).tolist() == [True, True, False]


def test_a_frames_own_score_model_decides_its_detections_confidence() -> None:
    strict = ScoreModel(center=2.0, scale=0.5, birth_score=1.0)  # e.g. HOG's SVM margins
    tracker = RobustTracker(RobustParams(n_init=2))
    # a score of 0.5 is a confident person under the default model, clutter under the strict one
    for k in range(6):
        tracker.step(k * 0.1, FrameInput.of(np.array([[3.0, 0.0, 1.0]]), scores=np.array([0.5]), score_model=strict))
    assert not tracker.tracks  # never born: below the strict model's birth score
    for k in range(6, 12):
        result = tracker.step(k * 0.1, FrameInput.of(np.array([[3.0, 0.0, 1.0]]), scores=np.array([0.5])))
    assert [v.status.name for v in result.tracks] == ["CONFIRMED"]


class Rig:
    def __init__(self, bus: MemoryBus, config: TrackerConfig) -> None:
        self.now = 100.0
        self.service = TrackerService(bus.transport(), KEYS, config, clock=lambda: self.now)
        peer = bus.transport()
        self.pubs: dict[str, object] = {}
        self.peer = peer
        self.tracks = peer.subscribe(KEYS.tracks(), Tracks, RELIABLE)

    def send(self, stream: str, seq: int, people: list[tuple[float, float]], *, detector: str = "depth",
             score: float = 0.9, camera_to_map: np.ndarray = FRONT, embed: bool = False,
             camera_frame: str | None = None) -> None:
        pub = self.pubs.get(stream)
        if pub is None:
            pub = self.pubs[stream] = self.peer.publisher(KEYS.localized(stream), LocalizedDetections, RELIABLE)
        header = Header(stamp_ns=T0 + seq * PERIOD_NS, frame_id="map", seq=seq, source=stream)
        dets = [LocalizedDetection(index=i, bbox_xyxy=(0, 0, 10, 30), score=score, position=np.array([x, y, 1.0]),
                                   cov=np.eye(3) * 0.01, depth_m=abs(x)) for i, (x, y) in enumerate(people)]
        view = CameraView(camera_to_frame=camera_to_map, K=K, width=320, height=240, max_range_m=10.0)
        pub.put(LocalizedDetections(header=header, detections=dets, view=view, detector=detector,  # type: ignore[attr-defined]
                                    camera_frame=camera_frame or f"{stream}_optical"))
        if embed:
            emb = self.pubs.get("emb/" + stream)
            if emb is None:
                emb = self.pubs["emb/" + stream] = self.peer.publisher(KEYS.embeddings(stream), Embeddings, RELIABLE)
            vectors = np.tile(np.eye(1, 16, dtype=np.float32), (len(people), 1))
            emb.put(Embeddings(header=header, model=ModelCard(name="colour", dim=16, normalized=True),  # type: ignore[attr-defined]
                               indices=np.arange(len(people), dtype=np.int32), vectors=vectors))

    def poll(self) -> list[Tracks]:
        self.service.poll(self.now)
        out = []
        while (got := self.tracks.try_recv()) is not None:
            out.append(got.msg)
        return out


def _config(tmp_path: Path, **kw: object) -> TrackerConfig:
    return TrackerConfig(memory_path=tmp_path / "memory.npz", camera="*", output_rate_hz=0.0, **kw)  # type: ignore[arg-type]


def test_a_slow_detectors_stream_is_tracked_without_waiting_for_embeddings(tmp_path: Path,
                                                                             memory_bus: MemoryBus) -> None:
    """head (depth, every frame) and head-hog (a slow detector, no embedder): one track; the
    slow stream's frames, late and out of order, are applied without waiting join_wait_s."""
    rig = Rig(memory_bus, _config(tmp_path, no_embeddings=["head-hog"]))
    published = []
    for seq in range(12):
        rig.send("head", seq, [(3.0, 0.05 * seq)], embed=True)
        if seq % 4 == 3:  # the slow detector's result for the frame 3 frames earlier, late
            rig.send("head-hog", seq - 3, [(3.0, 0.05 * (seq - 3))], detector="hog", camera_frame="head_optical")
        rig.now += 0.01  # far less than join_wait_s: only complete frames are released
        published += rig.poll()
    ids = {t.id for m in published for t in m.tracks}
    assert ids == {1}
    stats = rig.service.counters.extra
    assert stats.get("position_only_timeout", 0) == 0  # no frame of head-hog waited for embeddings
    assert stats["position_only_frames"] == 3  # the three head-hog frames, tracked by position
    assert rig.service.buffer.rewinds >= 1  # they came late: applied in stamp order by rewinding


def test_a_frame_applied_behind_a_slow_streams_frame_of_the_same_instant_gets_its_output(
        tmp_path: Path, memory_bus: MemoryBus) -> None:
    """The slow detector's result for a camera frame comes before the fast one's embeddings
    (head-hog needs none): head's frame of that instant is applied behind it by a rewind, and
    is still published as its own frame, once, with both streams' detections applied."""
    rig = Rig(memory_bus, _config(tmp_path, no_embeddings=["head-hog"]))
    published = []
    for seq in range(8):
        if seq % 2 == 0:  # the slow detector on every other frame, its result first
            rig.send("head-hog", seq, [(3.0, 0.05 * seq)], detector="hog", camera_frame="head_optical")
            rig.now += 0.005
            published += rig.poll()
        rig.send("head", seq, [(3.0, 0.05 * seq)], embed=True)
        rig.now += 0.005
        published += rig.poll()
    heads = [m for m in published if m.header.source == "head"]
    assert [m.header.seq for m in heads] == list(range(8))  # every head frame, once
    assert [m.header.seq for m in published if m.header.source == "head-hog"] == [0, 2, 4, 6]
    assert rig.service.buffer.rewinds >= 3  # head's frames 2, 4, 6 were applied behind head-hog's
    assert {t.id for m in heads[2:] for t in m.tracks} == {1}
    stamps = [m.header.stamp_ns for m in published]
    assert stamps == sorted(stamps)  # never an output older than one before it


def test_two_cameras_keep_one_id_and_report_a_person_only_one_camera_sees(tmp_path: Path,
                                                                          memory_bus: MemoryBus) -> None:
    """A person in front (head camera) and one behind (back camera): both reported on every
    output, although each camera's frames see one of them only."""
    rig = Rig(memory_bus, _config(tmp_path))
    outputs = []
    for seq in range(20):
        rig.send("head", seq, [(3.0, 0.0)], camera_to_map=FRONT)
        rig.send("back", seq, [(-3.0, 0.5)], camera_to_map=BACK)
        rig.now += 0.07
        outputs += rig.poll()
    late = [sorted(t.id for t in m.tracks) for m in outputs[-10:]]
    assert all(ids == [1, 2] for ids in late), late


def test_a_person_out_of_every_view_is_kept_but_not_reported(tmp_path: Path, memory_bus: MemoryBus) -> None:
    """Seen by the back camera, then gone out of both views (e.g. beside the robot): kept
    (same ID when seen again), not reported meanwhile."""
    rig = Rig(memory_bus, _config(tmp_path))
    for seq in range(10):
        rig.send("head", seq, [], camera_to_map=FRONT)
        rig.send("back", seq, [(-3.0, 0.0)], camera_to_map=BACK)
        rig.now += 0.07
        rig.poll()
    # the back camera turns away (its view now looks at the left side): the person is in no view
    side = _camera_to_map(np.pi / 2)
    out = []
    for seq in range(10, 14):
        rig.send("head", seq, [], camera_to_map=FRONT)
        rig.send("back", seq, [], camera_to_map=side)
        rig.now += 0.07
        out += rig.poll()
    assert out and not any(m.tracks for m in out[-2:])
    assert any(t.id == 1 for t in rig.service.tracker.tracks)  # kept
    for seq in range(14, 18):
        rig.send("head", seq, [], camera_to_map=FRONT)
        rig.send("back", seq, [(-3.0, 0.0)], camera_to_map=BACK)
        rig.now += 0.07
        out = rig.poll() or out
    assert [t.id for t in out[-1].tracks] == [1]


def test_detector_scores_config() -> None:
    cfg = TrackerConfig(memory_path=None, robust={"detector_scores": {"hog": ScoreConfig(center=1.0, scale=0.5)}})
    assert cfg.score_models().get("hog") == ScoreModel(center=1.0, scale=0.5)
    assert cfg.score_models().get("depth") is None and cfg.score_models().get("") is None


def test_two_streams_of_one_camera_use_that_cameras_view_at_each_frame(tmp_path: Path) -> None:
    """head and head-hog share the head camera: a late head-hog frame is judged by the view
    the camera had then, not by the union with the camera's newer view (it may have turned)."""
    service = TrackerService(MemoryBus().transport(), KEYS, _config(tmp_path), clock=lambda: 0.0)

    def loc(source: str, seq: int, to_map: np.ndarray, camera_frame: str = "head_optical") -> LocalizedDetections:
        return LocalizedDetections(header=Header(stamp_ns=T0 + seq * PERIOD_NS, frame_id="map", seq=seq, source=source),
                                   camera_frame=camera_frame,
                                   view=CameraView(camera_to_frame=to_map, K=K, width=320, height=240, max_range_m=10.0))

    assert isinstance(service._view(loc("head", 5, FRONT)), FieldOfView)
    late = service._view(loc("head-hog", 2, BACK))  # the head camera looked backwards then
    assert isinstance(late, FieldOfView) and np.allclose(late.camera_to_frame, BACK)
    both = service._view(loc("back", 5, BACK, camera_frame="back_optical"))
    assert isinstance(both, Views) and len(both.views) == 2


def test_a_fixed_cameras_floor_view_reaches_the_core_and_a_bad_one_is_counted(tmp_path: Path) -> None:
    """A camera placed by a floor homography sends its floor view (no intrinsics): the tracker
    takes it as a FloorView; a singular one is counted and the frame tracked without a view."""
    service = TrackerService(MemoryBus().transport(), KEYS, _config(tmp_path), clock=lambda: 0.0)

    def loc(seq: int, h: np.ndarray, view: CameraView | None = None) -> LocalizedDetections:
        return LocalizedDetections(header=Header(stamp_ns=T0 + seq * PERIOD_NS, frame_id="map", seq=seq, source="cctv"),
                                   camera_frame="cctv_optical", view=view,
                                   floor_view=FloorCameraView(image_to_frame=h, width=640, height=480))

    got = service._view(loc(1, np.diag([0.01, 0.01, 1.0])))
    assert isinstance(got, FloorView) and got.contains(np.array([[3.0, 2.0, 1.0], [7.0, 2.0, 1.0]])).tolist() == [True, False]
    pinhole = CameraView(camera_to_frame=FRONT, K=K, width=320, height=240, max_range_m=10.0)
    assert isinstance(service._view(loc(2, np.diag([0.01, 0.01, 1.0]), pinhole)), FieldOfView)  # the pinhole's first
    assert service._view(loc(3, np.zeros((3, 3)))) is None
    assert service.counters.extra["bad_view"] == 1
