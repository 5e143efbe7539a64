"""``perception launch`` with real child processes: restarts, clean stop, prefixes, errors."""

from __future__ import annotations

import io
import os
import signal
import subprocess
import threading
import time
from collections.abc import Iterator
from pathlib import Path

import pytest

from common.transport.router_process import RouterProcess, free_port
from tests.helpers.launcher import CHILD, PY, ROOT, TIMEOUT, Launch
from tests.helpers.wait import wait_until
from tools.launcher.supervisor import FailedChild, ProcessSpec, Supervisor


@pytest.fixture
def launches() -> Iterator[list[Launch]]:
    started: list[Launch] = []
    yield started
    for launch in started:
        launch.kill()


def _alive(pid: int) -> bool:
    """True while ``pid`` exists and is not a zombie waiting for its parent."""
    try:
        with open(f"/proc/{pid}/stat") as f:
            return f.read().rsplit(")", 1)[1].split()[0] != "Z"
    except FileNotFoundError:
        return False


def _wait_gone(pids: list[int], timeout: float = 20.0) -> list[int]:
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        left = [p for p in pids if _alive(p)]
        if not left:
            return []
        time.sleep(0.05)  # the poll interval of a deadline poll that returns the pids left, not a wait
    return [p for p in pids if _alive(p)]


@pytest.mark.skipif(not Path("/proc").is_dir(), reason="checks process liveness through /proc")
@pytest.mark.parametrize("sig", [signal.SIGINT, signal.SIGTERM])
def test_crash_restarts_then_signal_stops_everything(tmp_path: Path, launches: list[Launch], sig: signal.Signals) -> None:
    pidfile = tmp_path / "pids"
    f = tmp_path / "launch.yaml"
    f.write_text(f"""
services:
  - name: crasher
    exec: ["${{PY}}", "${{CHILD}}", crash, "3"]
    backoff: {{initial_s: 0.05, max_s: 0.2}}
  - name: family
    exec: ["${{PY}}", "${{CHILD}}", family, "{pidfile}"]
  - name: stubborn
    exec: ["${{PY}}", "${{CHILD}}", stubborn, "{pidfile}"]
    stop_timeout_s: 1
""")
    launch = Launch(f)
    launches.append(launch)
    launch.wait_for(lambda ls: any("family ready" in line for line in ls) and any("stubborn ready" in line for line in ls),
                    "the long-running children")
    launch.wait_for(lambda ls: sum("restart #3 in" in line for line in ls) >= 1, "three restarts of the crashing child")
    # Prefixed, aligned to the longest name ("stubborn"): '[crasher]  boom'.
    assert launch.count(r"^\[crasher\]  boom$") >= 3
    assert launch.count(r"^\[family\]   family ready$") == 1
    assert launch.count(r"crasher exited \(exit status 3\).*restart #2 in") == 1
    pids = [int(p) for p in pidfile.read_text().split()]
    assert len(pids) == 3 and all(_alive(p) for p in pids)

    launch.proc.send_signal(sig)
    assert launch.finish() == 0, launch.output()
    assert _wait_gone(pids) == [], f"left behind: {pids}\n{launch.output()}"
    out = launch.output()
    assert "stubborn did not stop after SIGTERM; sending SIGKILL" in out
    assert "all processes stopped" in out


def test_bad_launch_file_names_the_field_and_starts_nothing(tmp_path: Path) -> None:
    marker = tmp_path / "started"
    f = tmp_path / "bad.yaml"
    f.write_text(f"""
services:
  - name: first
    exec: ["{PY}", "{CHILD}", touch, "{marker}"]
  - name: tracker
    command: tracker
    restart: sometimes
""")
    res = subprocess.run([PY, "-m", "perception", "launch", str(f)], capture_output=True, text=True, timeout=TIMEOUT, cwd=ROOT)
    assert res.returncode == 2
    assert "services[1] (tracker).restart" in res.stderr and "'sometimes'" in res.stderr, res.stderr
    assert "Traceback" not in res.stderr
    assert not marker.exists()


@pytest.mark.parametrize(("body", "expected"), [
    ("services:\n  - name: x\n    exec: [\"${NOPE_NOT_SET}\"]\n", "environment variable NOPE_NOT_SET is not set"),
    ("services:\n  - name: x\n    command: no-such-command\n",
     "services[0] (x).command: 'no-such-command' is not a perception command"),
    ("services:\n  - name: x\n    exec: [ls]\n    colour: red\n", "services[0] (x).colour: Extra inputs are not permitted"),
    ("services:\n  - name: x\n    exec: [ls]\n    command: tracker\n", "give exactly one of 'command'"),
    ("router:\n  listen: [localhost:7447]\n", "router.listen: endpoint 'localhost:7447' is not of the form PROTO/ADDRESS"),
])
def test_launch_file_errors_are_clear(tmp_path: Path, body: str, expected: str) -> None:
    f = tmp_path / "bad.yaml"
    f.write_text(body)
    res = subprocess.run([PY, "-m", "perception", "launch", str(f)], capture_output=True, text=True, timeout=TIMEOUT, cwd=ROOT)
    assert res.returncode == 2 and expected in res.stderr, res.stderr
    assert "Traceback" not in res.stderr


def test_substitution_and_one_shot_children(tmp_path: Path, launches: list[Launch]) -> None:
    f = tmp_path / "echo.yaml"
    f.write_text("""
env:
  LAUNCH_TEST: ${LAUNCH_TEST_VALUE:-from-default}
services:
  - name: hello
    exec: ["${PY}", "${CHILD}", echo, "${GREETING:-hello}", "${WHO-nobody}"]
    restart: never
  - name: bye
    exec: ["${PY}", "${CHILD}", crash, "0"]
    restart: on-failure
""")
    launch = Launch(f, {"WHO": "robot"})
    launches.append(launch)
    assert launch.finish() == 0, launch.output()  # every child finished with status 0
    assert launch.count(r"^\[hello\] hello robot from-default$") == 1, launch.output()
    assert launch.count(r"^\[hello\] to stderr$") == 1
    assert launch.count(r"^\[bye\]   boom$") == 1

    launch = Launch(f, {"GREETING": "hi", "LAUNCH_TEST_VALUE": "set"})
    launches.append(launch)
    assert launch.finish() == 0
    assert launch.count(r"^\[hello\] hi nobody set$") == 1, launch.output()


def test_failed_one_shot_child_gives_exit_status_1(tmp_path: Path) -> None:
    f = tmp_path / "fail.yaml"
    f.write_text('services:\n  - {name: once, exec: ["${PY}", "${CHILD}", crash, "4"], restart: never}\n')
    launch = Launch(f)
    try:
        assert launch.finish() == 1
    finally:
        launch.kill()
    assert "once exited (exit status 4)" in launch.output() and "not restarted (restart: never)" in launch.output()


@pytest.mark.zenoh
def test_router_starts_first_and_a_child_connects_to_it(tmp_path: Path, launches: list[Launch]) -> None:
    f = tmp_path / "router.yaml"
    f.write_text("""
robot: ${ROBOT:-launchtest}
router:
  listen: ["tcp/127.0.0.1:${ROUTER_PORT}"]
services:
  - name: status
    command: status
    args: [--connect-timeout, 20]
    restart: never
""")
    port = free_port()
    launch = Launch(f, {"ROUTER_PORT": str(port)})
    launches.append(launch)
    launch.wait_for(lambda ls: any("status exited" in line for line in ls), "the status child to finish")
    out = launch.output()
    assert f"router is ready on 127.0.0.1:{port}" in out
    assert "status exited (exit status 0)" in out, out
    assert launch.count(r"^\[status\] no live services$") == 1, out
    assert out.index("router is ready") < out.index("started status")
    launch.proc.send_signal(signal.SIGINT)
    assert launch.finish() == 0, launch.output()
    assert "router stopped (exit status 0)" in launch.output()


def test_router_that_cannot_start_stops_the_launch_before_the_services(tmp_path: Path) -> None:
    marker = tmp_path / "started"
    f = tmp_path / "router.yaml"
    # 192.0.2.1 (TEST-NET-1) is no address of this machine: the router cannot listen there.
    f.write_text(f'router:\n  listen: ["tcp/192.0.2.1:7447"]\n'
                 f'services:\n  - {{name: x, exec: ["{PY}", "{CHILD}", touch, "{marker}"]}}\n')
    res = subprocess.run([PY, "-m", "perception", "launch", str(f)], capture_output=True, text=True, timeout=TIMEOUT, cwd=ROOT)
    assert res.returncode == 1, res.stdout + res.stderr
    assert "router exited during start-up" in res.stderr and "not starting the others" in res.stderr
    assert "[router] perception: error: could not open a Zenoh session" in res.stdout
    assert not marker.exists()


def test_supervisor_api_restarts_and_stops_on_request() -> None:
    out = io.BytesIO()
    # the sleeper's time.sleep is not a wait: it is a service that stays up until stopped
    specs = [ProcessSpec("sleeper", [PY, "-c", "import time; print('up', flush=True); time.sleep(3600)"], dict(os.environ)),
             ProcessSpec("crash", [PY, CHILD, "crash", "1"], dict(os.environ), backoff_initial_s=0.01, backoff_max_s=0.05)]
    sup = Supervisor(specs, out, handle_signals=False)
    result: list[int] = []
    thread = threading.Thread(target=lambda: result.append(sup.run()))
    thread.start()
    try:
        wait_until(lambda: sup.restarts("crash") >= 2 and b"[sleeper] up\n" in out.getvalue(), TIMEOUT, interval=0.05,
                   what=lambda: f"two restarts and the sleeper up:\n{out.getvalue().decode(errors='replace')}")
    finally:
        sup.request_stop()
        thread.join(TIMEOUT)
    assert result == [0]
    assert out.getvalue().count(b"[crash]   boom\n") >= 2


def test_before_last_runs_after_the_services_stop_and_before_the_router() -> None:
    """The launcher closes its failure report's Zenoh session there, while the router still runs."""
    out = io.BytesIO()
    up = "import time; print('up', flush=True); time.sleep(3600)"
    specs = [ProcessSpec("router", [PY, "-c", up], dict(os.environ), stop_last=True),
             ProcessSpec("service", [PY, "-c", up], dict(os.environ))]
    seen: list[tuple[int | None, int | None]] = []
    sup: Supervisor = Supervisor(specs, out, handle_signals=False,
                                 before_last=lambda: seen.append((sup.pid("service"), sup.pid("router"))))
    thread = threading.Thread(target=sup.run)
    thread.start()
    try:
        wait_until(lambda: out.getvalue().count(b" up\n") == 2, TIMEOUT, interval=0.05, what="both children up")
    finally:
        sup.request_stop()
        thread.join(TIMEOUT)
    assert len(seen) == 1 and seen[0][0] is None and seen[0][1] is not None  # the service gone, the router not


@pytest.mark.zenoh
def test_router_port_already_taken_is_reported_not_mistaken_for_ready(router: RouterProcess, tmp_path: Path) -> None:
    f = tmp_path / "twice.yaml"
    f.write_text(f'router:\n  listen: ["{router.endpoint}"]\nservices:\n  - {{name: x, exec: ["{PY}", "{CHILD}", crash, "0"]}}\n')
    res = subprocess.run([PY, "-m", "perception", "launch", str(f)], capture_output=True, text=True, timeout=TIMEOUT, cwd=ROOT)
    assert res.returncode == 1
    assert f"something already accepts connections on 127.0.0.1:{router.port} (another router?)" in res.stderr
    assert "started" not in res.stderr and "boom" not in res.stdout


def test_exit_status_2_is_not_restarted_and_said_once(caplog: pytest.LogCaptureFixture) -> None:
    out = io.BytesIO()
    failed: list[FailedChild] = []
    # the sleeper's time.sleep is not a wait: it is a service that stays up until stopped
    specs = [ProcessSpec("sleeper", [PY, "-c", "import time; print('up', flush=True); time.sleep(3600)"], dict(os.environ)),
             ProcessSpec("embedder", [PY, CHILD, "config-error"], dict(os.environ), restart="always",
                         backoff_initial_s=0.01, backoff_max_s=0.05)]
    sup = Supervisor(specs, out, handle_signals=False, on_failed=failed.append)
    result: list[int] = []
    thread = threading.Thread(target=lambda: result.append(sup.run()))
    with caplog.at_level("INFO", logger="tools.launcher.supervisor"):
        thread.start()
        try:
            wait_until(lambda: failed and b"[sleeper]  up" in out.getvalue(), TIMEOUT, interval=0.05,
                       what=lambda: f"the embedder to fail, the sleeper up:\n{out.getvalue().decode(errors='replace')}")
            time.sleep(0.3)  # not a wait: time for a restart that must not come (it would be due after 0.01 s)
        finally:
            sup.request_stop()
            thread.join(TIMEOUT)
    assert result == [0]
    assert sup.restarts("embedder") == 0 and out.getvalue().count(b"[embedder] loading settings") == 1
    assert len(failed) == 1 and failed[0].name == "embedder" and failed[0].returncode == 2 and failed[0].pid > 0
    assert failed[0].error == "perception: error: model file /nowhere/reid.onnx not found (fix it in the config)"
    said = [r.getMessage() for r in caplog.records if "NOT restarted" in r.getMessage()]
    assert len(said) == 1 and "embedder stopped" in said[0] and "/nowhere/reid.onnx" in said[0], said
