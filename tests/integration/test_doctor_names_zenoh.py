"""perception doctor names a robot-name mismatch: the nodes run as robot 'mbot', the doctor is
asked about the default robot, and each silent stream says where the traffic is."""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
from typing import Any

import pytest

from tests.helpers.wait import wait_until

pytestmark = pytest.mark.zenoh


def test_the_doctor_names_the_robot_the_nodes_run_as(router: Any, zenoh_client: Any) -> None:
    zen = ["--mode", "client", "--connect", router.endpoint, "--no-multicast-scouting"]
    env = {**os.environ, "RUST_LOG": "error"}
    node = subprocess.Popen([sys.executable, "-m", "perception", "tracker", "--robot", "mbot", "--no-memory", *zen],
                            stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True, env=env)
    try:
        t = zenoh_client()
        wait_until(lambda: node.poll() is not None or bool(t.alive("pp/mbot/perception/v1/alive/tracker/*")),
                   timeout=30, what="the tracker's liveliness")
        done = subprocess.run([sys.executable, "-m", "perception", "doctor", "--duration", "1", "--json", *zen],
                              capture_output=True, text=True, timeout=120, env=env)
        checks = {c["name"]: c for c in json.loads(done.stdout)["checks"]}
        assert "pp/mbot (tracker)" in checks["tracks"]["figure"] and "--robot mbot" in checks["tracks"]["fix"]
    finally:
        node.send_signal(signal.SIGINT)
        node.communicate(timeout=30)
