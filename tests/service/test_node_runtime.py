"""The shared node pieces: the stream joiner, the rate-limited log, NodeIO and the node loop."""

from __future__ import annotations

import logging
import math
import threading
from pathlib import Path

import pytest

from common.runtime.config import load_config
from common.runtime.join import Joiner
from common.messages.keys import RELIABLE, Keys
from common.transport.memory import MemoryBus
from common.runtime.node import Node, load_node_config
from common.runtime.ratelog import RateLimitedLog
from common.runtime.service import Counters, ServiceRuntime, Shutdown
from common.messages.schemas import Detections, Header

KEYS = Keys(robot="noderig")


def key(seq: int, source: str = "head") -> tuple[int, str, int]:
    return (1_000 + seq * 100, source, seq)


# ------------------------------------------------------------------- joiner
def test_header_join_key_sorts_in_sensor_time() -> None:
    a = Header(stamp_ns=5, source="z", seq=9)
    b = Header(stamp_ns=6, source="a", seq=1)
    assert a.join_key == (5, "z", 9) and a.join_key < b.join_key


def test_complete_entry_is_released_once_with_its_items() -> None:
    j: Joiner[str] = Joiner(("dets", "frame"), wait_s=1.0, buffer=4, max_waiting=4)
    assert j.add("frame", key(1), "F1", now=0.0) == []
    assert j.poll(0.0) == ([], [])  # a frame alone is not work
    j.add("dets", key(1), "D1", now=0.1)
    released, dropped = j.poll(0.1)
    assert dropped == [] and len(released) == 1
    r = released[0]
    assert (r.key, r.anchor, r.get("frame"), r.arrived, r.timed_out) == (key(1), "D1", "F1", 0.1, False)
    assert j.poll(0.2) == ([], []) and len(j) == 0
    # a repeated anchor or a late frame for a released key is dropped, not re-opened
    [dup] = j.add("dets", key(1), "D1 again", now=0.3)
    [late] = j.add("frame", key(1), "F1 again", now=0.3)
    assert (dup.reason, late.reason) == ("duplicate", "late") and len(j) == 0


def test_timeout_releases_incomplete_or_drops_per_policy() -> None:
    release: Joiner[str] = Joiner(("loc", "emb"), wait_s=0.5, buffer=4, max_waiting=4, on_timeout="release")
    release.add("loc", key(1), "L", now=10.0)
    assert release.poll(10.4) == ([], [])
    assert release.next_deadline(10.4) == pytest.approx(0.1)
    [r], _ = release.poll(10.5)
    assert r.timed_out and r.get("emb") is None
    drop: Joiner[str] = Joiner(("dets", "frame"), wait_s=0.5, buffer=4, max_waiting=4, on_timeout="drop")
    drop.add("dets", key(1), "D", now=10.0)
    _, [d] = drop.poll(10.6)
    assert (d.reason, d.slots, d.anchor) == ("timeout", ("dets",), "D")


def test_none_means_known_absent_and_complete_predicate() -> None:
    j: Joiner[list[int]] = Joiner(("loc", "emb"), wait_s=9.0, buffer=4, max_waiting=4,
                                  complete=lambda items: "emb" in items or not items["loc"])
    j.add("loc", key(1), [1], now=0.0)
    j.add("emb", key(1), None, now=0.0)  # rejected: the frame need not wait
    j.add("loc", key(2), [], now=0.0)  # nothing detected: needs no embeddings
    released, _ = j.poll(0.0)
    assert [r.key for r in released] == [key(1), key(2)] and released[0].get("emb") is None


def test_ordered_release_never_passes_a_waiting_entry() -> None:
    j: Joiner[str] = Joiner(("loc", "emb"), wait_s=1.0, buffer=4, max_waiting=8, on_timeout="release", ordered=True)
    j.add("loc", key(1), "L1", now=0.0)
    j.add("loc", key(2), "L2", now=0.0)
    j.add("emb", key(2), "E2", now=0.0)
    assert j.poll(0.5) == ([], [])  # frame 2 is complete but frame 1 still waits
    j.add("emb", key(1), "E1", now=0.6)
    released, _ = j.poll(0.6)
    assert [r.key for r in released] == [key(1), key(2)]


def test_unordered_release_with_a_limit_takes_one_at_a_time() -> None:
    j: Joiner[str] = Joiner(("dets", "frame"), wait_s=math.inf, buffer=4, max_waiting=8)
    j.add("dets", key(1), "D1", now=0.0)  # its frame never comes
    for s in (2, 3):
        j.add("frame", key(s), f"F{s}", now=0.0)
        j.add("dets", key(s), f"D{s}", now=0.0)
    first, _ = j.poll(0.0, limit=1)
    second, _ = j.poll(0.0, limit=1)
    assert [r.key for r in first + second] == [key(2), key(3)] and j.waiting == 1


def test_buffer_evicts_oldest_loose_inputs_silently_and_overflow_is_counted() -> None:
    j: Joiner[str] = Joiner(("dets", "frame"), wait_s=math.inf, buffer=2, max_waiting=2)
    for s in range(4):
        assert j.add("frame", key(s), f"F{s}", now=float(s)) == []
    assert j.evicted == 2 and len(j) == 2
    j.add("dets", key(10), "D10", now=0.0)
    j.add("dets", key(11), "D11", now=1.0)
    [over] = j.add("dets", key(12), "D12", now=2.0)
    assert (over.reason, over.key, over.anchor) == ("overflow", key(10), "D10")


def test_stale_by_sensor_time_and_lost_in_ordered_stream() -> None:
    j: Joiner[str] = Joiner(("dets", "frame"), wait_s=math.inf, buffer=8, max_waiting=8, max_lag_s=0.5)
    j.add("dets", key(1), "D1", now=0.0)
    j.add("frame", (key(1)[0] + 600_000_000, "head", 99), "F99", now=0.0)  # the camera moved on 0.6 s
    _, [d] = j.poll(0.0)
    assert d.reason == "stale"
    fifo: Joiner[str] = Joiner(("dets", "frame"), wait_s=5.0, buffer=8, max_waiting=8, in_order=("frame",))
    fifo.add("dets", key(1), "D1", now=0.0)
    assert fifo.poll(0.0) == ([], [])  # its frame may still come
    fifo.add("frame", key(2), "F2", now=0.0)  # frames come in order: frame 1 never will
    _, [lost] = fifo.poll(0.0)
    assert lost.reason == "lost"
    fifo.add("dets", key(3, source="other"), "D3", now=0.0)
    assert fifo.poll(0.0) == ([], [])  # another source's frames say nothing about it


def test_orphans_expire() -> None:
    j: Joiner[str] = Joiner(("loc", "emb"), wait_s=1.0, buffer=8, max_waiting=8, orphan_s=2.0)
    j.add("emb", key(1), "E1", now=0.0)
    assert j.poll(2.0) == ([], [])
    _, [o] = j.poll(2.1)
    assert (o.reason, o.slots) == ("orphan", ("emb",))


def test_bad_join_definitions_are_refused() -> None:
    with pytest.raises(ValueError):
        Joiner(("only",), wait_s=1, buffer=1, max_waiting=1)
    with pytest.raises(ValueError):
        Joiner(("a", "b"), wait_s=1, buffer=1, max_waiting=1, in_order=("a",))
    with pytest.raises(KeyError):
        Joiner(("a", "b"), wait_s=1, buffer=1, max_waiting=1).add("c", key(1), 1, now=0)


# --------------------------------------------------------------------- log
def test_rate_limited_log_says_how_many_were_held_back(caplog: pytest.LogCaptureFixture) -> None:
    t = [0.0]
    rl = RateLimitedLog(logging.getLogger("ratelog-test"), period_s=1.0, clock=lambda: t[0])
    with caplog.at_level(logging.WARNING, logger="ratelog-test"):
        assert rl.warning("a", "problem %d", 1)
        assert not rl.warning("a", "problem %d", 2)
        assert not rl.warning("a", "problem %d", 3)
        assert rl.warning("b", "other")  # another reason is not held back
        t[0] = 1.0
        assert rl.warning("a", "problem %d", 4)
    assert [r.getMessage() for r in caplog.records] == [
        "problem 1", "other", "problem 4 (2 more since the last report)"]


# ------------------------------------------------------------------- nodes
class Echo(Node):
    """Re-publishes detections on another camera's key; asks for a poll every 50 ms."""

    name = "echo"

    def __init__(self, transport, keys, config=None, counters=None):  # type: ignore[no-untyped-def]
        super().__init__(transport, keys, counters)
        self.inp = self.io.subscribe(keys.detections("a"), Detections, RELIABLE)
        self.out = self.io.publisher(keys.detections("b"), Detections, RELIABLE)
        self.polls = 0

    def poll(self, now: float) -> list[Detections]:
        self.polls += 1
        out = []
        while (got := self.inp.try_recv()) is not None:
            self.out.put(got.msg)
            out.append(got.msg)
        return out

    def deadline(self, now: float) -> float | None:
        return 0.05


def test_status_counts_what_the_node_declared(memory_bus: MemoryBus) -> None:
    counters = Counters()
    node = Echo(memory_bus.transport(), KEYS, counters=counters)
    runtime = ServiceRuntime("echo", node.transport, KEYS, counters=counters, io=node.io)
    peer = memory_bus.transport()
    pub = peer.publisher(KEYS.detections("a"), Detections, RELIABLE)
    sink = peer.subscribe(KEYS.detections("b"), Detections, RELIABLE)
    for s in range(3):
        pub.put(Detections(header=Header(stamp_ns=s, seq=s)))
    assert len(node.poll(0.0)) == 3
    status = runtime.status()
    assert (status.received, status.published) == (3, 3)
    assert [sink.try_recv().msg.header.seq for _ in range(3)] == [0, 1, 2]  # type: ignore[union-attr]
    node.close()
    assert node.inp.closed and node.out.closed


def test_run_polls_on_input_and_on_deadline_until_shutdown(memory_bus: MemoryBus) -> None:
    node = Echo(memory_bus.transport(), KEYS)
    shutdown = Shutdown()
    worker = threading.Thread(target=node.run, args=(shutdown,), daemon=True)
    worker.start()
    sink = memory_bus.transport().subscribe(KEYS.detections("b"), Detections, RELIABLE)
    memory_bus.transport().publisher(KEYS.detections("a"), Detections, RELIABLE).put(
        Detections(header=Header(stamp_ns=1, seq=7)))
    got = sink.recv(timeout=5.0)
    shutdown.wait(0.3)
    shutdown.set()
    worker.join(5.0)
    assert got is not None and got.msg.header.seq == 7
    assert not worker.is_alive() and node.polls >= 3  # woken by its 50 ms deadline, not only by input


# ------------------------------------------------------------------- config
def test_config_section_when_present_else_whole_file(tmp_path: Path) -> None:
    from pydantic import BaseModel, ConfigDict

    class Cfg(BaseModel):
        model_config = ConfigDict(extra="forbid")
        camera: str = "head"

    sectioned = tmp_path / "deploy.yaml"
    sectioned.write_text("tracker:\n  camera: left\n")
    flat = tmp_path / "tracker.yaml"
    flat.write_text("camera: right\n")
    assert load_config(Cfg, sectioned, section="tracker").camera == "left"
    assert load_config(Cfg, flat, section="tracker").camera == "right"
    assert load_node_config(Cfg, "tracker", flat, {"camera": None}).camera == "right"  # unset flags override nothing
    assert load_node_config(Cfg, "tracker", flat, {"camera": "cli"}).camera == "cli"
    from common.runtime.cli_util import CliError

    with pytest.raises(CliError, match=r"(?s)camera.*PERCEPTION_TRACKER__"):
        load_node_config(Cfg, "tracker", flat, {"camera": 5})


def test_a_clock_jump_lets_the_same_keys_come_again() -> None:
    """A replay that loops sends the same keys a second time; with clock_jump_s the join
    takes them as a new clock instead of dropping them as duplicates forever."""
    s = 1_000_000_000
    for jump, expect in ((None, 0), (5.0, 3)):
        j: Joiner[str] = Joiner(("dets", "frame"), wait_s=1.0, buffer=8, max_waiting=8, in_order=("frame",),
                                clock_jump_s=jump)
        for loop in range(2):
            got = 0
            for k in range(3):
                stamp_key = (100 * s + k * s, "head", k)
                j.add("frame", stamp_key, "F", now=loop * 10 + k)
                j.add("dets", stamp_key, "D", now=loop * 10 + k)
                got += len(j.poll(loop * 10 + k)[0])
            assert got == (3 if loop == 0 else expect)
            if loop == 0:
                for k in range(3, 12):  # the first run goes on 9 s more before the loop
                    late = (100 * s + k * s, "head", k)
                    j.add("frame", late, "F", now=k)
                    j.add("dets", late, "D", now=k)
                    j.poll(k)
        assert j.clock_jumps == (1 if jump else 0)
