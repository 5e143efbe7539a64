"""Tracks at a fixed rate (TU Ilmenau): the output holds its rate whatever the input rate,
through a pause, predicted to each publish time; late frames still go in stamp order."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from common.messages.schemas import Tracks
from tests.helpers.tracker_rig import T0, Rig, config

S = 1_000_000_000


def run(rig: Rig, input_hz: float, seconds: float, x0: float = 2.0, speed: float = 0.0, t0: float = 0.0,
        pause: tuple[float, float] | None = None) -> list[Tracks]:
    """A person at (x0 + speed t, 0) seen at ``input_hz``; the service polled every 10 ms."""
    out: list[Tracks] = []
    next_frame, seq, t = t0, int(t0 * 1000), t0
    while t < t0 + seconds:
        if t >= next_frame - 1e-9:
            if pause is None or not pause[0] <= t < pause[1]:
                rig.send(T0 + int(t * S), seq, [(0, (x0 + speed * t, 0.0, 1.0))])
                seq += 1
            next_frame += 1.0 / input_hz
        rig.clock.now = 100.0 + t
        out += rig.service.poll(rig.clock())
        t = round(t + 0.01, 6)
    return out


@pytest.mark.parametrize("input_hz", [5.0, 10.0, 30.0])
def test_the_output_rate_holds_whatever_the_input_rate(tmp_path: Path, input_hz: float) -> None:
    rig = Rig(config(tmp_path, output_rate_hz=10.0))
    out = run(rig, input_hz, 4.0)
    stamps = np.array([m.header.stamp_ns for m in out]) / S
    periods = np.diff(stamps)
    assert len(out) == pytest.approx(40, abs=2)
    assert np.median(periods) == pytest.approx(0.1, abs=0.005) and periods.min() > 0.09
    assert all(m.input_stamp_ns <= m.header.stamp_ns for m in out)
    assert [t.id for t in out[-1].tracks] == [1]


def test_the_output_goes_on_through_a_pause_and_predicts_to_the_publish_time(tmp_path: Path) -> None:
    rig = Rig(config(tmp_path, output_rate_hz=10.0))
    out = run(rig, 5.0, 4.0, speed=1.0, pause=(2.0, 2.25))
    t = np.array([m.header.stamp_ns - T0 for m in out]) / S
    assert np.max(np.diff(t)) < 0.12  # no gap in the output during the pause
    # between two frames 0.2 s apart, the outputs move on with the person (predicted), not in steps
    xs = np.array([m.tracks[0].position[0] if m.tracks else np.nan for m in out])
    walking = (t > 1.0) & (t < 2.0)
    np.testing.assert_allclose(xs[walking], 2.0 + t[walking], atol=0.12)
    assert len(set(np.round(xs[walking], 3))) == walking.sum()  # a new position at every output


def test_late_frames_are_applied_in_stamp_order_at_a_fixed_rate(tmp_path: Path) -> None:
    rig = Rig(config(tmp_path, output_rate_hz=10.0))
    out = []
    for k in range(20):
        seq = k ^ 1 if 5 <= k < 15 else k  # pairs of frames arrive swapped
        rig.send(T0 + seq * S // 10, seq, [(0, (2.0, 0.0, 1.0))])
        rig.clock.now += 0.1
        out += rig.service.poll(rig.clock())
    assert "dropped_too_old" not in rig.extra and rig.extra.get("rewinds", 0) >= 3
    assert len(out) >= 18 and out[-1].tracks


def test_zero_publishes_once_per_frame_as_before(tmp_path: Path) -> None:
    rig = Rig(config(tmp_path, output_rate_hz=0.0))
    out = run(rig, 30.0, 1.0)
    assert len(out) == 30 and all(m.input_stamp_ns == m.header.stamp_ns for m in out)
