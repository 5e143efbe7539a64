"""The simulated sensor stream: configuration -> world -> (key, message) pairs per frame."""

from __future__ import annotations

import math
import time

from common.keys import Keys
from common.schemas import Message, PeopleGroundTruth
from tools.simulator.config import SimulatorConfig
from tools.simulator.core.render import default_camera
from tools.simulator.core.head_servo import CommandedHead
from tools.simulator.core.scenarios import SCENARIOS, build_world
from tools.simulator.core.simulation import FrameData, Simulation
from tools.simulator.faults import OLD_STAMPS_S, apply_faults
from tools.simulator.messages import frame_message, groundtruth_message, static_transforms, tf_message

__all__ = ["SimulatedStream"]


class SimulatedStream:
    """Frames of one scenario as messages. Frame ``seq`` is at ``start_ns + seq / fps`` seconds."""

    def __init__(self, config: SimulatorConfig, keys: Keys) -> None:
        self.config = config
        self.keys = keys
        self.world = build_world(config.scenario, config.seed, config.alike)
        if config.head_control:  # the head starts at the scenario's pose, then obeys commands
            pan, tilt = self.world.robot.head.angles(0.0)
            self.world.robot.servo = CommandedHead(pan=pan, tilt=tilt)
            self.world.head_moves = True
        self.camera = default_camera(config.width, config.height)
        self.simulation = Simulation(
            self.world, self.camera, config.fps, config.seed, config.min_visible, config.depth_noise
        )
        self.faults = frozenset(config.faults)
        late_ns = round(OLD_STAMPS_S * 1e9) if "old-stamps" in self.faults else 0
        self.start_ns = max(0, (time.time_ns() if config.start_ns is None else config.start_ns) - late_ns)
        duration = SCENARIOS[config.scenario].duration_s if config.duration_s is None else config.duration_s
        #: Number of frames to produce; None = until stopped.
        self.frame_count: int | None = math.ceil(duration * config.fps) if duration > 0 else None
        self._static_every = max(1, round(config.static_period_s * config.fps))

    def stamp_ns(self, seq: int) -> int:
        return self.start_ns + round(seq * 1e9 / self.config.fps)

    def command_head(self, seq: int, pan_rate: float, tilt_rate: float, timeout_s: float) -> bool:
        """Apply a head velocity command from frame ``seq``'s time on; False without head control."""
        servo = self.world.robot.servo
        if servo is None:
            return False
        servo.command(seq / self.config.fps, pan_rate, tilt_rate, timeout_s)
        return True

    def messages(self, seq: int) -> tuple[FrameData, list[tuple[str, Message]]]:
        """Render frame ``seq``: its (key, message) pairs in publishing order (static
        transforms, transforms, ground truth, then the frame) and the raw frame data."""
        cfg, keys = self.config, self.keys
        fd = self.simulation.frame(seq)
        stamp = self.stamp_ns(seq)
        out: list[tuple[str, Message]] = []
        if seq % self._static_every == 0:
            out.append((keys.tf_static(), static_transforms(fd, stamp, cfg.camera, self.world.head_moves)))
        out.append((keys.tf(), tf_message(fd, stamp, cfg.camera, self.world.head_moves)))
        out.append((keys.groundtruth(), groundtruth_message(fd, stamp, cfg.camera, cfg.min_visible)))
        out.append((keys.frames(cfg.camera), frame_message(fd, self.camera, stamp, cfg.camera)))
        return fd, apply_faults(out, self.faults, keys, seq)

    @staticmethod
    def groundtruth_of(pairs: list[tuple[str, Message]]) -> PeopleGroundTruth:
        return next(m for _, m in pairs if isinstance(m, PeopleGroundTruth))
