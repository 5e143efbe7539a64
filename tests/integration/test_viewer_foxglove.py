"""Foxglove: ``perception view --foxglove-port`` answers a real WebSocket client speaking
Foxglove's protocol (as a real process over a real router), and the bridge's messages use
Foxglove's well-known schemas."""

from __future__ import annotations

import base64
import json
import os
import struct
import subprocess
import sys
import threading
import time
from pathlib import Path
from typing import Any, Callable, Iterator

import pytest

from common.messages.keys import Keys
from common.transport.router_process import RouterProcess, free_port
from common.transport.zenoh import ZenohTransport
from tests.fixtures.viewer_scene import IDS, ScenePublisher
from tests.helpers.wait import wait_until

pytest.importorskip("foxglove", reason="Foxglove needs foxglove-sdk (the 'view' extra)")
pytest.importorskip("websockets", reason="the protocol client is the websockets package (the 'test' extra)")
pytest.importorskip("google.protobuf", reason="decoding Foxglove's protobuf schemas needs protobuf")

KEYS = Keys(robot="viewerfox")
SUBPROTOCOLS = ["foxglove.sdk.v1", "foxglove.websocket.v1"]


def _decoder(channel: dict[str, Any]) -> Callable[[bytes], Any]:
    """A protobuf decoder for an advertised channel, built from the FileDescriptorSet it carries."""
    from google.protobuf import descriptor_pb2, descriptor_pool, message_factory

    fds = descriptor_pb2.FileDescriptorSet.FromString(base64.b64decode(channel["schema"]))
    pool = descriptor_pool.DescriptorPool()
    for f in fds.file:
        pool.Add(f)
    cls = message_factory.GetMessageClass(pool.FindMessageTypeByName(channel["schemaName"]))
    return cls.FromString


@pytest.fixture
def scene(zenoh_client: Callable[[], ZenohTransport]) -> Iterator[ScenePublisher]:
    pub = ScenePublisher(zenoh_client(), KEYS)
    stop = threading.Event()

    def loop() -> None:
        t0 = time.monotonic()
        while not stop.wait(1 / 15):
            pub.step(time.monotonic() - t0)

    thread = threading.Thread(target=loop, daemon=True)
    thread.start()
    yield pub
    stop.set()
    thread.join(5)


@pytest.mark.zenoh
def test_a_websocket_client_sees_the_channels_and_the_people(router: RouterProcess, scene: ScenePublisher,
                                                              tmp_path: Path) -> None:
    from websockets.sync.client import connect

    port = free_port()
    log = tmp_path / "viewer.log"
    proc = subprocess.Popen(
        [sys.executable, "-m", "perception", "view", "--foxglove-port", str(port), "--no-page", "--robot", KEYS.robot,
         "--connect", router.endpoint], stdout=log.open("wb"), stderr=subprocess.STDOUT,
        env={**os.environ, "RUST_LOG": "error"})

    def connected() -> Any:
        try:
            return connect(f"ws://127.0.0.1:{port}", subprotocols=SUBPROTOCOLS, max_size=None, open_timeout=5)
        except OSError:
            assert proc.poll() is None, log.read_text()
            return None

    try:
        ws_cm = wait_until(connected, 60.0, interval=0.2, what=lambda: f"the Foxglove server\n{log.read_text()}")
        with ws_cm as ws:
            assert ws.subprotocol in SUBPROTOCOLS
            channels: dict[str, dict[str, Any]] = {}
            while not {"/people", "/camera/image", "/camera/annotations", "/tf", "/perception/tracks"} <= set(channels):
                msg = ws.recv(timeout=30)
                if isinstance(msg, str):
                    op = json.loads(msg)
                    if op.get("op") == "advertise":
                        channels.update({c["topic"]: c for c in op["channels"]})
            assert channels["/people"]["schemaName"] == "foxglove.SceneUpdate"
            assert channels["/camera/image"]["schemaName"] == "foxglove.CompressedImage"
            assert channels["/camera/annotations"]["schemaName"] == "foxglove.ImageAnnotations"
            assert channels["/tf"]["schemaName"] == "foxglove.FrameTransforms"
            assert channels["/perception/tracks"]["encoding"] == "json"
            people = channels["/people"]
            ws.send(json.dumps({"op": "subscribe", "subscriptions": [{"id": 1, "channelId": people["id"]}]}))
            decode = _decoder(people)
            while True:
                msg = ws.recv(timeout=30)
                if isinstance(msg, bytes) and msg[0] == 0x01:
                    sub_id, _stamp = struct.unpack_from("<IQ", msg, 1)
                    assert sub_id == 1
                    update = decode(msg[13:])
                    if update.entities:
                        break
            assert sorted(e.id for e in update.entities) == sorted(f"person-{i}" for i in IDS)
            entity = update.entities[0]
            assert entity.frame_id == "map" and entity.cylinders and entity.arrows and entity.lines
            assert entity.texts[0].text in {f"ID {i}" for i in IDS}
    finally:
        proc.terminate()
        assert proc.wait(30) == 0, log.read_text()


def test_export_foxglove_writes_well_known_schemas_read_back_with_the_mcap_reader(tmp_path: Path) -> None:
    from mcap.reader import make_reader

    from tests.fixtures.viewer_scene import scene_messages
    from tools.replay.recorder import McapRecorder

    recording = tmp_path / "run.mcap"
    frames = 12
    with McapRecorder(recording) as rec:
        for seq in range(frames):
            for key, msg in scene_messages(seq, seq / 15, KEYS):
                rec.write(key, msg, msg.header.stamp_ns)  # type: ignore[arg-type]
    out = tmp_path / "foxglove.mcap"
    res = subprocess.run([sys.executable, "-m", "perception", "export-foxglove", str(recording), str(out)],
                         capture_output=True, text=True, timeout=120, check=False)
    assert res.returncode == 0, res.stderr
    counts: dict[str, int] = {}
    schemas: dict[str, str] = {}
    with out.open("rb") as f:
        for schema, channel, _message in make_reader(f).iter_messages():
            counts[channel.topic] = counts.get(channel.topic, 0) + 1
            schemas[channel.topic] = schema.name if schema is not None else ""
    assert schemas["/people"] == "foxglove.SceneUpdate"
    assert schemas["/camera/image"] == "foxglove.CompressedImage"
    assert schemas["/camera/annotations"] == "foxglove.ImageAnnotations"
    assert schemas["/tf"] == "foxglove.FrameTransforms"
    for topic in ("/people", "/camera/image", "/camera/annotations", "/tf", "/perception/tracks",
                  "/perception/detections", "/perception/localized", "/perception/status"):
        assert counts[topic] == frames, topic
    again = subprocess.run([sys.executable, "-m", "perception", "export-foxglove", str(recording), str(out)],
                           capture_output=True, text=True, timeout=120, check=False)
    assert again.returncode == 2 and "--force" in again.stderr


def test_the_robots_map_is_a_foxglove_grid_when_it_changes_and_every_few_seconds() -> None:
    from tests.fixtures.viewer_scene import static_map
    from tools.foxglove.bridge import MAP_PERIOD_S, FoxgloveBridge

    bridge = FoxgloveBridge()
    for k in range(12):  # the ros2 node's copies, one a second
        bridge.on_message("static_map", static_map(10**18 + k * 10**9))
    assert bridge.counts == {"/map": 1 + int(11 // MAP_PERIOD_S)}
    moved = static_map(10**18 + 12 * 10**9).model_copy(update={"origin": (1.0, -3.0, 0.0)})
    bridge.on_message("static_map", moved)  # a new map: at once
    assert bridge.counts == {"/map": 2 + int(11 // MAP_PERIOD_S)}


def test_export_foxglove_writes_each_lasers_scans_as_a_foxglove_laserscan(tmp_path: Path) -> None:
    """A recording's ``scans/{laser}`` become ``/scans/{laser}`` ``foxglove.LaserScan`` messages (the
    bridge's conversion; the export command passes every message through it)."""
    import math

    import numpy as np
    from mcap.reader import make_reader

    from common.messages.schemas import Header, LaserScan
    from tools.replay.recorder import McapRecorder

    recording, out = tmp_path / "run.mcap", tmp_path / "foxglove.mcap"
    ranges = np.array([1.0, np.nan, 2.0, np.inf, 3.0], np.float32)
    with McapRecorder(recording) as rec:
        for seq in range(4):
            stamp = 10**18 + seq * 10**8
            scan = LaserScan(header=Header(stamp_ns=stamp, frame_id="front_laser", seq=seq, source="front"),
                             angle_min=-math.pi / 4, angle_max=math.pi / 4, angle_increment=math.pi / 8,
                             range_min=0.05, range_max=30.0, ranges=ranges)
            rec.write(KEYS.scans("front"), scan, stamp)
    res = subprocess.run([sys.executable, "-m", "perception", "export-foxglove", str(recording), str(out)],
                         capture_output=True, text=True, timeout=120, check=False)
    assert res.returncode == 0, res.stderr
    decoded = []
    with out.open("rb") as f:
        for schema, channel, message in make_reader(f).iter_messages():
            assert channel.topic == "/scans/front" and schema is not None and schema.name == "foxglove.LaserScan"
            decoded.append(_decoder({"schema": base64.b64encode(schema.data).decode(), "schemaName": schema.name})(
                message.data))
    assert len(decoded) == 4
    scan = decoded[0]
    assert scan.frame_id == "front_laser"
    assert (scan.start_angle, scan.end_angle) == pytest.approx((-math.pi / 4, math.pi / 4))
    got = np.array(scan.ranges)
    assert got[[0, 2, 4]] == pytest.approx([1.0, 2.0, 3.0]) and np.isnan(got[[1, 3]]).all()
