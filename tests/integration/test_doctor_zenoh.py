"""perception doctor against real faults: a real router on loopback, the simulated robot and
the four real nodes in one process (tests/fixtures/doctor_system.py) with one setup fault
each, and `perception doctor` as its own process. The right line fails with the right hint;
a healthy pipeline passes every check."""

from __future__ import annotations

import json
import os
import subprocess
import sys
import uuid
from collections.abc import Iterator
from pathlib import Path

import pytest

from common.transport.router_process import RouterProcess
from tests.helpers.wait import wait_until

pytestmark = [pytest.mark.zenoh]
PY = sys.executable
ROOT = Path(__file__).resolve().parents[2]
WATCH_S = "3"
TIMEOUT = 90.0

#: fault -> (the check that fails, in its figure, in its fix)
FAULTS = {
    "depth-float-mm": ("depth unit (head)", "millimetres stored as floats", "divide the depth by 1000"),
    "depth-half-size": ("depth registered (head)", "depth 160x120, colour 320x240", "register depth"),
    "zero-k": ("camera info (head)", "K is all zeros", "calibration"),
    "no-odom-edge": ("chain map ← camera", "missing odom → base_link", "publish odom → base_link"),
    "static-once": ("static transforms", "no tf_static in", "republish static transforms"),
    "old-stamps": ("frame stamps (head)", "stamped 5.0 s before they arrive", "synchronise the PCs' clocks"),
    "mount-high": ("people's height (camera)", "above the floor", "the camera's height in"),
    "mount-pitched": ("people's height (camera)", "the farther they are", "pitch"),
    "mount-upside-down": ("people's height (camera)", "the image's up", "rolled 180°"),
    "mount-pitched-floor": ("floor (detector)", "the depth shows no floor where the transforms put it", "pitch looks"),
    "embedder-stopped": ("embedder", "not running", "perception embedder"),
    "tracker-model": ("embedding model", "the tracker takes trinet", "set the tracker's embedding_model to colour"),
    "camera-mismatch": ("camera names", "tracker front", "set the tracker's camera to head"),
}


@pytest.fixture(scope="module")
def shared_router(tmp_path_factory: pytest.TempPathFactory) -> Iterator[RouterProcess]:
    """One router for every case (each case has its own robot name, so its own keys)."""
    proc = RouterProcess(log_path=str(tmp_path_factory.mktemp("doctor") / "router.log"))
    proc.start()
    try:
        yield proc
    finally:
        proc.stop()


def _system(router: RouterProcess, robot: str, fault: str, log: Path) -> subprocess.Popen[bytes]:
    env = {**os.environ, "RUST_LOG": "error"}
    return subprocess.Popen([PY, "-m", "tests.fixtures.doctor_system", router.endpoint, robot, fault],
                            stdout=log.open("wb"), stderr=subprocess.STDOUT, env=env, cwd=ROOT)


def _wait_ready(proc: subprocess.Popen[bytes], log: Path) -> None:
    def ready() -> bool:
        if b"READY" in log.read_bytes():
            return True
        if proc.poll() is not None:
            pytest.fail(f"the system did not come up:\n{log.read_text(errors='replace')[-3000:]}")
        return False

    wait_until(ready, TIMEOUT, interval=0.1,
               what=lambda: f"the system to come up:\n{log.read_text(errors='replace')[-3000:]}")


def _doctor(router: RouterProcess, robot: str) -> tuple[int, dict[str, dict[str, str]], str]:
    res = subprocess.run([PY, "-m", "perception", "-q", "doctor", "--duration", WATCH_S, "--json", "--robot", robot,
                          "--connect", router.endpoint], capture_output=True, text=True, timeout=TIMEOUT, cwd=ROOT,
                         env={**os.environ, "RUST_LOG": "error"}, check=False)
    report = json.loads(res.stdout)
    assert report["exit_code"] == res.returncode
    return res.returncode, {c["name"]: c for c in report["checks"]}, res.stdout


@pytest.mark.parametrize("fault", ["healthy", *FAULTS])
def test_doctor_finds_each_fault(shared_router: RouterProcess, tmp_path: Path, fault: str) -> None:
    robot = f"doc{uuid.uuid4().hex[:8]}"
    log = tmp_path / "system.log"
    system = _system(shared_router, robot, fault, log)
    try:
        _wait_ready(system, log)
        code, checks, out = _doctor(shared_router, robot)
    finally:
        system.terminate()
        system.wait(30)
    if fault == "healthy":
        bad = [c for c in checks.values() if c["status"] != "ok"]
        assert code == 0 and not bad, f"{bad}\n{log.read_text(errors='replace')[-2000:]}"
        return
    name, figure, fix = FAULTS[fault]
    check = checks[name]
    assert code == 2, out
    assert check["status"] == "fail" and figure in check["figure"] and fix in check["fix"], out
