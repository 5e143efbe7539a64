"""The simulated sensor stream: configuration -> world -> (key, message) pairs per frame."""

from __future__ import annotations

import math
import time

from common.messages.keys import Keys
from common.messages.schemas import Message, PeopleGroundTruth, RGBDFrame
from tools.simulator.config import SimulatorConfig
from tools.simulator.core.cameras import back_camera
from tools.simulator.core.head_servo import CommandedHead
from tools.simulator.core.laser_scan import LaserSpec
from tools.simulator.core.render import default_camera
from tools.simulator.core.scenarios import SCENARIOS, build_world
from tools.simulator.core.simulation import BaseLaser, FrameData, Simulation
from tools.simulator.faults import OLD_STAMPS_S, apply_faults
from tools.simulator.messages import (
    fixed_frame_message,
    frame_message,
    groundtruth_message,
    scan_message,
    static_transforms,
    tf_message,
)

__all__ = ["SimulatedStream"]


class SimulatedStream:
    """Frames of one scenario as messages. Frame ``seq`` is at ``start_ns + seq / fps`` seconds.

    With ``config.back_camera`` every tick has two RGB-D frames, the head camera's and the
    back camera's, with the same stamp and seq (each camera counts its own frames, one per
    tick); :attr:`cameras` names them and :meth:`frames_of` picks them out of a tick's messages.
    """

    def __init__(self, config: SimulatorConfig, keys: Keys) -> None:
        self.config = config
        self.keys = keys
        self.world = build_world(config.scenario, config.seed, config.alike)
        if config.head_control:  # the head starts at the scenario's pose, then obeys commands
            pan, tilt = self.world.robot.head.angles(0.0)
            self.world.robot.servo = CommandedHead(pan=pan, tilt=tilt)
            self.world.head_moves = True
        self.camera = default_camera(config.width, config.height)
        fixed = [back_camera(config.back_camera)] if config.back_camera is not None else []
        self.laser = None if config.laser is None else BaseLaser(LaserSpec(
            fov_deg=config.laser_fov_deg, step_deg=config.laser_step_deg, rate_hz=config.laser_rate_hz), config.laser)
        self.simulation = Simulation(
            self.world, self.camera, config.fps, config.seed, config.min_visible, config.depth_noise, fixed, self.laser
        )
        #: The names of the cameras published, the head camera first; each has a frames key.
        self.cameras: tuple[str, ...] = (config.camera, *(c.name for c in fixed))
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
        transforms, transforms, ground truth, then the frames, the head camera's first) and
        the raw frame data (the back camera's in its ``views``)."""
        cfg, keys = self.config, self.keys
        fd = self.simulation.frame(seq)
        stamp = self.stamp_ns(seq)
        out: list[tuple[str, Message]] = []
        if seq % self._static_every == 0:
            out.append((keys.tf_static(), static_transforms(fd, stamp, cfg.camera, self.world.head_moves, self.laser)))
        out.append((keys.tf(), tf_message(fd, stamp, cfg.camera, self.world.head_moves)))
        out.append((keys.groundtruth(), groundtruth_message(fd, stamp, cfg.camera, cfg.min_visible)))
        out.append((keys.frames(cfg.camera), frame_message(fd, self.camera, stamp, cfg.camera)))
        for name, view in fd.views.items():
            out.append((keys.frames(name), fixed_frame_message(view, fd.seq, self.camera, stamp)))
        if fd.scan is not None:
            out.append((keys.scans(fd.scan.laser.name), scan_message(fd.scan, fd.seq, stamp)))
        return fd, apply_faults(out, self.faults, keys, seq)

    @staticmethod
    def groundtruth_of(pairs: list[tuple[str, Message]]) -> PeopleGroundTruth:
        return next(m for _, m in pairs if isinstance(m, PeopleGroundTruth))

    @staticmethod
    def frames_of(pairs: list[tuple[str, Message]]) -> dict[str, RGBDFrame]:
        """The RGB-D frames of one tick's messages by camera name (``header.source``)."""
        return {m.header.source: m for _, m in pairs if isinstance(m, RGBDFrame)}
