"""Real processes over a real ``perception router`` on loopback (multicast scouting off)."""

from __future__ import annotations

import json
import subprocess
import sys
import threading
import time
from pathlib import Path
from typing import Callable

import msgpack
import pytest

from common.messages.codec import decode_any
from common.messages.keys import RELIABLE, Keys
from common.transport.router_process import RouterProcess, free_port
from common.messages.samples import example_messages
from common.messages.schemas import Header, Tracks
from common.transport.zenoh import ZenohTransport

pytestmark = pytest.mark.zenoh
KEYS = Keys(robot="xproc")
PY = sys.executable


def _spawn(*args: str) -> subprocess.Popen[str]:
    return subprocess.Popen([PY, "-m", *args], stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)


def _wait_line(proc: subprocess.Popen[str], text: str) -> None:
    assert proc.stdout is not None
    line = proc.stdout.readline()
    assert text in line, f"expected {text!r}, got {line!r}; stderr: {proc.stderr.read() if proc.stderr else ''}"


def test_two_processes_exchange_every_message_type(router: RouterProcess, tmp_path: Path) -> None:
    out = tmp_path / "received.msgpack"
    sub = _spawn("tests.helpers.exchange", "sub", router.endpoint, str(out))
    try:
        _wait_line(sub, "READY")
        pub = _spawn("tests.helpers.exchange", "pub", router.endpoint)
        assert pub.wait(60) == 0, pub.stderr.read() if pub.stderr else ""
        assert sub.wait(60) == 0, sub.stderr.read() if sub.stderr else ""
    finally:
        sub.kill()
    received = [decode_any(b) for b in msgpack.unpackb(out.read_bytes(), raw=False)]
    assert received == example_messages()


def _tracks(seq: int) -> Tracks:
    return Tracks(header=Header(stamp_ns=time.time_ns(), frame_id="map", seq=seq, source="test"))


def test_pub_sub_resume_after_router_sigkill_and_restart(router: RouterProcess,
                                                         zenoh_client: Callable[[], ZenohTransport]) -> None:
    pub_t, sub_t = zenoh_client(), zenoh_client()
    sub = sub_t.subscribe(KEYS.tracks(), Tracks, RELIABLE)
    pub = pub_t.publisher(KEYS.tracks(), Tracks, RELIABLE)
    assert pub.wait_for_subscribers(10)
    stop = threading.Event()
    seq = [0]

    def publish() -> None:
        while not stop.is_set():
            seq[0] += 1
            pub.put(_tracks(seq[0]))
            stop.wait(0.02)

    thread = threading.Thread(target=publish, daemon=True)
    thread.start()
    try:
        assert sub.recv(10) is not None
        router.kill()
        last_seen = 0
        while (late := sub.recv(0.3)) is not None:  # what was already on its way before the kill
            last_seen = late.msg.header.seq
        router.start()
        restarted = time.monotonic()
        got = sub.recv(2.0)
        resumed_after = time.monotonic() - restarted
        assert got is not None, "no message within 2 s of the router coming back"
        assert got.msg.header.seq > last_seen + 1, "expected samples published during the outage to be lost, not replayed"
        assert resumed_after < 2.0
        assert pub.unmatched > 0, "puts during the outage should be counted as unmatched"
    finally:
        stop.set()
        thread.join(2)


def test_status_lists_live_services_and_forgets_killed_ones(router: RouterProcess) -> None:
    svc = _spawn("tests.helpers.exchange", "service", router.endpoint, "detector")
    try:
        _wait_line(svc, "READY")
        cmd = [PY, "-m", "perception", "status", "--connect", router.endpoint, "--robot", "xproc", "--json"]
        listed = json.loads(subprocess.run(cmd, capture_output=True, text=True, timeout=60, check=True).stdout)
        assert [e["service"] for e in listed] == ["detector"]
        assert listed[0]["status"]["pid"] == svc.pid
        svc.kill()
        svc.wait(10)
        deadline = time.monotonic() + 10
        while time.monotonic() < deadline:
            listed = json.loads(subprocess.run(cmd, capture_output=True, text=True, timeout=60, check=True).stdout)
            if not listed:
                break
        assert listed == []
    finally:
        svc.kill()


def test_router_stops_cleanly_on_sigterm() -> None:
    r = RouterProcess().start()
    assert r.proc is not None
    proc = r.proc
    proc.terminate()
    assert proc.wait(10) == 0


def test_router_reports_a_port_in_use(router: RouterProcess) -> None:
    res = subprocess.run([PY, "-m", "perception", "router", "--listen", router.endpoint], capture_output=True, text=True, timeout=60)
    assert res.returncode == 2
    assert "Address already in use" in res.stderr and "--listen" in res.stderr


def test_client_without_router_fails_with_advice() -> None:
    endpoint = f"tcp/127.0.0.1:{free_port()}"
    res = subprocess.run([PY, "-m", "perception", "status", "--connect", endpoint, "--connect-timeout", "0.5"],
                         capture_output=True, text=True, timeout=60)
    assert res.returncode == 2
    assert "no Zenoh router answered" in res.stderr and "perception router" in res.stderr
    assert "Traceback" not in res.stderr


def test_selfcheck_end_to_end() -> None:
    res = subprocess.run([PY, "-m", "perception", "-q", "selfcheck"], capture_output=True, text=True, timeout=120)
    assert res.returncode == 0, res.stdout + res.stderr
    assert f"all {len(example_messages())} message types went through the router and decoded equal" in res.stdout
