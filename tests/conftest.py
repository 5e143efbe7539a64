"""Shared fixtures: a real ``perception router`` subprocess, Zenoh client transports, data paths."""

from __future__ import annotations

import os
import shutil
import tempfile
from pathlib import Path
from typing import Any, Callable, Iterator

import pytest

from common.transport.memory import MemoryBus
from common.transport.router_process import RouterProcess
from common.transport.zenoh_config import ZenohOptions
from common.transport.zenoh import ZenohTransport, open_transport

ROOT = Path(__file__).resolve().parents[1]
SHARED_DATA = Path(os.environ.get("PERCEPTION_SHARED_DATA", ROOT.parent / "shared" / "data"))

# Zenoh logs to stdout; keep test output to errors unless asked otherwise.
os.environ.setdefault("RUST_LOG", "error")

#: The user's real state directory, read before the override below: the tracker's ID memory
#: (services/tracker/config.py default_memory_path) lives there, and no test may write it.
REAL_STATE_HOME = Path(os.environ.get("XDG_STATE_HOME") or Path.home() / ".local" / "state")
#: The session's own directories, made in the real temporary directory and removed at the end:
#: ``state/`` is XDG_STATE_HOME and ``tmp/`` is TMPDIR, for this process and every child it starts
#: (set at import, before any test runs: os.environ is what children inherit). Other sessions on
#: the machine share /tmp; this one's leftovers are told apart in its own ``tmp/``.
TEST_ROOT = Path(tempfile.mkdtemp(prefix="perception-test-session-"))
TEST_STATE_HOME = TEST_ROOT / "state"
TEST_TMP = TEST_ROOT / "tmp"
TEST_STATE_HOME.mkdir()
TEST_TMP.mkdir()
os.environ.setdefault("PYTEST_DEBUG_TEMPROOT", tempfile.gettempdir())  # pytest's tmp_path stays where it was
os.environ["XDG_STATE_HOME"] = str(TEST_STATE_HOME)
os.environ["TMPDIR"] = str(TEST_TMP)
tempfile.tempdir = str(TEST_TMP)
#: Temporary directories our code names ``perception-*`` (the demo's logs, the launcher's
#: configs, the browser's profile, ...); the session fails if a test leaves one behind.
TEMP_PREFIX = "perception-"
_BEFORE = pytest.StashKey[tuple[set[str], set[str]]]()
_LEFT = pytest.StashKey[list[str]]()


def _real_state_entries() -> set[str]:
    """What our code may write under the real state directory (``people-perception/...``), each
    entry with its modification time, so that a rewritten file counts as well as a new one."""
    ours = REAL_STATE_HOME / "people-perception"
    paths = [ours, *ours.rglob("*")] if ours.exists() else []
    return {f"{p.relative_to(REAL_STATE_HOME)} (modified {p.stat().st_mtime_ns})" for p in paths}


def _our_temp_entries() -> set[str]:
    return {p.name for p in TEST_TMP.glob(TEMP_PREFIX + "*")}


def pytest_sessionstart(session: pytest.Session) -> None:
    session.config.stash[_BEFORE] = (_real_state_entries(), _our_temp_entries())


def pytest_sessionfinish(session: pytest.Session, exitstatus: int) -> None:
    """Fail the session if it wrote the real state directory or left ``perception-*`` temp entries."""
    before = session.config.stash.get(_BEFORE, None)
    if before is None or session.config.option.collectonly:
        shutil.rmtree(TEST_ROOT, ignore_errors=True)
        return
    state_before, temp_before = before
    problems = []
    if new := sorted(_real_state_entries() - state_before):
        problems.append(f"written under the real state directory {REAL_STATE_HOME}: {', '.join(new)}")
    if new := sorted(_our_temp_entries() - temp_before):
        problems.append(f"left in the temporary directory: {', '.join(new)}")
    shutil.rmtree(TEST_ROOT, ignore_errors=True)
    session.config.stash[_LEFT] = problems
    if problems and session.exitstatus == pytest.ExitCode.OK:
        session.exitstatus = pytest.ExitCode.TESTS_FAILED


def pytest_terminal_summary(terminalreporter: pytest.TerminalReporter) -> None:
    for line in terminalreporter.config.stash.get(_LEFT, []):
        terminalreporter.write_line(f"tests left something behind: {line}", red=True)


@pytest.fixture
def shared_data() -> Path:
    """``../shared/data``; tests that need it are skipped when it is absent."""
    if not SHARED_DATA.is_dir():
        pytest.skip(f"shared test data not found at {SHARED_DATA} (set PERCEPTION_SHARED_DATA)")
    return SHARED_DATA


@pytest.fixture
def router(tmp_path: Path) -> Iterator[RouterProcess]:
    """A real router process on a free loopback port, multicast scouting off.

    Ready (accepting TCP connections) when the test starts; stopped at teardown.
    ``router.kill()`` / ``router.start()`` restart it on the same port.
    """
    proc = RouterProcess(log_path=str(tmp_path / "router.log"))
    proc.start()
    try:
        yield proc
    finally:
        proc.stop()


@pytest.fixture
def zenoh_client(router: RouterProcess) -> Iterator[Callable[[], ZenohTransport]]:
    """A factory of client transports connected to the ``router`` fixture; all closed at teardown."""
    opened: list[ZenohTransport] = []

    def make() -> ZenohTransport:
        t = open_transport(ZenohOptions(mode="client", connect=[router.endpoint], connect_timeout_s=5.0))
        opened.append(t)
        return t

    try:
        yield make
    finally:
        for t in opened:
            t.close()


@pytest.fixture
def memory_bus() -> MemoryBus:
    return MemoryBus()


@pytest.fixture
def sdk_session(router: RouterProcess, monkeypatch: pytest.MonkeyPatch) -> Iterator[tuple[Any, str, int]]:
    """zenoh-ros2-sdk's shared session, on the test's router, loopback only, no scouting
    (tests/helpers/ros2_sdk.py has the rest of the far side)."""
    sdk = pytest.importorskip("zenoh_ros2_sdk", reason="zenoh-ros2-sdk (the test extra) is not installed")
    monkeypatch.setenv("ZENOH_CONFIG_OVERRIDE", 'scouting/multicast/enabled=false;listen/endpoints=["tcp/127.0.0.1:0"]')
    host, port = router.endpoint.removeprefix("tcp/").rsplit(":", 1)
    sdk.ZenohSession._instance = None
    session = sdk.ZenohSession.get_instance(host, int(port))
    try:
        yield session, host, int(port)
    finally:
        session.session.close()
        sdk.ZenohSession._instance = None
