"""TrackerService through the in-memory transport: join, position-only fallback, reordering,
queries, thresholds from model cards, and ID persistence across a restart."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from common.messages.keys import RELIABLE, Keys
from common.transport.memory import MemoryBus
from common.messages.schemas import (
    AppearanceThresholds,
    Embeddings,
    Header,
    IdDecisions,
    LocalizedDetection,
    LocalizedDetections,
    ModelCard,
    Tracks,
)
from services.tracker.config import TrackerConfig
from services.tracker.core.types import FrameResult, IdCandidate, IdDecision
from services.tracker.service import TrackerService

KEYS = Keys(robot="r1")
T0 = 1_700_000_000_000_000_000
PERIOD_NS = 33_333_333
DIM = 16
RNG = np.random.default_rng(11)
LOOKS = RNG.normal(size=(3, DIM))
LOOKS /= np.linalg.norm(LOOKS, axis=1, keepdims=True)


class Clock:
    def __init__(self) -> None:
        self.now = 100.0

    def __call__(self) -> float:
        return self.now


class Rig:
    """A service on a MemoryBus plus a 'localizer/embedder' publishing and a 'navigation' listening."""

    def __init__(self, bus: MemoryBus, config: TrackerConfig) -> None:
        self.clock = Clock()
        self.service = TrackerService(bus.transport(), KEYS, config, clock=self.clock)
        peer = bus.transport()
        self.peer = peer
        self.loc_pub = peer.publisher(KEYS.localized("head"), LocalizedDetections, RELIABLE)
        self.emb_pub = peer.publisher(KEYS.embeddings("head"), Embeddings, RELIABLE)
        self.tracks_sub = peer.subscribe(KEYS.tracks(), Tracks, RELIABLE)

    def send(self, seq: int, people: list[tuple[int, tuple[float, float, float]]], embeddings: bool = True,
             model: ModelCard | None = None, loc: bool = True) -> None:
        header = Header(stamp_ns=T0 + seq * PERIOD_NS, frame_id="map", seq=seq, source="head")
        dets = [LocalizedDetection(index=i, bbox_xyxy=(0, 0, 10, 10), score=0.9, position=np.array(p, float),
                                   cov=np.eye(3) * 0.01, depth_m=2.0) for i, (_, p) in enumerate(people)]
        if loc:
            self.loc_pub.put(LocalizedDetections(header=header, detections=dets))
        if embeddings:
            vec = np.stack([LOOKS[w] + RNG.normal(scale=0.01, size=DIM) for w, _ in people]) if people else np.zeros((0, DIM))
            card = model or ModelCard(name="colour", dim=DIM, normalized=True)
            self.emb_pub.put(Embeddings(header=header, model=card, indices=np.arange(len(people), dtype=np.int32),
                                        vectors=vec.astype(np.float32)))

    def poll(self) -> int:
        """One poll at the rig's clock; the number of Tracks messages published."""
        return len(self.service.poll(self.clock()))

    def outputs(self) -> list[Tracks]:
        out = []
        while (got := self.tracks_sub.try_recv()) is not None:
            out.append(got.msg)
        return out


def config(tmp_path: Path, **kw: object) -> TrackerConfig:
    """The thesis profile unless ``profile`` says otherwise (these tests pin its timings)."""
    kw.setdefault("profile", "thesis")
    kw.setdefault("output_rate_hz", 0.0)  # once per frame: these tests follow each frame's output
    return TrackerConfig(memory_path=tmp_path / "memory.npz", **kw)  # type: ignore[arg-type]


def test_joined_frames_publish_confirmed_tracks(tmp_path: Path, memory_bus: MemoryBus) -> None:
    rig = Rig(memory_bus, config(tmp_path))
    for k in range(5):
        rig.send(k, [(0, (2.0, 0.0, 1.0)), (1, (4.0, 1.0, 1.0))])
        assert rig.poll() == 1
    out = rig.outputs()
    assert len(out) == 5 and all(m.appearance_available for m in out)
    assert [len(m.tracks) for m in out] == [0, 0, 2, 2, 2]
    assert sorted(t.id for t in out[-1].tracks) == [1, 2]
    assert out[-1].header.stamp_ns == T0 + 4 * PERIOD_NS and out[-1].header.frame_id == "map"
    assert out[-1].embedding_model == "colour"
    assert all(t.status == "confirmed" and t.appearance_available for t in out[-1].tracks)


def test_missing_embeddings_fall_back_to_position_only(tmp_path: Path, memory_bus: MemoryBus) -> None:
    rig = Rig(memory_bus, config(tmp_path))
    for k in range(3):
        rig.send(k, [(0, (2.0, 0.0, 1.0))])
        rig.poll()
    rig.send(3, [(0, (2.0, 0.0, 1.0))], embeddings=False)
    assert rig.poll() == 0  # waiting for the embeddings
    rig.clock.now += 0.05
    assert rig.poll() == 0
    rig.clock.now += 0.06  # past the 100 ms join window
    assert rig.poll() == 1
    last = rig.outputs()[-1]
    assert not last.appearance_available and not last.tracks[0].appearance_available
    assert [t.id for t in last.tracks] == [1]
    assert rig.service.counters.extra["position_only_timeout"] == 1
    gallery = rig.service.tracker.tracks[0].gallery
    before = len(gallery) if gallery is not None else 0
    rig.send(3, [(0, (2.0, 0.0, 1.0))], loc=False)  # the embeddings show up after all: frame 3 again, with them
    assert rig.poll() == 0  # once per frame: frame 3 was published already
    extra = rig.service.counters.extra
    assert extra["late_embeddings_applied"] == 1 and "dropped_late_embeddings" not in extra
    assert len(rig.service.tracker.tracks[0].gallery) == before + 1  # the late descriptor was learnt
    for k in range(4, 12):  # 0.8 s on: frame 3 has left the reorder window
        rig.send(k, [(0, (2.0, 0.0, 1.0))])
        rig.poll()
    rig.send(3, [(0, (2.0, 0.0, 1.0))], loc=False)  # a second copy, far too late: dropped and counted
    rig.poll()
    assert rig.service.counters.extra["dropped_late_embeddings"] == 1


def test_frames_behind_a_waiting_frame_are_held_in_order(tmp_path: Path, memory_bus: MemoryBus) -> None:
    rig = Rig(memory_bus, config(tmp_path))
    rig.send(0, [(0, (2.0, 0.0, 1.0))], embeddings=False)  # the embedder is slow on frame 0
    rig.send(1, [(0, (2.0, 0.0, 1.0))])
    assert rig.poll() == 0  # frame 1 is complete but waits behind frame 0
    rig.send(0, [(0, (2.0, 0.0, 1.0))], loc=False)
    assert rig.poll() == 2
    assert [m.header.seq for m in rig.outputs()] == [0, 1]
    assert "rewinds" not in rig.service.counters.extra


def test_empty_frames_need_no_embeddings(tmp_path: Path, memory_bus: MemoryBus) -> None:
    rig = Rig(memory_bus, config(tmp_path))
    rig.send(0, [], embeddings=False)
    assert rig.poll() == 1
    rig.send(0, [], loc=False)  # the embedder's empty Embeddings for it, after the frame ran: no loss
    assert rig.poll() == 0
    extra = rig.service.counters.extra
    assert not any(k in extra for k in ("dropped_late_embeddings", "late_embeddings_applied", "rewinds"))


def test_out_of_order_frames_are_reordered_and_stale_ones_dropped(tmp_path: Path, memory_bus: MemoryBus) -> None:
    rig = Rig(memory_bus, config(tmp_path))
    for k in [0, 1, 2, 4, 5, 3, 6]:  # frame 3 arrives two frames late
        rig.send(k, [(0, (2.0 + 0.01 * k, 0.0, 1.0))])
        rig.poll()
    assert rig.service.counters.extra["rewinds"] == 1
    tracks = rig.outputs()
    assert tracks[-1].header.seq == 6 and tracks[-1].tracks[0].hits == 7
    for k in range(7, 40):
        if k != 10:  # frame 10 is lost on the way ...
            rig.send(k, [(0, (2.0, 0.0, 1.0))])
        rig.poll()
    rig.send(10, [(0, (2.0, 0.0, 1.0))])  # ... and arrives 1 s late: beyond the 500 ms window
    rig.poll()
    assert rig.service.buffer.dropped_old == 1 and rig.service.counters.extra["dropped_too_old"] == 1
    assert rig.service.counters.dropped == 1
    assert rig.outputs()[-1].header.seq == 39


def test_query_answers_last_known_state(tmp_path: Path, memory_bus: MemoryBus) -> None:
    rig = Rig(memory_bus, config(tmp_path))
    for k in range(4):
        rig.send(k, [(0, (2.0, 1.0, 1.0))])
        rig.poll()
    asker = memory_bus.transport()
    replies = asker.query(KEYS.track_query() + "?id=1")
    assert len(replies) == 1
    msg = replies[0][1]
    assert isinstance(msg, Tracks) and [t.id for t in msg.tracks] == [1]
    np.testing.assert_allclose(msg.tracks[0].position[:2], [2.0, 1.0], atol=0.1)
    assert msg.tracks[0].last_update_ns == T0 + 3 * PERIOD_NS
    empty = asker.query(KEYS.track_query() + "?id=99")[0][1]
    assert isinstance(empty, Tracks) and empty.tracks == []
    bad = asker.query(KEYS.track_query() + "?id=abc")[0][1]
    assert isinstance(bad, Tracks) and bad.tracks == []


def test_model_card_thresholds_are_a_fallback(tmp_path: Path, memory_bus: MemoryBus, caplog: pytest.LogCaptureFixture) -> None:
    rig = Rig(memory_bus, config(tmp_path))
    card = ModelCard(name="osnet", dim=DIM, thresholds=AppearanceThresholds(t_lower=0.25, t_upper=0.6, t_recover=0.35))
    rig.send(0, [(0, (2.0, 0.0, 1.0))], model=card)
    rig.poll()
    assert "using the model card" in caplog.text
    assert rig.outputs()[-1].appearance_available and rig.service.model == "osnet"


def test_model_without_thresholds_runs_position_only(tmp_path: Path, memory_bus: MemoryBus) -> None:
    rig = Rig(memory_bus, config(tmp_path))
    card = ModelCard(name="unknown-net", dim=DIM)
    for k in range(2):
        rig.send(k, [(0, (2.0, 0.0, 1.0))], model=card)
        rig.poll()
    assert not rig.outputs()[-1].appearance_available
    assert rig.service.counters.extra["no_thresholds"] == 2


def test_other_models_are_refused(tmp_path: Path, memory_bus: MemoryBus) -> None:
    rig = Rig(memory_bus, config(tmp_path, embedding_model="colour"))
    rig.send(0, [(0, (2.0, 0.0, 1.0))], model=ModelCard(name="trinet", dim=DIM))
    assert rig.poll() == 1  # processed at once, position-only
    assert rig.service.counters.extra["dropped_wrong_model"] == 1
    assert not rig.outputs()[-1].appearance_available


def test_identities_survive_a_restart(tmp_path: Path, caplog: pytest.LogCaptureFixture) -> None:
    caplog.set_level("INFO", logger="services.tracker.service")
    cfg = config(tmp_path)
    bus = MemoryBus()
    rig = Rig(bus, cfg)
    for k in range(6):
        rig.send(k, [(0, (2.0, 0.0, 1.0)), (1, (5.0, 0.0, 1.0))])
        rig.poll()
    for k in range(6, 12):  # person 0 leaves: its track is deleted and archived -> saved at once
        rig.send(k, [(1, (5.0, 0.0, 1.0))])
        rig.poll()
    assert rig.service.counters.extra["memory_saves"] >= 1
    rig.service.close()  # shutdown also saves live tracks' galleries (person 1)
    rig.service.transport.close()

    bus2 = MemoryBus()
    rig2 = Rig(bus2, cfg)  # a new process: loads the file
    why = bus2.transport().subscribe(KEYS.id_decisions(), IdDecisions, RELIABLE)
    for k in range(100, 104):  # both come back, in swapped places
        rig2.send(k, [(1, (2.0, 0.0, 1.0)), (0, (5.0, 0.0, 1.0))])
        rig2.poll()
    last = rig2.outputs()[-1]
    by_x = {round(float(t.position[0])): t.id for t in last.tracks}
    assert by_x == {2: 2, 5: 1}
    assert rig2.service.counters.extra["ids_recovered"] == 2
    # why, for the thesis profile too: Algorithm 2's nearest remembered person, logged and published
    lines = [r.getMessage() for r in caplog.records if r.getMessage().startswith("ID decision")]
    assert sorted(line.split(" at ")[0] for line in lines) == ["ID decision: ID 1 recovered", "ID decision: ID 2 recovered"]
    assert all("(Algorithm 2)" in line and "< t_recover" in line for line in lines)
    sent = []
    while (got := why.try_recv()) is not None:
        sent.append(got.msg)
    [msg] = sent  # both confirmed in one frame
    assert sorted((d.id, d.rule, d.outcome) for d in msg.decisions) == [(1, "nearest", "recovered"),
                                                                         (2, "nearest", "recovered")]
    assert all(d.candidates[0].distance is not None and d.candidates[0].distance < d.threshold for d in msg.decisions)


def test_periodic_save_covers_a_crash(tmp_path: Path, memory_bus: MemoryBus) -> None:
    rig = Rig(memory_bus, config(tmp_path, memory_save_period_s=1.0))
    for k in range(3):
        rig.send(k, [(0, (2.0, 0.0, 1.0))])
        rig.poll()
    assert not (tmp_path / "memory.npz").exists()
    rig.clock.now += 1.5
    rig.send(3, [(0, (2.0, 0.0, 1.0))])
    rig.poll()
    assert (tmp_path / "memory.npz").exists()  # no close(): as after SIGKILL
    rig2 = Rig(MemoryBus(), config(tmp_path))
    rig2.send(50, [(0, (2.0, 0.0, 1.0))])
    rig2.poll()
    assert rig2.service.counters.extra["ids_recovered"] == 1


def test_memory_of_another_model_is_refused(tmp_path: Path, memory_bus: MemoryBus) -> None:
    rig = Rig(memory_bus, config(tmp_path))
    for k in range(3):
        rig.send(k, [(0, (2.0, 0.0, 1.0))])
        rig.poll()
    rig.service.close()
    with pytest.raises(ValueError, match="embedding model 'colour'"):
        TrackerService(MemoryBus().transport(), KEYS, config(tmp_path, embedding_model="trinet"))


def test_inputs_in_another_frame_are_dropped(tmp_path: Path, memory_bus: MemoryBus) -> None:
    rig = Rig(memory_bus, config(tmp_path))
    header = Header(stamp_ns=T0, frame_id="odom", seq=0, source="head")
    rig.loc_pub.put(LocalizedDetections(header=header))
    assert rig.poll() == 0
    assert rig.service.counters.extra["dropped_wrong_frame"] == 1


def test_all_cameras_with_wildcard(tmp_path: Path, memory_bus: MemoryBus) -> None:
    service = TrackerService(memory_bus.transport(), KEYS, config(tmp_path, camera="*"))
    pub = memory_bus.transport().publisher(KEYS.localized("left"), LocalizedDetections, RELIABLE)
    pub.put(LocalizedDetections(header=Header(stamp_ns=T0, frame_id="map", seq=0, source="left")))
    assert len(service.poll(0.0)) == 1


def test_tracker_command_rejects_bad_config_before_connecting(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    from perception.cli import main

    bad = tmp_path / "tracker.yaml"
    bad.write_text("tracker:\n  join_wait_s: -1\n")
    assert main(["tracker", "--service-config", str(bad), "--connect", "tcp/127.0.0.1:1"]) == 2
    assert "join_wait_s" in capsys.readouterr().err
    bad.write_text("appearance:\n  trinet: {t_lower: 700, t_upper: 300, t_recover: 400}\n")
    assert main(["tracker", "--service-config", str(bad), "--connect", "tcp/127.0.0.1:1"]) == 2
    assert "appearance.trinet" in capsys.readouterr().err


def test_unreadable_memory_file_stops_the_start(tmp_path: Path) -> None:
    (tmp_path / "memory.npz").write_bytes(b"garbage")
    with pytest.raises(ValueError, match="not a tracker ID memory file"):
        TrackerService(MemoryBus().transport(), KEYS, config(tmp_path))


def test_false_positives_are_forgotten_by_the_query(tmp_path: Path, memory_bus: MemoryBus) -> None:
    rig = Rig(memory_bus, config(tmp_path))
    rig.send(0, [(0, (2.0, 0.0, 1.0)), (2, (6.0, 6.0, 1.0))])  # person 2 only once: a false positive
    rig.poll()
    for k in range(1, 8):
        rig.send(k, [(0, (2.0, 0.0, 1.0))])
        rig.poll()
    asker = memory_bus.transport()
    assert asker.query(KEYS.track_query() + "?id=2")[0][1].tracks == []  # type: ignore[union-attr]
    assert [t.id for t in asker.query(KEYS.track_query())[0][1].tracks] == [1]  # type: ignore[union-attr]


def test_shipped_colour_thresholds_match_the_embedder_card() -> None:
    from services.embedder.core.colour import COLOUR_THRESHOLDS
    from services.tracker.config import DEFAULT_APPEARANCE

    shipped = DEFAULT_APPEARANCE["colour"]
    assert (shipped["t_lower"], shipped["t_upper"], shipped["t_recover"]) == COLOUR_THRESHOLDS


# ------------------------------------------------------------------ robust profile
def test_robust_profile_publishes_coasting_tracks_then_recovers_the_id_after_a_restart(
        tmp_path: Path, caplog: pytest.LogCaptureFixture) -> None:
    caplog.set_level("INFO", logger="services.tracker.service")
    cfg = config(tmp_path, profile="robust")
    rig = Rig(MemoryBus(), cfg)
    for k in range(5):
        rig.send(k, [(0, (2.0, 0.0, 1.0)), (1, (5.0, 0.0, 1.0))])
        rig.poll()
    [last] = rig.outputs()[-1:]
    assert {t.status for t in last.tracks} == {"confirmed"} and len(last.tracks) == 2
    person0 = next(t.id for t in last.tracks if t.position[0] < 3)
    rig.send(5, [(1, (5.0, 0.0, 1.0))])  # person 0 is missed once: reported as coasting, with its prediction
    rig.poll()
    [msg] = rig.outputs()
    assert {t.id: t.status for t in msg.tracks}[person0] == "coasting"
    for k in range(6, 80):  # 2.5 s later its track is deleted and archived
        rig.send(k, [(1, (5.0, 0.0, 1.0))])
        rig.poll()
    assert person0 not in {t.id for t in rig.outputs()[-1].tracks}
    rig.service.close()
    rig2 = Rig(MemoryBus(), config(tmp_path, profile="robust"))
    for k in range(100, 104):  # person 0 comes back to a restarted tracker
        rig2.send(k, [(0, (2.0, 0.0, 1.0))])
        rig2.poll()
    assert [t.id for t in rig2.outputs()[-1].tracks] == [person0]
    assert rig2.service.counters.extra["ids_recovered"] == 1
    [line] = [r.getMessage() for r in caplog.records if r.getMessage().startswith("ID decision")]
    assert f"ID {person0} recovered" in line and f"candidates: {person0} (log-odds" in line  # why, in the log


def test_an_id_decision_applied_again_by_a_rewind_is_reported_once(
        tmp_path: Path, memory_bus: MemoryBus, caplog: pytest.LogCaptureFixture) -> None:
    caplog.set_level("INFO", logger="services.tracker.service")
    rig = Rig(memory_bus, config(tmp_path, profile="robust"))
    service = rig.service
    sub = memory_bus.transport().subscribe(KEYS.id_decisions(), IdDecisions, RELIABLE)
    made = IdDecision(3.0, 7, "new", 1.0, 2.0, 0.3, 0.5, 0.6, 0.1, (IdCandidate(4, 1.2, 0.3, True),))
    again = FrameResult(3.0, True, id_decisions=[made])
    service._report_decisions(again, HDR)
    service._report_decisions(again, HDR)  # the same frame re-applied after a late input: the same decision
    revised = IdDecision(3.0, 4, "recovered", 1.0, 2.0, 0.6, 0.5, 0.2, 0.1, (IdCandidate(4, 2.4, 0.6, True),))
    service._report_decisions(FrameResult(3.0, True, id_decisions=[revised]), HDR)  # with the late descriptors: another
    lines = [r.getMessage() for r in caplog.records if r.getMessage().startswith("ID decision")]
    assert lines == [f"ID decision: {made.summary()}", f"ID decision (revised by late inputs): {revised.summary()}"]
    sent = []
    while (got := sub.try_recv()) is not None:
        sent.append(got.msg)
    assert [[(d.id, d.outcome, d.summary) for d in m.decisions] for m in sent] == [
        [(7, "new", made.summary())], [(4, "recovered", revised.summary())]]
    assert sent[0].header.stamp_ns == HDR.stamp_ns and sent[0].header.frame_id == "map"
    assert sent[1].decisions[0].candidates[0].log_odds == 2.4


HDR = Header(stamp_ns=T0 + 3_000_000_000, frame_id="camera", seq=30, source="head")
