"""A crash loop is a finding, not a retry: a launched embedder whose model file is missing
exits with status 2, is not restarted, and `perception status` and `perception doctor`
show it as failed with its error line and the tracker's position_only counters."""

from __future__ import annotations

import json
import os
import signal
import subprocess
import time
import uuid
from pathlib import Path

import pytest

from common.transport.router_process import free_port
from common.messages.schemas import Header, ServiceStatus
from tools.system.status_cli import render
from tests.helpers.launcher import PY, ROOT, TIMEOUT, Launch

MISSING = "/nonexistent/people-perception/reid.onnx"


def _status(**kw: object) -> ServiceStatus:
    return ServiceStatus(header=Header(stamp_ns=0), host="pc", **kw)  # type: ignore[arg-type]


def test_status_renders_a_failed_service_with_its_error_and_the_trackers_counters() -> None:
    rows = [("tracker", "pc-2", _status(name="tracker", instance="pc-2", extra={"position_only_frames": 41})),
            ("embedder", "pc-1", _status(name="embedder", instance="pc-1", state="failed", exit_status=2,
                                         error="perception: error: ONNX model file not found: /m.onnx"))]
    text = render(rows)
    assert "embedder     pc-1                     pc               FAILED (exit status 2, not restarted); tracker: " \
           "position_only_frames=41, position_only_timeout=0" in text
    assert "error: perception: error: ONNX model file not found: /m.onnx" in text


@pytest.mark.zenoh
def test_a_service_with_a_configuration_error_is_not_restarted_and_is_shown_failed(tmp_path: Path) -> None:
    robot = f"fail{uuid.uuid4().hex[:8]}"
    port = free_port()
    f = tmp_path / "launch.yaml"
    f.write_text(f"""
robot: {robot}
router: {{listen: ["tcp/127.0.0.1:{port}"]}}
services:
  - name: embedder
    command: embedder
    restart: always
    backoff: {{initial_s: 0.1, max_s: 0.2}}
    config: {{backend: onnx, onnx: {{path: {MISSING}}}}}
  - {{name: tracker, command: tracker, args: [--no-memory], restart: always}}
""")
    launch = Launch(f)
    try:
        launch.wait_for(lambda ls: any("NOT restarted" in line for line in ls), "the embedder to stop")
        launch.wait_for(lambda ls: any("tracker started as" in line for line in ls), "the tracker")
        connect = ["--robot", robot, "--connect", f"tcp/127.0.0.1:{port}"]
        env = {**os.environ, "RUST_LOG": "error"}
        status = subprocess.run([PY, "-m", "perception", "-q", "status", *connect], capture_output=True, text=True,
                                timeout=TIMEOUT, cwd=ROOT, env=env, check=False)
        doctor = subprocess.run([PY, "-m", "perception", "-q", "doctor", "--duration", "1", "--json", *connect],
                                capture_output=True, text=True, timeout=TIMEOUT, cwd=ROOT, env=env, check=False)
        time.sleep(0.5)  # not a wait: time for a restart that must not come (it would be due 0.1 s after the exit)
        out = launch.output()
        # said once, plainly: which node stopped and why; started once, never again
        said = [line for line in out.splitlines() if "NOT restarted" in line]
        assert len(said) == 1 and "embedder stopped" in said[0] and MISSING in said[0], out
        assert launch.count(r"started embedder") == 1 and "restart #1" not in out, out
        # perception status: failed, its error line, the tracker's position_only counters next to it
        lines = status.stdout.splitlines()
        row = next(line for line in lines if line.startswith("embedder"))
        assert "FAILED (exit status 2, not restarted); tracker: position_only_frames=0" in row, status.stdout
        assert any(line.strip().startswith("error: perception: error:") and MISSING in line for line in lines)
        assert any(line.startswith("tracker") and "FAILED" not in line for line in lines), status.stdout
        # perception doctor: the embedder's line fails with the same error
        assert doctor.returncode == 2, doctor.stdout + doctor.stderr
        check = next(c for c in json.loads(doctor.stdout)["checks"] if c["name"] == "embedder")
        assert check["status"] == "fail" and check["figure"].startswith("FAILED (exit status 2, not restarted)")
        assert MISSING in check["figure"] and "position_only_frames=0" in check["figure"]
        launch.proc.send_signal(signal.SIGINT)
        assert launch.finish() == 0, launch.output()
    finally:
        launch.kill()


@pytest.mark.zenoh
def test_the_failure_report_closes_its_session_before_close_returns_even_with_no_router() -> None:
    """The report's session opens in a thread; a thread still inside Zenoh at interpreter exit
    aborts the launcher ('FATAL: exception not rethrown'), so close() waits for it, and the open
    is bounded so that it can."""
    from common.messages.keys import Keys
    from common.transport.zenoh_config import ZenohOptions
    from tools.launcher.report import REPORT_CONNECT_S, FailureReport
    from tools.launcher.supervisor import FailedChild

    options = ZenohOptions(mode="client", connect=[f"tcp/127.0.0.1:{free_port()}"], connect_timeout_s=-1)
    report = FailureReport(Keys(robot="noreport"), options, {})
    assert report.options.connect_timeout_s == REPORT_CONNECT_S
    report(FailedChild(name="x", pid=1, returncode=2, error="bad", run_s=0.1))
    report.close()
    assert report._thread is not None and not report._thread.is_alive()
    assert report.reported == []  # no router: nothing served, and nothing left running
