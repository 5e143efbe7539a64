"""A replay that loops, through the whole pipeline: the simulator's stamps start over (its
transforms too), and the four real nodes go on tracking, with the people's IDs remembered.

The nodes run in one process on an in-memory bus, polled in turn as ``tools/demo/inprocess``
does; a second simulator with the same start stamp plays the loop."""

from __future__ import annotations

from common.messages.keys import RELIABLE, Keys
from common.transport.memory import MemoryBus
from common.messages.schemas import Tracks
from services.detector.config import DetectorConfig
from services.detector.service import DetectorService
from services.embedder.config import EmbedderConfig
from services.embedder.service import EmbedderService
from services.localizer.config import LocalizerConfig
from services.localizer.service import LocalizerService
from services.tracker.config import TrackerConfig
from services.tracker.service import TrackerService
from tools.simulator.config import SimulatorConfig
from tools.simulator.service import SimulatorService

FPS = 10.0
SECONDS = 12.0  # longer than the TF buffer's 10 s history, so the loop's transforms are a new clock


def test_a_looping_replay_keeps_the_pipeline_tracking_with_the_same_ids() -> None:
    keys = Keys(robot="loop")
    bus = MemoryBus()
    nodes = [
        DetectorService(bus.transport(), keys, DetectorConfig(backend="depth")),
        LocalizerService(bus.transport(), keys, LocalizerConfig()),
        EmbedderService(bus.transport(), keys, EmbedderConfig()),
        TrackerService(bus.transport(), keys, TrackerConfig(memory_path=None)),
    ]
    tracks = bus.transport().subscribe(keys.tracks(), Tracks, RELIABLE)
    clock = 0.0
    ids: list[set[int]] = []
    for _ in range(2):  # the same recording twice: stamps start over at the loop
        sim = SimulatorService(bus.transport(), keys, SimulatorConfig(
            scenario="moving-head", seed=0, fps=FPS, width=320, height=240, duration_s=SECONDS, start_ns=10**18))
        seen: set[int] = set()
        while not sim.done:
            sim.step()
            clock += 1.0 / FPS
            for node in nodes:
                node.poll(clock)
            for node in nodes[2:]:
                node.poll(clock)
            while (t := tracks.try_recv()) is not None:
                seen |= {tr.id for tr in t.msg.tracks if tr.status == "confirmed"}
        ids.append(seen)
        sim.close()
    localizer, tracker = nodes[1].counters.extra, nodes[3].counters.extra
    for node in nodes:
        node.close()
    assert tracker["clock_jumps"] == 1 and localizer["clock_jumps"] == 1
    assert "dropped_too_old" not in tracker and "dropped_no_transform" not in localizer
    first, second = ids
    assert len(first) >= 2 and second, (first, second)
    # the people of the loop are the people of the first run: their IDs come back from the memory
    assert len(second & first) >= len(first) - 1, (first, second)
    assert tracker.get("ids_recovered", 0) >= 2
