"""The viewer's pure pieces, its node on the in-memory transport, and its HTTP server."""

from __future__ import annotations

import base64
import json
import threading
import urllib.request
from pathlib import Path

import numpy as np
import pytest

from common.messages.keys import Keys
from common.transport.memory import MemoryBus
from tests.fixtures.viewer_scene import IDS, ScenePublisher, camera_to_map
from tools.viewer.config import ViewerConfig
from tools.viewer.core.health import NodeSeen, health
from tools.drawing.tracks import label_boxes, project_to_image
from tools.drawing.meters import StageMeter
from tools.viewer.core.drawing import Trails, colour_hex, yaw_of
from tools.viewer.node import ViewerNode
from tools.viewer.web import LatestState, WebServer

KEYS = Keys(robot="viewertest")


def test_colours_are_stable_and_distinct_for_nearby_ids() -> None:
    assert colour_hex(7) == colour_hex(7) == "#f032e6"
    assert len({colour_hex(i) for i in range(5, 17)}) == 12


def test_trails_keep_the_last_seconds_and_forget_lost_tracks() -> None:
    trails = Trails(span_s=2.0, min_step_s=0.1)
    for k in range(50):
        trails.add(1, k * 0.1, float(k), 0.0)
    trails.prune(4.9)
    xs = [x for x, _ in trails.get(1)]
    assert xs[0] >= 29 and xs[-1] == 49
    trails.prune(10.0)
    assert trails.get(1) == []


def test_stage_meter_rate_and_latency() -> None:
    m = StageMeter()
    for k in range(31):
        m.add(k / 30, 20.0 + k % 2)
    assert m.rate_hz(1.0) == pytest.approx(30.0)
    assert m.latency_ms(50, 1.0) == pytest.approx(20.0)
    assert StageMeter().latency_ms(50, 0.0) is None


def test_projection_and_box_labels() -> None:
    K = np.array([[250.0, 0, 160], [0, 250.0, 120], [0, 0, 1]])
    points = np.array([[3.0, 0.0, 1.0], [-3.0, 0.0, 1.0], [3.0, 1.0, 1.0]])  # ahead, behind, ahead-left
    px = project_to_image(points, camera_to_map(), K, 320, 240)
    assert px[0] == pytest.approx([160.0, 120.0])
    assert np.isnan(px[1]).all()
    assert px[2][0] < 160
    boxes = np.array([[140, 60, 180, 200], [50, 60, 110, 200], [250, 60, 300, 200]])
    assert label_boxes(boxes, px, np.array([5, 6, 9])) == [5, 9, None]


def test_yaw_and_health() -> None:
    c, s = np.cos(0.5), np.sin(0.5)
    assert yaw_of(np.array([[c, -s, 0], [s, c, 0], [0, 0, 1]])) == pytest.approx(0.5)
    node = NodeSeen("tracker", "a", alive=True, status_at=10.0)
    assert health(node, 11.0) == "ok"
    assert health(node, 20.0) == "stale"
    node.alive = False
    assert health(node, 11.0) == "down"
    node.state = "failed"
    assert health(node, 11.0) == "failed"


def test_node_builds_the_page_state_from_the_streams() -> None:
    bus = MemoryBus()
    state = LatestState()
    node = ViewerNode(bus.transport(), KEYS, ViewerConfig(), state=state)
    scene = ScenePublisher(bus.transport(), KEYS)
    state.watched_at = float("inf")  # a browser is watching: images get encoded
    for k in range(5):
        scene.step(k * 0.1)
        node.poll(100.0 + k * 0.1)
    node.poll(101.0)
    snap = json.loads(state.wait_state(0, 0.0))
    assert [t["id"] for t in snap["tracks"]] == list(IDS)
    assert all(len(t["trail"]) >= 2 for t in snap["tracks"])
    assert sorted(b["id"] for b in snap["boxes"]) == list(IDS)
    assert snap["robot"] is not None and snap["robot"]["x"] == pytest.approx(0.04)
    assert snap["image"] == {"seq": 4, "width": 320, "height": 240}
    stages = {s["name"]: s for s in snap["stages"]}
    assert stages["tracker"]["count"] == 5 and stages["camera"]["count"] == 5
    assert stages["detector"]["latency_p50_ms"] is not None
    nodes = {n["name"]: n for n in snap["nodes"]}
    assert nodes["tracker"]["health"] == "ok" and nodes["tracker"]["host"] == "testhost"
    jpeg = state.image()
    assert jpeg is not None and jpeg[:2] == b"\xff\xd8"
    node.close()


def test_no_image_is_encoded_while_nobody_watches() -> None:
    bus = MemoryBus()
    state = LatestState()
    node = ViewerNode(bus.transport(), KEYS, ViewerConfig(), state=state)
    scene = ScenePublisher(bus.transport(), KEYS)
    scene.step(0.0)
    node.poll(1.0)
    assert state.image() is None
    node.close()


def _get(url: str) -> tuple[int, bytes, str]:
    with urllib.request.urlopen(url, timeout=20) as res:
        return res.status, res.read(), res.headers.get("Content-Type", "")


def test_server_serves_the_assets_and_the_latest_state_to_many_clients() -> None:
    state = LatestState()
    server = WebServer("127.0.0.1", 0, state)
    server.start()
    try:
        status, body, kind = _get(server.url)
        assert status == 200 and kind.startswith("text/html") and b"/static/app.js" in body
        for asset in ("app.js", "style.css"):
            assert _get(server.url + "static/" + asset)[0] == 200
        # nothing from elsewhere: the page and its script load no URL with a host
        for asset in ("index.html", "app.js", "style.css"):
            text = _get(server.url + ("" if asset == "index.html" else "static/" + asset))[1].decode()
            assert "http://" not in text and "https://" not in text and "//cdn" not in text
        with pytest.raises(urllib.error.HTTPError):
            _get(server.url + "static/../web.py")
        assert _get(server.url + "api/image.jpg")[0] == 204
        # eight browsers waiting on a long poll all get the next state, and only the newest
        got: list[dict] = []
        waiters = [threading.Thread(target=lambda: got.append(json.loads(_get(server.url + "api/state?after=0")[1])))
                   for _ in range(8)]
        for w in waiters:
            w.start()
        state.set_state({"tracks": [], "n": 1})
        state.set_state({"tracks": [], "n": 2})
        for w in waiters:
            w.join(15)
        assert len(got) == 8 and all(g["version"] >= 1 for g in got)
        assert json.loads(_get(server.url + "api/state?after=0")[1])["n"] == 2
    finally:
        server.close()


def test_a_busy_port_is_a_start_up_error() -> None:
    first = WebServer("127.0.0.1", 0, LatestState())
    try:
        port = int(first.url.rsplit(":", 1)[1].strip("/"))
        with pytest.raises(ValueError, match="cannot serve the page"):
            WebServer("127.0.0.1", port, LatestState())
    finally:
        first.close()


def test_the_state_carries_the_newest_image_only_when_the_browser_lacks_it() -> None:
    state = LatestState()
    state.set_state({"tracks": [], "image": {"seq": 5, "width": 2, "height": 2}})
    assert "jpeg" not in json.loads(state.wait_state(0, 0.0, have_image=-1))  # no image yet
    state.set_image(b"\xff\xd8fake", seq=5)
    got = json.loads(state.wait_state(0, 0.0, have_image=-1))
    assert base64.b64decode(got["jpeg"]) == b"\xff\xd8fake" and got["image"]["seq"] == 5
    assert "jpeg" not in json.loads(state.wait_state(0, 0.0, have_image=5))  # it has this one
    assert "jpeg" not in json.loads(state.wait_state(0, 0.0))  # a client that asks for no image


def test_page_states_are_built_once_a_second_while_nobody_watches() -> None:
    bus = MemoryBus()
    state = LatestState()
    node = ViewerNode(bus.transport(), KEYS, ViewerConfig(), state=state)
    scene = ScenePublisher(bus.transport(), KEYS)
    for k in range(30):  # 3 s at 10 Hz, a new frame each time
        scene.step(k * 0.1)
        node.poll(100.0 + k * 0.1)
    assert 3 <= state.version <= 4
    state.watched_at = float("inf")  # a browser asks: the page's own rate again
    before = state.version
    for k in range(10):  # 1.1 s, polled a little slower than the page's 10 states a second
        scene.step(3.0 + k * 0.11)
        node.poll(103.0 + k * 0.11)
    assert state.version - before >= 9
    node.close()


def test_the_robots_map_goes_to_the_page_once_from_a_file_or_the_stream(tmp_path: Path) -> None:
    from common.geometry.map_file import OccupancyGrid, write_map
    from common.messages.keys import MAPS
    from common.messages.schemas import Header, StaticMap

    bus = MemoryBus()
    pub = bus.transport().publisher(KEYS.static_map(), StaticMap, MAPS)
    cells = np.zeros((4, 6), np.int8)
    cells[1, 2:5] = 100
    grid = StaticMap(header=Header(stamp_ns=1, frame_id="map"), resolution=0.1, width=6, height=4,
                     origin=(1.0, 2.0, 0.0), data=cells.tobytes())
    state = LatestState()
    node = ViewerNode(bus.transport(), KEYS, ViewerConfig(port=0), state=state)
    for _ in range(2):  # sent again by the ros2 node: one version
        pub.put(grid)
        node.poll(0.0)
    shown = json.loads(state.static_map())
    assert shown["runs"] == [[1, 2, 5]] and shown["origin"] == [1.0, 2.0, 0.0] and shown["version"] == 1
    assert node.snapshot(0.0)["static_map"] == {"version": 1, "frame_id": "map"}
    node.close()
    # a map file wins over the stream
    occupied = np.zeros((3, 3), bool)
    occupied[0, 0] = True
    write_map(tmp_path / "m.yaml", OccupancyGrid(occupied, np.zeros_like(occupied), 0.05, (0.0, 0.0, 0.0)))
    state = LatestState()
    node = ViewerNode(bus.transport(), KEYS, ViewerConfig(port=0, static_map=tmp_path / "m.yaml"), state=state)
    pub.put(grid)
    node.poll(0.0)
    assert json.loads(state.static_map())["runs"] == [[0, 0, 1]]
    node.close()


def test_a_map_file_goes_to_the_sinks_every_few_seconds(tmp_path: Path) -> None:
    from common.geometry.map_file import OccupancyGrid, write_map
    from common.messages.schemas import StaticMap

    occupied = np.zeros((3, 4), bool)
    occupied[1, :] = True
    write_map(tmp_path / "m.yaml", OccupancyGrid(occupied, np.zeros_like(occupied), 0.05, (2.0, 1.0, 0.0)))
    got: list[StaticMap] = []

    class Sink:
        def on_message(self, stream: str, msg: object) -> None:
            if isinstance(msg, StaticMap):
                got.append(msg)

        def close(self) -> None:
            pass

    node = ViewerNode(MemoryBus().transport(), KEYS, ViewerConfig(port=None, foxglove_port=0,
                                                                   static_map=tmp_path / "m.yaml"), sinks=(Sink(),))
    for now in (0.0, 1.0, 4.0, 5.5):
        node.poll(now)
    node.close()
    assert len(got) == 2 and got[0].origin == (2.0, 1.0, 0.0) and got[0].header.frame_id == "map"
    assert got[0].occupancy()[1].tolist() == [100] * 4 and got[0].occupancy()[0].tolist() == [0] * 4
