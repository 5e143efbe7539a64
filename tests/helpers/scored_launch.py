"""A launch file's pipeline fed by the simulator and scored against its ground truth.

``scored_run`` starts ``perception launch FILE`` (router and the four services), waits
until the services are alive, then runs ``perception simulate`` with a fixed scenario,
seed and duration, and scores the tracks with ``perception demo``'s code
(:func:`tools.demo.scoring.score`, Table II). The plain and the secure deployment are run
the same way; only the endpoint and the client's Zenoh config and credentials differ.
"""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Callable

from common.messages.keys import RELIABLE, Keys
from common.transport.router_process import wait_for_port
from common.messages.schemas import Tracks
from common.transport.zenoh_config import ZenohOptions
from common.transport.zenoh import open_transport
from tools.demo.monitor import Monitor
from tools.demo.scoring import GroundTruthLog, score

__all__ = ["PIPELINE_ENV", "SERVICES", "Run", "Scenario", "ZenohClient", "scored_run"]

PY = sys.executable
SERVICES = ("detector", "localizer", "embedder", "tracker")


@dataclass(frozen=True)
class Scenario:
    """What the simulator plays: ``perception demo``'s defaults, 20 s of ``still`` (its integration test)."""

    name: str = "still"
    seed: int = 0
    duration_s: float = 20.0
    fps: float = 10.0
    width: int = 320
    height: int = 240
    #: each frame as soon as the detector has answered the previous one (``perception simulate
    #: --max``): the same frames reach the tracker whatever else the machine is doing
    max_speed: bool = False


@dataclass(frozen=True)
class ZenohClient:
    """How a client reaches the launched router: endpoint, and for the secure deployment its
    Zenoh config and a credentials file per role (``{role}`` in ``credentials``)."""

    endpoint: str
    config_file: Path | None = None
    credentials: str | None = None  # e.g. ".../credentials/{role}.txt"

    def options(self, role: str) -> ZenohOptions:
        return ZenohOptions(mode="client", connect=[self.endpoint], config_file=self.config_file,
                            credentials=Path(self.credentials.format(role=role)) if self.credentials else None,
                            connect_timeout_s=30.0)

    def flags(self, role: str) -> list[str]:
        out = ["--connect", self.endpoint]
        if self.config_file is not None:
            out += ["--config", str(self.config_file)]
        if self.credentials is not None:
            out += ["--credentials", self.credentials.format(role=role)]
        return out


#: The same settings as ``perception demo`` (tools/demo/main.py), through the services'
#: PERCEPTION_<NAME>__* environment: the depth detector, and Tracks once per camera frame,
#: as Table II scores every frame against its ground truth. One BLAS thread per process.
PIPELINE_ENV = {"PERCEPTION_DETECTOR__BACKEND": "depth", "PERCEPTION_TRACKER__OUTPUT_RATE_HZ": "0",
                "OPENBLAS_NUM_THREADS": "1", "OMP_NUM_THREADS": "1", "RUST_LOG": "off"}


@dataclass
class Run:
    """One scored run: Table II as a dict (``overall``: mota, idf1, ...) and what a consumer saw."""

    report: dict[str, Any]
    consumer_tracks: int = 0
    launch_status: int | None = None
    log: str = field(default="", repr=False)

    @property
    def overall(self) -> dict[str, Any]:
        return self.report["overall"]


def _stop(proc: subprocess.Popen[bytes], timeout: float = 60.0) -> int:
    if proc.poll() is None:
        proc.send_signal(signal.SIGINT)
    try:
        return proc.wait(timeout)
    except subprocess.TimeoutExpired:
        proc.kill()
        proc.wait()
        return -9


def scored_run(launch_file: Path, port: int, client: ZenohClient, workdir: Path, robot: str,
               scenario: Scenario | None = None, env: dict[str, str] | None = None,
               feeder: Callable[[Scenario, Keys], list[str]] | None = None,
               services: tuple[str, ...] = SERVICES) -> Run:
    """Launch ``launch_file`` on ``port``, play ``scenario`` into it, score the tracks.

    The monitor (``monitor`` role: reads everything) collects the ground truth and every
    stage's output; a ``consumer`` (navigation's role: tracks only) counts the Tracks with
    people in them that reach it. ``workdir`` gets the logs and the tracker's ID memory.
    """
    sc = scenario or Scenario()
    workdir.mkdir(parents=True, exist_ok=True)
    log_path = workdir / "launch.log"
    keys = Keys(robot=robot)
    launch = subprocess.Popen(
        [PY, "-m", "perception", "launch", str(launch_file)], stdout=log_path.open("wb"), stderr=subprocess.STDOUT,
        env={**os.environ, **PIPELINE_ENV, "ROBOT": robot, "ZENOH_PORT": str(port), "XDG_STATE_HOME": str(workdir),
             **(env or {})})
    sim: subprocess.Popen[bytes] | None = None
    run = Run(report={})
    try:
        if not wait_for_port("127.0.0.1", port, 60, launch):
            raise AssertionError(f"no router on port {port}:\n{log_path.read_text()[-3000:]}")
        with open_transport(client.options("monitor")) as mon, open_transport(client.options("consumer")) as nav:
            monitor, gt = Monitor(mon, keys), GroundTruthLog(mon, keys)
            tracks = nav.subscribe(keys.tracks(), Tracks, RELIABLE)
            deadline, alive = time.monotonic() + 90, set()
            while time.monotonic() < deadline and not set(services) <= alive and launch.poll() is None:
                alive = {keys.parse_alive(k).service for k in mon.alive(keys.alive(), timeout=0.5)}
            if not set(services) <= alive:
                raise AssertionError(f"alive: {sorted(alive)}\n{log_path.read_text()[-3000:]}")
            command = feeder(sc, keys) if feeder is not None else [
                PY, "-m", "perception", "simulate", "--scenario", sc.name, "--seed", str(sc.seed),
                "--duration", str(sc.duration_s), "--fps", str(sc.fps), "--width", str(sc.width),
                "--height", str(sc.height), *(("--max",) if sc.max_speed else ()), "--robot", robot,
                *client.flags("sensors")]
            sim = subprocess.Popen(
                command,
                stdout=(workdir / "simulate.log").open("wb"), stderr=subprocess.STDOUT,
                env={**os.environ, "RUST_LOG": "off"})
            deadline = time.monotonic() + sc.duration_s + 120
            while time.monotonic() < deadline:
                monitor.poll()
                gt.poll()
                while (got := tracks.try_recv()) is not None:
                    run.consumer_tracks += bool(got.msg.tracks and got.msg.appearance_available)
                if sim.poll() is not None and gt.idle_for(1.5):
                    break  # the scenario is over and the pipeline has drained
                time.sleep(0.2)  # not a wait: the pace of this loop that reads the pipeline while it runs
            monitor.poll()
            gt.poll()
            assert sim.wait(30) == 0, (workdir / "simulate.log").read_text()[-3000:]
    finally:
        if sim is not None and sim.poll() is None:
            _stop(sim, 10)
        run.launch_status = _stop(launch)
        run.log = log_path.read_text()[-3000:]
    run.report, _ = score(gt, monitor, sc.name)
    return run
