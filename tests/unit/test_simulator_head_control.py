"""The simulated head obeys velocity commands: integrated in simulated time, clipped, stopped
after a command's timeout, and published on tf as a moving base_link -> head_link."""

from __future__ import annotations

import pytest

from common.messages.keys import Keys
from common.messages.schemas import TransformBatch
from tools.simulator.config import SimulatorConfig
from tools.simulator.core.head_servo import CommandedHead
from tools.simulator.source import SimulatedStream


def test_commanded_head_integrates_clips_and_times_out() -> None:
    head = CommandedHead(pan=0.0, tilt=0.1, max_rate=1.0, pan_range=(-1.0, 1.0))
    head.command(0.0, 0.5, -0.2, timeout_s=1.0)
    assert head.angles(0.5) == pytest.approx((0.25, 0.0))
    assert head.angles(3.0) == pytest.approx((0.5, -0.1))  # stopped at the timeout (t = 1)
    head.command(3.0, 5.0, 0.0, timeout_s=10.0)  # clipped to 1 rad/s, then to the pan range
    assert head.angles(3.2)[0] == pytest.approx(0.7)
    assert head.angles(9.0)[0] == pytest.approx(1.0)


def test_head_control_moves_the_published_head_joint() -> None:
    stream = SimulatedStream(SimulatorConfig(scenario="people-following", fps=10, width=64, height=48, duration_s=2,
                                             start_ns=10**18, head_control=True), Keys(robot="hc"))
    stream.command_head(0, 0.5, 0.0, 1.0)
    _, pairs = stream.messages(10)  # t = 1 s
    tf = next(m for _, m in pairs if isinstance(m, TransformBatch) and any(t.child_frame == "head_link" and not t.static
                                                                               for t in m.transforms))
    joint = next(t for t in tf.transforms if t.child_frame == "head_link")
    assert joint.rotation_xyzw[2] == pytest.approx(0.247, abs=0.01)  # sin(0.5 / 2): 0.5 rad of pan
