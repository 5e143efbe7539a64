"""``SimulatorService``: publishes the simulated camera, transforms and ground truth."""

from __future__ import annotations

import logging
import time
from typing import Any

from common.messages.keys import COMMANDS, FRAMES, RELIABLE, SCANS, Keys
from common.runtime.service import Counters, Shutdown
from common.messages.schemas import (Detections, HeadCommand, LaserScan, Message, PeopleGroundTruth, RGBDFrame,
                                     TransformBatch)
from common.transport.base import Publisher, Subscription, Transport
from tools.simulator.config import SimulatorConfig
from tools.simulator.groundtruth import GroundTruthCsv
from tools.simulator.source import SimulatedStream

__all__ = ["SimulatorService"]

log = logging.getLogger(__name__)


class SimulatorService:
    """Publishes frame after frame of a scenario, in real time (``rate``) or, with
    ``max_speed``, each frame as soon as the detector has answered the previous one."""

    #: --max: timeouts in a row after which the detector is taken as absent.
    GIVE_UP = 3

    def __init__(
        self,
        transport: Transport,
        keys: Keys,
        config: SimulatorConfig,
        counters: Counters | None = None,
        gt_csv: GroundTruthCsv | None = None,
    ) -> None:
        self.transport = transport
        self.keys = keys
        self.config = config
        self.counters = counters if counters is not None else Counters()
        self.ros = None
        if config.ros2:
            # a ROS 2 robot: built first (its type store takes a moment), so that frame 0's stamp,
            # taken by the stream, is not older than the first publish
            from tools.simulator.ros2_out import RosRobot

            self.ros = RosRobot(transport, config.ros2_domain_id)
        self.stream = SimulatedStream(config, keys)
        if self.ros is not None:
            from tools.simulator.static_map import apartment_static_map

            self.ros.publish_map(apartment_static_map(self.stream.stamp_ns(0), self.stream.world.apartment))
        self.gt_csv = gt_csv
        self.seq = 0
        self._timeouts_in_row = 0
        self.publishers: dict[str, Publisher[Any]] = {
            keys.frames(camera): transport.publisher(keys.frames(camera), RGBDFrame, FRAMES)
            for camera in self.stream.cameras
        }
        self.publishers |= {
            keys.tf(): transport.publisher(keys.tf(), TransformBatch, RELIABLE),
            keys.tf_static(): transport.publisher(keys.tf_static(), TransformBatch, RELIABLE),
            keys.groundtruth(): transport.publisher(keys.groundtruth(), PeopleGroundTruth, RELIABLE),
        }
        if config.laser is not None:
            self.publishers[keys.scans(config.laser)] = transport.publisher(keys.scans(config.laser), LaserScan, SCANS)
        if self.ros is not None:
            # the head camera and the transforms go out as ROS 2 topics instead
            for key in (keys.frames(config.camera), keys.tf(), keys.tf_static()):
                self.publishers[key].close()
            self.publishers[keys.frames(config.camera)] = self.ros.camera()  # type: ignore[assignment]
            self.publishers[keys.tf()] = self.ros.transforms(static=False)  # type: ignore[assignment]
            self.publishers[keys.tf_static()] = self.ros.transforms(static=True)  # type: ignore[assignment]
            if config.laser is not None:  # the base laser's driver: /scan
                self.publishers[keys.scans(config.laser)].close()
                self.publishers[keys.scans(config.laser)] = self.ros.laser()  # type: ignore[assignment]
        # --max: each camera's detector (the head's, and the back camera's if there is one)
        self._detections: dict[str, Subscription[Detections]] = {
            camera: transport.subscribe(keys.detections(camera), Detections, RELIABLE)
            for camera in self.stream.cameras
        } if config.max_speed else {}
        self._head = transport.subscribe(keys.head_command(), HeadCommand, COMMANDS) if config.head_control else None

    @property
    def done(self) -> bool:
        total = self.stream.frame_count
        return total is not None and self.seq >= total

    def step(self) -> list[tuple[str, Message]]:
        """Render and publish the next frame; returns what was published."""
        if self._head is not None and (got := self._head.try_recv()) is not None:  # the newest command only
            cmd = got.msg
            self.stream.command_head(self.seq, cmd.pan_rate, cmd.tilt_rate, cmd.timeout_s)
            self.counters.count("head_commands")
        t0 = time.perf_counter()
        _, pairs = self.stream.messages(self.seq)
        self.counters.gauge("render_ms", (time.perf_counter() - t0) * 1000.0)
        for key, msg in pairs:
            self.publishers[key].put(msg)
        if self.gt_csv is not None:
            self.gt_csv.add(SimulatedStream.groundtruth_of(pairs))
        self.counters.count("frames")
        self.seq += 1
        return pairs

    def _wait_for_detector(self, seq: int, shutdown: Shutdown) -> None:
        """--max: wait until the detector of every camera that has one listening has published
        the detections of frame ``seq``.

        After ``GIVE_UP`` timeouts in a row the detectors are taken as absent and frames go out
        unpaced, until one answers again.
        """
        waiting = {camera: sub for camera, sub in self._detections.items()
                   if self.publishers[self.keys.frames(camera)].has_subscribers()}
        if not waiting:
            return
        if self._timeouts_in_row >= self.GIVE_UP:
            if all(sub.try_recv() is None for sub in waiting.values()):
                return
            self._timeouts_in_row = 0
        deadline = time.monotonic() + self.config.max_wait_s
        while waiting and not shutdown.is_set():
            remaining = deadline - time.monotonic()
            if remaining <= 0:
                self.counters.count("detector_timeouts")
                self._timeouts_in_row += 1
                if self._timeouts_in_row == self.GIVE_UP:
                    log.warning("no detections from %s for %d frames: unpaced until the detector answers",
                                ", ".join(waiting), self.GIVE_UP)
                return
            for camera, sub in list(waiting.items()):
                got = sub.recv(timeout=min(remaining, 0.1 / len(waiting)))
                if got is not None and got.msg.header.seq >= seq:
                    del waiting[camera]
        self._timeouts_in_row = 0

    def run(self, shutdown: Shutdown) -> None:
        """Publish until the scenario ends or ``shutdown`` is set."""
        cfg = self.config
        wall0 = time.monotonic()
        first = self.seq
        while not self.done and not shutdown.is_set():
            if not cfg.max_speed:
                delay = wall0 + (self.seq - first) / cfg.fps / cfg.rate - time.monotonic()
                if delay > 0 and shutdown.wait(delay):
                    break
                if delay < -1.0 / cfg.fps:
                    self.counters.count("late_frames")
            seq = self.seq
            self.step()
            if self._detections:
                self._wait_for_detector(seq, shutdown)
            elapsed = time.monotonic() - wall0
            if elapsed > 0:
                self.counters.gauge("fps", (self.seq - first) / elapsed)
        log.info("simulator published %d frames", self.seq - first)

    def close(self) -> None:
        for pub in self.publishers.values():
            pub.close()
        if self.ros is not None:
            self.ros.close()
        for sub in (*self._detections.values(), self._head):
            if sub is not None:
                sub.close()
