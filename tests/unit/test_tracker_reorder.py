"""The out-of-order buffer: inputs applied in stamp order, late ones replayed, stale ones dropped."""

from __future__ import annotations

import numpy as np

from services.tracker.core import AppearanceGate, ThesisTracker, ThesisParams
from services.tracker.core.types import FrameInput
from services.tracker.reorder import ReorderBuffer

MS = 1_000_000


class Recorder:
    """A consumer whose state is the list of stamps applied, in order."""

    def __init__(self) -> None:
        self.applied: list[int] = []

    def buffer(self, window_ms: int = 500, period_ms: int = 100) -> ReorderBuffer:
        return ReorderBuffer(apply=self.apply, snapshot=lambda: list(self.applied), restore=self.restore,
                             window_ns=window_ms * MS, snapshot_period_ns=period_ms * MS)

    def apply(self, stamp: int) -> int:
        self.applied.append(stamp)
        return stamp

    def restore(self, state: list[int]) -> None:
        self.applied = list(state)


def push(buf: ReorderBuffer, stamp_ms: int) -> list:
    return buf.push((stamp_ms * MS, "head", stamp_ms), stamp_ms)


def test_in_order_inputs_are_applied_at_once() -> None:
    rec = Recorder()
    buf = rec.buffer()
    for t in range(0, 1000, 33):
        assert push(buf, t) == [t]
    assert rec.applied == list(range(0, 1000, 33)) and buf.rewinds == 0


def test_late_input_within_window_is_replayed_in_order() -> None:
    rec = Recorder()
    buf = rec.buffer()
    for t in range(0, 700, 33):
        push(buf, t)
    results = push(buf, 500)  # late by 193 ms
    assert results[-1] == 693 and 500 in results
    assert rec.applied == sorted(list(range(0, 700, 33)) + [500])
    assert buf.rewinds == 1 and buf.dropped_old == 0


def test_input_older_than_window_is_dropped_and_counted() -> None:
    rec = Recorder()
    buf = rec.buffer()
    for t in range(0, 2000, 33):
        push(buf, t)
    before = list(rec.applied)
    assert push(buf, 1000) == []  # 980 ms behind the newest
    assert rec.applied == before and buf.dropped_old == 1


def test_duplicates_are_dropped() -> None:
    rec = Recorder()
    buf = rec.buffer()
    push(buf, 10)
    push(buf, 20)
    assert push(buf, 10) == [] and buf.dropped_duplicate == 1


def test_an_input_still_in_the_log_can_be_replaced_and_everything_after_it_is_applied_again() -> None:
    rec = Recorder()
    buf = rec.buffer()
    for t in range(0, 700, 33):
        buf.push((t * MS, "head", t), (t, "position"))
    assert buf.get((495 * MS, "head", 495)) == (495, "position") and buf.get((496 * MS, "head", 496)) is None
    results = buf.push((495 * MS, "head", 495), (495, "appearance"), replace=True)
    assert (495, "appearance") in results and results[-1] == (693, "position")  # replayed from a snapshot before it
    assert rec.applied == [(t, "appearance" if t == 495 else "position") for t in range(0, 700, 33)]
    assert buf.rewinds == 1 and buf.dropped_duplicate == 0
    # the newest input replaced; an input that left the log (or never came) is dropped as too old
    assert buf.push((693 * MS, "head", 693), (693, "appearance"), replace=True)[-1] == (693, "appearance")
    assert rec.applied[-2:] == [(660, "position"), (693, "appearance")]
    for t in range(726, 2000, 33):
        buf.push((t * MS, "head", t), (t, "position"))
    assert buf.push((495 * MS, "head", 495), (495, "late"), replace=True) == [] and buf.dropped_old == 1
    assert buf.push((1900 * MS, "head", 1900), (1900, "x"), replace=True) == [] and buf.dropped_old == 2


def test_memory_stays_bounded() -> None:
    rec = Recorder()
    buf = rec.buffer(window_ms=200, period_ms=50)
    for t in range(0, 20_000, 10):
        push(buf, t)
    assert len(buf._log) <= 30 and len(buf._snaps) <= 8


def test_tracker_result_equals_in_order_processing() -> None:
    """Shuffled arrival within the window gives exactly the tracker state of ordered arrival."""
    rng = np.random.default_rng(4)
    looks = rng.normal(size=(2, 16))
    looks /= np.linalg.norm(looks, axis=1, keepdims=True)
    frames = []
    for k in range(60):
        pos = np.array([[0.03 * k, 0.0, 1.0], [2.0, -0.02 * k, 1.0]]) + rng.normal(scale=0.01, size=(2, 3))
        desc = (looks + rng.normal(scale=0.01, size=looks.shape)).astype(np.float32)
        frames.append((k * 33 * MS, pos, desc))
    params = ThesisParams(gate=AppearanceGate(0.25, 0.6), t_recover=0.35)

    def run(order: list[int]) -> ThesisTracker:
        tr = ThesisTracker(params)
        buf = ReorderBuffer(apply=lambda f: tr.step(f[0] / 1e9, FrameInput.of(f[1], f[2])), snapshot=tr.snapshot,
                            restore=tr.restore)
        for k in order:
            buf.push((frames[k][0], "head", k), frames[k])
        return tr

    ordered = run(list(range(60)))
    shuffled_order = list(range(60))
    for i in range(0, 60, 6):  # swap neighbours within blocks (at most ~165 ms late)
        block = shuffled_order[i : i + 6]
        rng.shuffle(block)
        shuffled_order[i : i + 6] = block
    shuffled = run(shuffled_order)
    assert [t.id for t in ordered.tracks] == [t.id for t in shuffled.tracks]
    for a, b in zip(ordered.tracks, shuffled.tracks):
        np.testing.assert_allclose(a.mean, b.mean)
        assert a.status == b.status and a.hits == b.hits
