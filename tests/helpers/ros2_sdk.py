"""zenoh-ros2-sdk (PyPI), a third party's implementation of rmw_zenoh's protocol, as the far side of
the ros2 node's tests: its session on the test's router, ROS 2 publishers, and the ros2 node as a
process. Importing it skips a test module when the test extra is not installed."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
from typing import Any

import pytest

from common.messages.keys import Keys
from services.ros2.core.types import types_of
from tests.helpers.wait import wait_until

os.environ.setdefault("GIT_PYTHON_REFRESH", "quiet")
sdk = pytest.importorskip("zenoh_ros2_sdk", reason="zenoh-ros2-sdk (the test extra) is not installed")

__all__ = ["DOMAIN", "KEYS", "T", "fields", "ros2_node", "ros2_publisher", "sdk", "stop", "wait_alive"]

KEYS = Keys(robot="rosz")
T = types_of()
DOMAIN = 17


def ros2_node(router: Any, *extra: str) -> subprocess.Popen[str]:
    cmd = [sys.executable, "-m", "perception", "ros2", "--robot", KEYS.robot, "--domain-id", str(DOMAIN), "--mode",
           "client", "--connect", router.endpoint, "--no-multicast-scouting", *extra]
    return subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True,
                            env={**os.environ, "RUST_LOG": "error"})


def wait_alive(t: Any, node: subprocess.Popen[str], timeout: float = 30.0) -> None:
    def up() -> bool:
        assert node.poll() is None, node.communicate()[0]
        return bool(t.alive(KEYS.alive("ros2")))

    wait_until(up, timeout, what="perception ros2's liveliness")


def stop(node: subprocess.Popen[str]) -> str:
    node.send_signal(signal.SIGINT)
    out, _ = node.communicate(timeout=30)
    assert node.returncode == 0, out
    return out


def ros2_publisher(session: tuple[Any, str, int], topic: str, type_name: str) -> Any:
    _, host, port = session
    return sdk.ROS2Publisher(topic, type_name, msg_definition=T.definition(type_name), type_hash=T.hash(type_name),
                             domain_id=DOMAIN, router_ip=host, router_port=port, node_name="camera")


def fields(msg: Any) -> dict[str, Any]:
    return {f: getattr(msg, f) for f in msg.__dataclass_fields__}
