"""perception doctor live on a ROS 2 robot: a third party's ROS 2 publishers (zenoh-ros2-sdk) of
another distribution's hash and of the wrong type, a real ros2 node and a real router; the
doctor names each failure with its fix."""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
from typing import Any

import pytest

from services.ros2.core.types import types_of
from tests.helpers.wait import wait_until

T = types_of()
COLOUR, DEPTH, INFO = ("/camera/camera/color/image_raw", "/camera/camera/aligned_depth_to_color/image_raw",
                       "/camera/camera/color/camera_info")


@pytest.mark.zenoh
@pytest.mark.slow
def test_the_doctor_names_a_ros2_cameras_silent_failures_live(router: Any, zenoh_client: Any,
                                                              monkeypatch: pytest.MonkeyPatch) -> None:
    os.environ.setdefault("GIT_PYTHON_REFRESH", "quiet")
    sdk = pytest.importorskip("zenoh_ros2_sdk", reason="zenoh-ros2-sdk (the test extra) is not installed")
    monkeypatch.setenv("ZENOH_CONFIG_OVERRIDE", 'scouting/multicast/enabled=false;listen/endpoints=["tcp/127.0.0.1:0"]')
    host, port = router.endpoint.removeprefix("tcp/").rsplit(":", 1)
    zen = ["--robot", "docros", "--mode", "client", "--connect", router.endpoint, "--no-multicast-scouting"]
    env = {**os.environ, "RUST_LOG": "error"}
    node = subprocess.Popen([sys.executable, "-m", "perception", "ros2", "--domain-id", "29", *zen],
                            stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True, env=env)
    sdk.ZenohSession._instance = None
    try:
        def pub(topic: str, type_name: str, type_hash: str) -> Any:
            return sdk.ROS2Publisher(topic, type_name, msg_definition=T.definition(type_name), type_hash=type_hash,
                                     domain_id=29, router_ip=host, router_port=int(port), node_name="camera")

        humble = pub(COLOUR, "sensor_msgs/msg/Image", "TypeHashNotSupported")  # noqa: F841 (kept alive)
        compressed = pub(DEPTH, "sensor_msgs/msg/CompressedImage", T.hash("sensor_msgs/msg/CompressedImage"))  # noqa: F841
        watcher = zenoh_client()
        wait_until(lambda: node.poll() is not None or bool(watcher.alive("pp/docros/perception/v1/alive/ros2/*")),
                   timeout=30, what="the ros2 node's liveliness")
        assert node.poll() is None, node.communicate()[0]
        done = subprocess.run([sys.executable, "-m", "perception", "doctor", "--duration", "2", "--json", *zen],
                              capture_output=True, text=True, timeout=120, env=env)
        report = json.loads(done.stdout)
        checks = {c["name"]: c for c in report["checks"] if c["section"] == "ROS 2"}
        assert checks, report
        assert checks["graph"]["status"] == "ok" and "(/camera)" in checks["graph"]["figure"]
        assert checks[COLOUR]["status"] == "fail" and "Humble" in checks[COLOUR]["figure"]
        assert checks[DEPTH]["status"] == "fail" and "CompressedImage" in checks[DEPTH]["figure"]
        assert checks[INFO]["status"] == "fail" and "no publisher" in checks[INFO]["figure"]
        assert done.returncode == 2
    finally:
        session = sdk.ZenohSession._instance
        if session is not None:
            session.session.close()
        sdk.ZenohSession._instance = None
        node.send_signal(signal.SIGINT)
        node.communicate(timeout=30)
