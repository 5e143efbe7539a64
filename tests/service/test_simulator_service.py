"""Simulator service through the in-memory transport, the MCAP writer, the GT CSV and the CLI."""

from __future__ import annotations

import threading
import time
from pathlib import Path

import numpy as np
import pytest

from common.messages.codec import decode
from common.geometry.messages import rigid_from_msg
from common.messages.keys import FRAMES, RELIABLE, Keys
from common.transport.memory import MemoryBus
from common.runtime.service import Counters, Shutdown
from common.messages.schemas import (
    MESSAGE_TYPES,
    Detections,
    Header,
    PeopleGroundTruth,
    RGBDFrame,
    Transform,
    TransformBatch,
)
from perception.cli import main as cli_main
from tests.helpers.wait import wait_until
from tools.simulator.config import SimulatorConfig
from tools.simulator.core.scenarios import SCENARIOS
from tools.simulator.groundtruth import write_groundtruth_csv
from tools.simulator.service import SimulatorService
from tools.simulator.source import SimulatedStream

KEYS = Keys()
START = 1_700_000_000_000_000_000


def _config(**kw: object) -> SimulatorConfig:
    base = dict(width=160, height=120, fps=10.0, start_ns=START, duration_s=1.0)
    base.update(kw)
    return SimulatorConfig(**base)  # type: ignore[arg-type]


def _pose(tf: Transform) -> np.ndarray:
    """T_parent_child of a published transform, read as the localizer reads it."""
    return rigid_from_msg(tf).matrix


def test_published_messages_share_the_frame_header_and_compose_to_the_camera_pose(memory_bus: MemoryBus) -> None:
    t = memory_bus.transport()
    cfg = _config(scenario="moving-head")
    subs = {
        "frames": t.subscribe(KEYS.frames("head"), RGBDFrame, FRAMES),
        "tf": t.subscribe(KEYS.tf(), TransformBatch, RELIABLE),
        "static": t.subscribe(KEYS.tf_static(), TransformBatch, RELIABLE),
        "gt": t.subscribe(KEYS.groundtruth(), PeopleGroundTruth, RELIABLE),
    }
    service = SimulatorService(memory_bus.transport(), KEYS, cfg, Counters())
    static_tfs: dict[tuple[str, str], np.ndarray] = {}
    for seq in range(3):
        service.step()
        frame = subs["frames"].recv(timeout=5.0).msg
        tf = subs["tf"].recv(timeout=5.0).msg
        gt = subs["gt"].recv(timeout=5.0).msg
        if seq == 0:
            for item in subs["static"].recv(timeout=5.0).msg.transforms:
                static_tfs[(item.parent_frame, item.child_frame)] = _pose(item)
        stamp = START + seq * 100_000_000
        for header in (frame.header, frame.rgb.header, frame.depth.header, frame.camera_info.header):
            assert (header.stamp_ns, header.seq, header.source, header.frame_id) == (stamp, seq, "head", "camera")
        assert frame.rgb.encoding == "rgb8" and frame.depth.encoding == "16UC1"
        assert frame.rgb.shape == (120, 160, 3) and frame.depth.shape == (120, 160)
        assert (gt.header.stamp_ns, gt.header.seq, gt.header.frame_id) == (stamp, seq, "map")
        assert all(item.stamp_ns == stamp for item in tf.transforms)
        chain = {(i.parent_frame, i.child_frame): _pose(i) for i in tf.transforms} | static_tfs
        # the head moves in this scenario: its joint is a dynamic transform
        assert ("base_link", "head_link") in {(i.parent_frame, i.child_frame) for i in tf.transforms}
        cam = (
            chain[("map", "odom")]
            @ chain[("odom", "base_link")]
            @ chain[("base_link", "head_link")]
            @ chain[("head_link", "camera")]
        )
        truth = service.stream.simulation.frame(seq).map_camera
        np.testing.assert_allclose(cam, truth, atol=1e-6)
        assert {p.id for p in gt.people} == {1, 2, 3}
    assert service.counters.extra["frames"] == 3


def test_a_static_head_is_a_static_transform(memory_bus: MemoryBus) -> None:
    t = memory_bus.transport()
    static = t.subscribe(KEYS.tf_static(), TransformBatch, RELIABLE)
    dynamic = t.subscribe(KEYS.tf(), TransformBatch, RELIABLE)
    SimulatorService(memory_bus.transport(), KEYS, _config(scenario="still")).step()
    assert {(i.parent_frame, i.child_frame) for i in static.recv(timeout=5.0).msg.transforms} == {
        ("base_link", "head_link"),
        ("head_link", "camera"),
    }
    assert {(i.parent_frame, i.child_frame) for i in dynamic.recv(timeout=5.0).msg.transforms} == {
        ("map", "odom"),
        ("odom", "base_link"),
    }


def test_run_ends_after_the_duration(memory_bus: MemoryBus) -> None:
    t = memory_bus.transport()
    gt = t.subscribe(KEYS.groundtruth(), PeopleGroundTruth, RELIABLE)
    service = SimulatorService(memory_bus.transport(), KEYS, _config(rate=100.0, duration_s=1.0))
    with Shutdown() as shutdown:
        service.run(shutdown)
    assert service.seq == 10 and gt.pending() == 10


def test_max_speed_waits_for_the_detector_so_it_sees_every_frame(memory_bus: MemoryBus) -> None:
    detector_side = memory_bus.transport()
    frames = detector_side.subscribe(KEYS.frames("head"), RGBDFrame, FRAMES)
    out = detector_side.publisher(KEYS.detections("head"), Detections, RELIABLE)
    seen: list[int] = []
    stop = threading.Event()

    def detector() -> None:
        while not stop.is_set():
            got = frames.recv(timeout=0.1)
            if got is not None:
                seen.append(got.msg.header.seq)
                out.put(Detections(header=Header(**got.msg.header.model_dump())))

    thread = threading.Thread(target=detector, daemon=True)
    thread.start()
    service = SimulatorService(memory_bus.transport(), KEYS, _config(max_speed=True, max_wait_s=10.0, duration_s=2.0))
    try:
        with Shutdown() as shutdown:
            service.run(shutdown)
    finally:
        stop.set()
        thread.join(timeout=5.0)
    assert seen == list(range(20))
    assert "detector_timeouts" not in service.counters.extra


def test_max_speed_waits_for_both_cameras_detectors(memory_bus: MemoryBus) -> None:
    """With a back camera, --max paces on both detectors: the slower one sees every frame too."""
    seen: dict[str, list[int]] = {"head": [], "back": []}
    subscribed = {"head": threading.Event(), "back": threading.Event()}
    stop = threading.Event()

    def detector(camera: str, delay_s: float) -> None:
        side = memory_bus.transport()
        frames = side.subscribe(KEYS.frames(camera), RGBDFrame, FRAMES)
        out = side.publisher(KEYS.detections(camera), Detections, RELIABLE)
        subscribed[camera].set()
        while not stop.is_set():
            got = frames.recv(timeout=0.1)
            if got is not None:
                time.sleep(delay_s)  # not a wait: the slower detector's inference time
                seen[camera].append(got.msg.header.seq)
                out.put(Detections(header=Header(**got.msg.header.model_dump())))

    threads = [threading.Thread(target=detector, args=(c, d), daemon=True) for c, d in (("head", 0.0), ("back", 0.03))]
    for thread in threads:
        thread.start()
    wait_until(lambda: all(e.is_set() for e in subscribed.values()), 30.0, what="both detectors to subscribe")
    service = SimulatorService(memory_bus.transport(), KEYS,
                               _config(max_speed=True, max_wait_s=10.0, duration_s=2.0, back_camera="back"))
    try:
        with Shutdown() as shutdown:
            service.run(shutdown)
    finally:
        stop.set()
        for thread in threads:
            thread.join(timeout=5.0)
    assert seen["head"] == list(range(20)) and seen["back"] == list(range(20))  # FRAMES keeps only the newest
    assert "detector_timeouts" not in service.counters.extra


def test_max_speed_stops_waiting_for_an_absent_detector(memory_bus: MemoryBus) -> None:
    frames = memory_bus.transport().subscribe(KEYS.frames("head"), RGBDFrame, FRAMES)  # a listener, no detector
    service = SimulatorService(memory_bus.transport(), KEYS, _config(max_speed=True, max_wait_s=0.05, duration_s=1.0))
    with Shutdown() as shutdown:
        service.run(shutdown)
    assert service.seq == 10 and frames.stats.received == 10
    assert service.counters.extra["detector_timeouts"] == SimulatorService.GIVE_UP


@pytest.mark.parametrize("name", list(SCENARIOS))
def test_every_scenario_runs(name: str) -> None:
    stream = SimulatedStream(_config(scenario=name, duration_s=2.0, fps=5.0, width=96, height=72), KEYS)
    assert stream.frame_count == 10
    ids: set[int] = set()
    for seq in range(stream.frame_count):
        _, pairs = stream.messages(seq)
        keys = [k for k, _ in pairs]
        assert KEYS.frames("head") in keys and KEYS.tf() in keys and KEYS.groundtruth() in keys
        gt = SimulatedStream.groundtruth_of(pairs)
        ids |= {p.id for p in gt.people}
        assert all(1.5 <= p.height_m <= 1.95 for p in gt.people)
    assert ids == set(range(1, len(stream.world.walkers) + 1))


def test_clothes_change_keeps_the_id() -> None:
    stream = SimulatedStream(_config(scenario="changing-clothes-in-view", duration_s=30.0, fps=2.0), KEYS)
    outfits = {
        (p.id, p.outfit, p.clothing)
        for seq in range(0, 60, 2)
        for p in SimulatedStream.groundtruth_of(stream.messages(seq)[1]).people
        if p.id == 1
    }
    assert {o for _, o, _ in outfits} == {0, 1} and len({c for _, _, c in outfits}) == 2


def test_alike_dresses_two_people_the_same() -> None:
    stream = SimulatedStream(_config(alike=True), KEYS)
    a, b = stream.world.walkers[0].wardrobe[0], stream.world.walkers[1].wardrobe[0]
    assert (a.top, a.bottom, a.pattern) == (b.top, b.bottom, b.pattern)


def test_groundtruth_csv_reads_in_the_evaluator(tmp_path: Path) -> None:
    from tools.evaluation.readers import read_tracking_csv

    stream = SimulatedStream(_config(duration_s=2.0), KEYS)
    msgs = [SimulatedStream.groundtruth_of(stream.messages(seq)[1]) for seq in range(20)]
    path = tmp_path / "gt.csv"
    rows = write_groundtruth_csv(path, msgs)
    table = read_tracking_csv(path)
    expected = [(m.header.seq, p.id) for m in msgs for p in m.people if p.counted]
    assert rows == len(table) == len(expected) > 0
    assert sorted(zip(table.frames.tolist(), table.ids.tolist())) == sorted(expected)


def test_output_writes_an_mcap_that_describes_itself(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    from mcap.reader import make_reader

    out, gt = tmp_path / "run.mcap", tmp_path / "gt.csv"
    code = cli_main(
        [
            "simulate",
            "--scenario",
            "chairs",
            "--duration",
            "1",
            "--fps",
            "5",
            "--width",
            "64",
            "--height",
            "48",
            "--start-ns",
            str(START),
            "--output",
            str(out),
            "--gt-csv",
            str(gt),
        ]
    )
    assert code == 0 and "wrote" in capsys.readouterr().out
    counts: dict[str, int] = {}
    with out.open("rb") as f:
        for schema, channel, message in make_reader(f).iter_messages():
            assert channel.message_encoding == "msgpack"
            msg = decode(MESSAGE_TYPES[schema.name], message.data)
            assert message.log_time == message.publish_time == msg.header.stamp_ns
            counts[channel.topic] = counts.get(channel.topic, 0) + 1
    assert counts[KEYS.frames("head")] == counts[KEYS.tf()] == counts[KEYS.groundtruth()] == 5
    assert counts[KEYS.tf_static()] == 1
    assert gt.read_text().splitlines()[0] == "frame,id,x,y,z"


def test_list_snapshot_and_errors(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    assert cli_main(["simulate", "--list"]) == 0
    listing = capsys.readouterr().out
    assert all(name in listing for name in SCENARIOS)
    png = tmp_path / "snap.png"
    assert (
        cli_main(["simulate", "--scenario", "still", "--width", "160", "--height", "120", "--snapshot", str(png)]) == 0
    )
    import cv2

    assert cv2.imread(str(png)).shape == (120, 320, 3)
    assert cli_main(["simulate", "--scenario", "nope", "--snapshot", str(png)]) == 2
    assert "unknown scenario 'nope'" in capsys.readouterr().err
    assert cli_main(["simulate", "--output", str(tmp_path / "missing" / "x.mcap")]) == 2
    assert "does not exist" in capsys.readouterr().err
