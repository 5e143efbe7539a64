"""Shared fixtures: a real ``perception router`` subprocess, Zenoh client transports, data paths."""

from __future__ import annotations

import os
from pathlib import Path
from typing import Callable, Iterator

import pytest

from common.transport.memory import MemoryBus
from common.transport.router_process import RouterProcess
from common.transport.zenoh_config import ZenohOptions
from common.transport.zenoh import ZenohTransport, open_transport

ROOT = Path(__file__).resolve().parents[1]
SHARED_DATA = Path(os.environ.get("PERCEPTION_SHARED_DATA", ROOT.parent / "shared" / "data"))

# Zenoh logs to stdout; keep test output to errors unless asked otherwise.
os.environ.setdefault("RUST_LOG", "error")


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
