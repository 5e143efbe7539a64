"""Every long-running command starts and stops cleanly, again and again, two at a time: exit
status 0 on SIGINT, and no 'FATAL', 'Traceback' or 'exception not rethrown' in its output (a
Zenoh object left to the interpreter's finalization aborts a process that way)."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
from collections.abc import Callable, Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import cv2
import numpy as np
import pytest

from common.messages.keys import Keys
from common.transport.router_process import free_port
from tests.helpers.wait import wait_until

pytestmark = [pytest.mark.zenoh, pytest.mark.slow]

ROOT = Path(__file__).resolve().parents[2]
ROUNDS = 3
BAD = ("FATAL", "Traceback", "exception not rethrown")
UP_S = 60.0  # generous: two cold starts at once on a shared, slow machine
DOWN_S = 30.0


@dataclass
class Command:
    """How to start one command (``argv(endpoint, robot, workdir)``) and the service whose
    liveliness says it is up (None: the command says so in its output, ``ready``)."""

    name: str
    argv: Callable[[str, str, Path], list[str]]
    service: str | None = None
    ready: str = ""


def _zenoh(endpoint: str, robot: str) -> list[str]:
    return ["--robot", robot, "--mode", "client", "--connect", endpoint, "--no-multicast-scouting"]


def _node(command: str, *extra: str) -> Callable[[str, str, Path], list[str]]:
    return lambda endpoint, robot, _work: ["-m", "perception", command, *extra, *_zenoh(endpoint, robot)]


def _camera(endpoint: str, robot: str, work: Path) -> list[str]:
    folder = work / "frames"
    if not folder.is_dir():
        folder.mkdir()
        for k in range(3):
            cv2.imwrite(str(folder / f"{k:03d}.jpg"), np.full((48, 64, 3), 40 * k, np.uint8))
    return ["-m", "perception", "camera", str(folder), "--fps", "5", "--loop", *_zenoh(endpoint, robot)]


def _launch(endpoint: str, robot: str, work: Path) -> list[str]:
    f = work / "launch.yaml"
    f.write_text(f"robot: {robot}\nzenoh:\n  connect: [\"{endpoint}\"]\n"
                 f"services:\n  - name: tracker\n    command: tracker\n    args: [--memory, \"{work / 'launch-ids.npz'}\"]\n")
    return ["-m", "perception", "launch", str(f), "--color", "never"]


COMMANDS = [
    Command("router", lambda _e, _r, _w: ["-m", "perception", "router", "--listen", f"tcp/127.0.0.1:{free_port()}",
                                          "--no-multicast-scouting"], ready="router ready"),
    Command("detector", _node("detector", "--camera", "head"), "detector"),
    Command("localizer", _node("localizer"), "localizer"),
    Command("embedder", _node("embedder"), "embedder"),
    Command("tracker", lambda e, r, w: ["-m", "perception", "tracker", "--memory", str(w / f"{r}.npz"), *_zenoh(e, r)],
            "tracker"),
    Command("attention", _node("attention", "--target", "nearest"), "attention"),
    Command("view", _node("view", "--port", "0"), "viewer"),
    Command("ros2", _node("ros2", "--domain-id", "23"), "ros2"),
    Command("camera", _camera, "camera"),
    Command("launch", _launch, "tracker"),
]


class Running:
    """One command as a child process, its merged output in a file."""

    def __init__(self, command: Command, endpoint: str, robot: str, work: Path) -> None:
        self.command, self.robot = command, robot
        self.log = work / f"{robot}.log"
        with open(self.log, "wb") as out:
            self.proc = subprocess.Popen([sys.executable, *command.argv(endpoint, robot, work)], cwd=ROOT, stdout=out,
                                         stderr=subprocess.STDOUT, env={**os.environ, "RUST_LOG": "error"})

    def output(self) -> str:
        return self.log.read_text(errors="replace")

    def up(self, client: Any) -> bool:
        assert self.proc.poll() is None, f"{self.command.name} exited ({self.proc.returncode}):\n{self.output()}"
        if self.command.service is None:
            return self.command.ready in self.output()
        return bool(client.alive(Keys(robot=self.robot).alive(self.command.service), timeout=0.5))

    def stop(self) -> None:
        if self.proc.poll() is None:
            self.proc.kill()
            self.proc.wait()


@pytest.fixture
def running() -> Iterator[list[Running]]:
    started: list[Running] = []
    yield started
    for r in started:
        r.stop()


def test_every_command_starts_and_stops_cleanly_two_at_a_time(router: Any, zenoh_client: Any, tmp_path: Path,
                                                                running: list[Running]) -> None:
    client = zenoh_client()
    for k in range(ROUNDS):
        for i in range(0, len(COMMANDS), 2):
            pair = [Running(c, router.endpoint, f"ss{k}{c.name}", tmp_path) for c in COMMANDS[i:i + 2]]
            running.extend(pair)
            for r in pair:
                wait_until(lambda r=r: r.up(client), UP_S, interval=0.1, what=f"{r.command.name} (round {k + 1}) up")
            for r in pair:
                r.proc.send_signal(signal.SIGINT)
            for r in pair:
                code = r.proc.wait(DOWN_S)
                out = r.output()
                assert code == 0, f"{r.command.name} (round {k + 1}) exited with {code}:\n{out[-3000:]}"
                assert not [b for b in BAD if b in out], f"{r.command.name} (round {k + 1}):\n{out[-3000:]}"
