"""The two-PC deployment on one machine: the routers of deploy/hri-pc.yaml and nav-pc.yaml connect."""

from __future__ import annotations

import signal
import time
from collections.abc import Iterator
from pathlib import Path

import pytest

from common.messages.keys import RELIABLE, Keys
from common.transport.router_process import free_port
from common.messages.samples import example_messages
from common.messages.schemas import Tracks
from common.transport.zenoh_config import ZenohOptions
from common.transport.zenoh import open_transport
from tests.helpers.launcher import TIMEOUT, Launch

DEPLOY = Path(__file__).resolve().parents[2] / "deploy"


@pytest.fixture
def two_pc_routers() -> Iterator[tuple[int, int]]:
    """Both PCs' routers from their launch files, on loopback ports standing in for the LAN."""
    hri_port, nav_port = free_port(), free_port()
    env = {"HRI_PC": "127.0.0.1", "NAV_PC": "127.0.0.1", "HRI_PORT": str(hri_port), "NAV_PORT": str(nav_port),
           "ROBOT": "deploytest"}
    launches = [Launch(DEPLOY / "hri-pc.yaml", env, "--only", "router"),
                Launch(DEPLOY / "nav-pc.yaml", env, "--only", "router")]
    try:
        for launch in launches:
            launch.wait_for(lambda ls: any("router is ready" in line for line in ls), "the router")
        yield hri_port, nav_port
        for launch in launches:
            launch.proc.send_signal(signal.SIGINT)
        for launch in launches:
            assert launch.finish() == 0, launch.output()
    finally:
        for launch in launches:
            launch.kill()


@pytest.mark.zenoh
def test_hri_and_nav_routers_connect_to_each_other(two_pc_routers: tuple[int, int]) -> None:
    hri_port, nav_port = two_pc_routers
    keys = Keys(robot="deploytest")
    tracks = next(m for m in example_messages() if isinstance(m, Tracks))

    def client(port: int):  # noqa: ANN202
        return open_transport(ZenohOptions(mode="client", connect=[f"tcp/127.0.0.1:{port}"], connect_timeout_s=TIMEOUT))

    with client(nav_port) as nav, client(hri_port) as hri:
        sub = nav.subscribe(keys.tracks(), Tracks, RELIABLE)
        pub = hri.publisher(keys.tracks(), Tracks, RELIABLE)
        deadline = time.monotonic() + TIMEOUT
        got = None
        while got is None and time.monotonic() < deadline:
            pub.put(tracks)  # re-sent until the routers have exchanged the subscription
            got = sub.recv(timeout=0.5)
        assert got is not None, "no message crossed from the HRI PC's router to the navigation PC's"
        assert got.msg == tracks
