"""The whole system as separate processes over real routers on loopback."""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time
import uuid
from pathlib import Path
from typing import Iterator

import pytest

from common.messages.keys import RELIABLE, Keys
from common.transport.router_process import free_port, wait_for_port
from common.messages.schemas import ServiceStatus, Tracks
from common.transport.zenoh_config import ZenohOptions
from common.transport.zenoh import ZenohTransport, open_transport

pytestmark = [pytest.mark.zenoh, pytest.mark.slow]
PY = sys.executable
#: MOTA of `perception demo --scenario still --duration 20` measured at 0.68-0.72 on the
#: 2-core CI machine; the floor leaves room for scheduling noise.
MOTA_FLOOR = 0.55


def _processes_mentioning(text: str) -> list[int]:
    """PIDs of live processes whose command line contains ``text``."""
    found = []
    for entry in Path("/proc").iterdir():
        if not entry.name.isdigit() or int(entry.name) == os.getpid():
            continue
        try:
            cmdline = (entry / "cmdline").read_bytes().replace(b"\0", b" ").decode(errors="replace")
            state = (entry / "stat").read_text().rsplit(")", 1)[1].split()[0]
        except OSError:
            continue
        if text in cmdline and state != "Z":
            found.append(int(entry.name))
    return found


def _wait_gone(text: str, timeout: float = 15.0) -> list[int]:
    deadline = time.monotonic() + timeout
    while (left := _processes_mentioning(text)) and time.monotonic() < deadline:
        time.sleep(0.1)  # the poll interval of a deadline poll that returns the processes left, not a wait
    return left


def test_demo_runs_the_pipeline_and_scores_it(tmp_path: Path) -> None:
    proc = subprocess.Popen([PY, "-m", "perception", "demo", "--scenario", "still", "--duration", "20", "--json", "--no-view",
                             "--log-dir", str(tmp_path)],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    out, err = proc.communicate(timeout=300)
    assert proc.returncode == 0, err[-3000:]
    result = json.loads(out[out.index("\n{") + 1 :])
    tracker = result["pipeline"]["tracker"]
    assert tracker["messages"] > 100
    assert result["overall"]["objects"] > 100
    assert result["overall"]["mota"] >= MOTA_FLOOR, result["overall"]
    cpu = result["cpu_percent"]
    assert set(cpu) == {"detector", "localizer", "embedder", "tracker"}, cpu
    assert all(v is not None and v > 0 for v in cpu.values()), cpu
    assert _wait_gone(f"--robot demo{proc.pid}") == []


@pytest.mark.slow
def test_demo_fuses_two_detectors_and_two_cameras_through_processes(tmp_path: Path) -> None:
    """TU Ilmenau's fusion through real processes and a router: depth and HOG (3 Hz, its own
    stream) on the head camera, a back camera with its own chain, one tracker on every stream."""
    proc = subprocess.Popen([PY, "-m", "perception", "demo", "--scenario", "handover", "--duration", "20",
                             "--second-detector", "hog", "--back-camera", "back", "--json", "--no-view",
                             "--log-dir", str(tmp_path)],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    out, err = proc.communicate(timeout=400)
    assert proc.returncode == 0, err[-3000:]
    result = json.loads(out[out.index("\n{") + 1 :])
    # the people behind the robot count (the back camera's view): handover has them there half the time
    assert result["overall"]["objects"] > 200, result["overall"]  # head camera alone: 156
    assert result["overall"]["mota"] >= 0.5, result["overall"]
    # one CPU figure per process, not per service name (three detectors here)
    assert {"detector", "detector-slow", "detector-back", "localizer-slow", "embedder-back"} <= set(result["cpu_percent"])
    assert _wait_gone(f"--robot demo{proc.pid}") == []


@pytest.mark.slow
def test_demo_with_the_base_laser_runs_the_laser_node_and_judges_everyone_around(tmp_path: Path) -> None:
    """--laser: the simulator's 2-D laser, the laser node as a process, the tracker fusing its people;
    the ground truth is everyone the camera or the laser could see."""
    proc = subprocess.Popen([PY, "-m", "perception", "demo", "--laser", "--duration", "12", "--json", "--no-view",
                             "--log-dir", str(tmp_path)],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    out, err = proc.communicate(timeout=300)
    assert proc.returncode == 0, err[-3000:]
    result = json.loads(out[out.index("\n{") + 1 :])
    assert result["cpu_percent"].get("laser") is not None, result["cpu_percent"]
    # the camera alone counts about 0.6 of these 12 s (the laser sees people out of its view)
    assert result["overall"]["objects"] > 300, result["overall"]
    assert result["overall"]["mota"] >= 0.6, result["overall"]
    assert _wait_gone(f"--robot demo{proc.pid}") == []


def _write(path: Path, text: str) -> Path:
    path.write_text(text)
    return path


@pytest.fixture
def launched(tmp_path: Path) -> Iterator[list[subprocess.Popen[bytes]]]:
    """`perception launch` processes started by a test; SIGINT and reaped at teardown."""
    procs: list[subprocess.Popen[bytes]] = []
    yield procs
    for p in procs:
        if p.poll() is None:
            p.send_signal(signal.SIGINT)
    for p in procs:
        try:
            p.wait(30)
        except subprocess.TimeoutExpired:
            p.kill()


def _launch(file: Path, log: Path) -> subprocess.Popen[bytes]:
    return subprocess.Popen([PY, "-m", "perception", "launch", str(file)], stdout=log.open("wb"), stderr=subprocess.STDOUT,
                            env={**os.environ, "RUST_LOG": "error"})


def _client(port: int) -> ZenohTransport:
    return open_transport(ZenohOptions(mode="client", connect=[f"tcp/127.0.0.1:{port}"], connect_timeout_s=30))


def _wait_tracks(sub, predicate, timeout: float) -> Tracks | None:  # type: ignore[no-untyped-def]
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        got = sub.recv(1.0)
        if got is not None and predicate(got.msg):
            return got.msg
    return None


SIM_ARGS = "[--scenario, still, --duration, '120', --width, '320', --height, '240', --fps, '8']"


def test_two_routers_one_per_pc(tmp_path: Path, launched: list[subprocess.Popen[bytes]]) -> None:
    robot = f"it{uuid.uuid4().hex[:8]}"
    hri, nav = free_port(), free_port()
    hri_file = _write(tmp_path / "hri.yaml", f"""
robot: {robot}
router: {{listen: ["tcp/127.0.0.1:{hri}"], connect: ["tcp/127.0.0.1:{nav}"]}}
services:
  - {{name: detector, command: detector, args: [--backend, depth]}}
  - {{name: embedder, command: embedder}}
  - {{name: simulator, command: simulate, args: {SIM_ARGS}, restart: never}}
""")
    nav_file = _write(tmp_path / "nav.yaml", f"""
robot: {robot}
router: {{listen: ["tcp/127.0.0.1:{nav}"], connect: ["tcp/127.0.0.1:{hri}"]}}
services:
  - {{name: localizer, command: localizer}}
  - {{name: tracker, command: tracker, args: [--no-memory]}}
""")
    launched.append(_launch(nav_file, tmp_path / "nav.log"))
    assert wait_for_port("127.0.0.1", nav, 30)
    launched.append(_launch(hri_file, tmp_path / "hri.log"))
    with _client(nav) as t:  # a navigation-side consumer, attached to the nav PC's router only
        sub = t.subscribe(Keys(robot=robot).tracks(), Tracks, RELIABLE)
        got = _wait_tracks(sub, lambda m: len(m.tracks) > 0, 120)
        assert got is not None, (tmp_path / "hri.log").read_text()[-2000:] + (tmp_path / "nav.log").read_text()[-2000:]
        assert got.appearance_available
    for p in launched:
        p.send_signal(signal.SIGINT)
        assert p.wait(60) == 0
    assert _wait_gone(f"--robot {robot}") == []


def test_embedder_killed_mid_run(tmp_path: Path, launched: list[subprocess.Popen[bytes]]) -> None:
    robot = f"it{uuid.uuid4().hex[:8]}"
    port = free_port()
    keys = Keys(robot=robot)
    launch_file = _write(tmp_path / "all.yaml", f"""
robot: {robot}
router: {{listen: ["tcp/127.0.0.1:{port}"]}}
services:
  - {{name: detector, command: detector, args: [--backend, depth], restart: always}}
  - {{name: localizer, command: localizer, restart: always}}
  - {{name: embedder, command: embedder, restart: always, backoff: {{initial_s: 1.0, max_s: 2.0}}}}
  - {{name: tracker, command: tracker, args: [--no-memory], restart: always}}
  - {{name: simulator, command: simulate, args: {SIM_ARGS}, restart: never}}
""")
    launcher = _launch(launch_file, tmp_path / "launch.log")
    launched.append(launcher)
    assert wait_for_port("127.0.0.1", port, 30)
    with _client(port) as t:
        sub = t.subscribe(keys.tracks(), Tracks, RELIABLE)
        log = lambda: (tmp_path / "launch.log").read_text()[-3000:]  # noqa: E731
        assert _wait_tracks(sub, lambda m: m.appearance_available and len(m.tracks) > 0, 120) is not None, log()
        replies = [m for _, m in t.query(keys.status("embedder"), timeout=5) if isinstance(m, ServiceStatus)]
        assert len(replies) == 1, log()
        os.kill(replies[0].pid, signal.SIGKILL)
        # The tracker goes on without embeddings...
        degraded = _wait_tracks(sub, lambda m: not m.appearance_available, 30)
        assert degraded is not None, log()
        assert all(not tr.appearance_available for tr in degraded.tracks)
        # ...the launcher restarts the embedder, and appearance association resumes.
        resumed = _wait_tracks(sub, lambda m: m.appearance_available and m.header.stamp_ns > degraded.header.stamp_ns, 60)
        assert resumed is not None, log()
        new = [m for _, m in t.query(keys.status("embedder"), timeout=5) if isinstance(m, ServiceStatus)]
        assert len(new) == 1 and new[0].pid != replies[0].pid
    launcher.send_signal(signal.SIGINT)
    assert launcher.wait(60) == 0
    assert "embedder exited (killed by SIGKILL)" in (tmp_path / "launch.log").read_text()
    assert _wait_gone(f"--robot {robot}") == []
