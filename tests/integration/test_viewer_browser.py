"""``perception view`` as a real process over a real router, watched by headless Chromium.

A test publisher sends a known scene (two people, track IDs 7 and 12, a robot, a camera
with their boxes); the page, in a real browser, must show both tracks in its table, draw
them on the map, show the camera image with ID-labelled boxes, the stages' rates and the
publishing node's health; a 2-D laser on the robot must have its scan's returns drawn where
they are in the map (through the robot's transforms) and its person as a ring, with no image
box. Skipped, saying why, when no Chromium is installed (Debian:
``apt-get install chromium``; ``scripts/test.sh`` installs it where it can).
"""

from __future__ import annotations

import os
import subprocess
import sys
import threading
import time
from pathlib import Path
from typing import Callable, Iterator

import numpy as np
import pytest

from common.geometry.messages import transform_msg
from common.geometry.transforms import RigidTransform
from common.messages.keys import RELIABLE, SCANS, Keys
from common.messages.schemas import Header, LaserScan, LocalizedDetection, LocalizedDetections, TransformBatch
from common.transport.router_process import RouterProcess, free_port
from common.transport.zenoh import ZenohTransport
from tests.fixtures.viewer_scene import IDS, WALL_RGB, ScenePublisher
from tests.helpers.chromium import Browser, chromium_path

pytestmark = [pytest.mark.zenoh, pytest.mark.skipif(
    chromium_path() is None, reason="no Chromium installed (apt-get install chromium) for the browser test")]
KEYS = Keys(robot="viewerbrowser")
#: the laser 0.3 m ahead of base_link, seeing a straight wall 2.5 m ahead of it from -50 to +50 degrees
#: (beams 1 degree apart from -60 to +60, those beyond 50 degrees with no return)
LASER_X, WALL_M, BEAMS, SEEN = 0.3, 2.5, 121, 101
#: the person the laser sees, in the map (no image box)
LASER_PERSON = (1.5, 1.5)
#: how the page draws them (tools/viewer/static/app.js)
SCAN_RGB, LASER_PERSON_RGB = (0xD8, 0xC2, 0x7A), (0xA0, 0xE8, 0xFF)


def _viewer(endpoint: str, port: int, log: Path) -> subprocess.Popen[bytes]:
    return subprocess.Popen(
        [sys.executable, "-m", "perception", "view", "--port", str(port), "--robot", KEYS.robot,
         "--connect", endpoint],
        stdout=log.open("wb"), stderr=subprocess.STDOUT, env={**os.environ, "RUST_LOG": "error"})


@pytest.fixture
def scene(zenoh_client: Callable[[], ZenohTransport]) -> Iterator[ScenePublisher]:
    """The scene published at 15 Hz from a thread until the test ends."""
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


def _laser_messages(stamp: int, seq: int) -> list[tuple[str, object]]:
    angles = np.radians(np.arange(BEAMS) - 60.0)
    ranges = np.where(np.abs(angles) <= np.radians(50.5), WALL_M / np.cos(angles), np.nan).astype(np.float32)
    scan = LaserScan(header=Header(stamp_ns=stamp, frame_id="front_laser", seq=seq, source="front"),
                     angle_min=float(angles[0]), angle_max=float(angles[-1]), angle_increment=float(np.radians(1.0)),
                     range_min=0.05, range_max=8.0, ranges=ranges)
    mount = TransformBatch(header=Header(stamp_ns=stamp, source="tf_static"), transforms=[transform_msg(
        "base_link", "front_laser", stamp, RigidTransform.from_quat(np.array([LASER_X, 0, 0.2]), np.array([0, 0, 0, 1.0])),
        static=True)])
    people = LocalizedDetections(header=Header(stamp_ns=stamp, frame_id="map", seq=seq, source="front"),
                                 camera_frame="front_laser", detector="laser-legs", detections=[LocalizedDetection(
                                     index=0, bbox_xyxy=(0.0, 0.0, 0.0, 0.0), score=0.8, depth_m=2.0,
                                     position=np.array([*LASER_PERSON, 0.9]), cov=np.eye(3) * 0.01)])
    return [(KEYS.tf_static(), mount), (KEYS.scans("front"), scan), (KEYS.localized("front"), people)]


@pytest.fixture
def laser(zenoh_client: Callable[[], ZenohTransport]) -> Iterator[None]:
    """A laser on the robot: its mount (tf_static), scans and people, at 10 Hz from a thread."""
    transport = zenoh_client()
    pubs = {KEYS.tf_static(): transport.publisher(KEYS.tf_static(), TransformBatch, RELIABLE),
            KEYS.scans("front"): transport.publisher(KEYS.scans("front"), LaserScan, SCANS),
            KEYS.localized("front"): transport.publisher(KEYS.localized("front"), LocalizedDetections, RELIABLE)}
    stop = threading.Event()

    def loop() -> None:
        seq = 0
        while not stop.wait(0.1):
            for key, msg in _laser_messages(time.time_ns(), seq):
                pubs[key].put(msg)  # type: ignore[arg-type]
            seq += 1

    thread = threading.Thread(target=loop, daemon=True)
    thread.start()
    yield
    stop.set()
    thread.join(5)


def _painted(rgb: tuple[int, int, int], at_least: int) -> str:
    """JavaScript: how many of the map canvas's pixels are ``rgb`` (within 3 a channel), or null below ``at_least``."""
    return ("(() => { const c = document.getElementById('map'); const d = c.getContext('2d')"
            ".getImageData(0, 0, c.width, c.height).data; let n = 0; for (let i = 0; i < d.length; i += 4)"
            f" if (Math.abs(d[i]-{rgb[0]}) < 4 && Math.abs(d[i+1]-{rgb[1]}) < 4 && Math.abs(d[i+2]-{rgb[2]}) < 4) n++;"
            f" return n >= {at_least} ? n : null; }})()")


def test_the_page_shows_the_tracks_camera_and_health_in_a_real_browser(
        router: RouterProcess, scene: ScenePublisher, laser: None, tmp_path: Path) -> None:
    port = free_port()
    proc = _viewer(router.endpoint, port, tmp_path / "viewer.log")
    try:
        with Browser(width=1280, height=900) as browser:
            url = f"http://127.0.0.1:{port}/"
            deadline = time.monotonic() + 60
            while True:  # the viewer process takes a moment to bind
                browser.goto(url)
                if browser.wait_for("document.readyState === 'complete' && !!document.getElementById('map')", 10):
                    break
                assert time.monotonic() < deadline and proc.poll() is None, (tmp_path / "viewer.log").read_text()
            ids = browser.wait_for(
                "(() => { const ids = [...document.querySelectorAll('#tracks [data-track-id]')]"
                ".map(e => +e.dataset.trackId); return ids.length >= 2 ? ids : null; })()", 60)
            assert sorted(ids) == list(IDS)
            # the camera image arrived and its boxes carry the tracks' IDs
            assert browser.wait_for("document.getElementById('camera').naturalWidth", 30) == 320
            boxes = browser.evaluate("fetch('/api/state').then(r => r.json()).then(s => s.boxes.map(b => b.id))")
            assert sorted(boxes) == list(IDS)
            # the map canvas shows each track's colour
            for track_id in IDS:
                colour = browser.evaluate(
                    f"document.querySelector('[data-track-id=\"{track_id}\"] .swatch').style.background")
                rgb = [int(v) for v in colour.removeprefix("rgb(").rstrip(")").split(",")]
                painted = browser.evaluate(
                    "(() => { const c = document.getElementById('map'); const d = c.getContext('2d')"
                    ".getImageData(0, 0, c.width, c.height).data; let n = 0; for (let i = 0; i < d.length; i += 4)"
                    f" if (Math.abs(d[i]-{rgb[0]}) < 4 && Math.abs(d[i+1]-{rgb[1]}) < 4 && Math.abs(d[i+2]-{rgb[2]}) < 4) n++;"
                    " return n; })()")
                assert painted > 50, f"track {track_id} is not drawn on the map"
            # the robot's map, under the tracks: the wall at x = 5 m
            assert browser.wait_for("staticMap && staticMap.runs.length", 30) == 80
            walls = browser.wait_for(
                "(() => { const c = document.getElementById('map'); const d = c.getContext('2d')"
                ".getImageData(0, 0, c.width, c.height).data; let n = 0; for (let i = 0; i < d.length; i += 4)"
                f" if (Math.abs(d[i]-{WALL_RGB[0]}) < 4 && Math.abs(d[i+1]-{WALL_RGB[1]}) < 4 && Math.abs(d[i+2]-{WALL_RGB[2]}) < 4)"
                " n++; return n > 200 ? n : null; })()", 30)
            assert walls, "the robot's map is not drawn"
            # the laser's scan: every return, on the wall 2.8 m ahead of the robot in the map
            scan = browser.wait_for(
                "fetch('/api/state').then(r => r.json()).then(s => s.scans && s.scans.length && s.robot"
                " ? {scan: s.scans[0], robot: s.robot, people: s.laser_people, boxes: s.boxes} : null)", 30)
            assert scan, (tmp_path / "viewer.log").read_text()
            assert scan["scan"]["laser"] == "front" and scan["scan"]["frame_id"] == "front_laser"
            assert "error" not in scan["scan"] and scan["scan"]["beams"] == BEAMS
            xy = np.array(scan["scan"]["points"]).reshape(-1, 2)
            assert len(xy) == SEEN
            robot = scan["robot"]
            assert np.abs(xy[:, 0] - (robot["x"] + LASER_X + WALL_M)).max() < 0.1  # the robot moves at 0.1 m/s
            assert xy[:, 1] == pytest.approx(sorted(WALL_M * np.tan(np.radians(np.arange(-50, 51)))), abs=0.05)
            # the laser's person: on the map only, no box on the image
            assert scan["people"] == [{"source": "front", "x": LASER_PERSON[0], "y": LASER_PERSON[1], "score": 0.8}]
            assert sorted(b["id"] for b in scan["boxes"]) == list(IDS)
            assert browser.wait_for(_painted(SCAN_RGB, 300), 30), "the laser's scan is not drawn on the map"
            assert browser.wait_for(_painted(LASER_PERSON_RGB, 20), 30), "the laser's person is not drawn on the map"
            assert "laser front" in browser.evaluate("document.getElementById('map').dataset.legend")
            # the tracker's latest ID decisions, in words
            why = browser.wait_for("document.querySelector('#id-decisions li[data-outcome=\"recovered\"]')?.textContent", 30)
            assert f"ID {IDS[0]} recovered: support 0.85" in why and " s ago: " in why
            # stages with rates, and the publisher's health from its token and status
            assert browser.wait_for(
                "+document.querySelector('[data-stage=\"tracker\"]').children[2].textContent > 5", 20)
            assert browser.wait_for("document.querySelector('[data-node=\"tracker\"]')?.dataset.health === 'ok'", 20)
            png = browser.screenshot()
            assert png[:8] == b"\x89PNG\r\n\x1a\n"
            import cv2

            shot = cv2.imdecode(np.frombuffer(png, np.uint8), cv2.IMREAD_COLOR)
            assert shot.shape[:2] == (900, 1280) and shot.std() > 10
            (tmp_path / "page.png").write_bytes(png)
    finally:
        proc.terminate()
        assert proc.wait(30) == 0, (tmp_path / "viewer.log").read_text()


def test_a_slow_browser_gets_the_newest_state_not_a_queue(router: RouterProcess, scene: ScenePublisher,
                                                         tmp_path: Path) -> None:
    """A client that asks seldom gets states whose versions jump: nothing waited for it."""
    import json
    import urllib.request

    port = free_port()
    proc = _viewer(router.endpoint, port, tmp_path / "viewer.log")
    try:
        deadline = time.monotonic() + 60
        versions: list[int] = []
        while len(versions) < 3 and time.monotonic() < deadline:
            try:
                with urllib.request.urlopen(f"http://127.0.0.1:{port}/api/state?after=0", timeout=15) as res:
                    snap = json.loads(res.read())
            except OSError:
                time.sleep(0.2)  # the poll interval while the server starts, inside the loop's deadline; not a wait
                continue
            if snap.get("tracks"):
                versions.append(snap["version"])
                time.sleep(1.0)  # not a wait: the test is about a slow browser, which asks once a second
        assert len(versions) == 3, (tmp_path / "viewer.log").read_text()
        assert all(b - a > 3 for a, b in zip(versions, versions[1:]))
    finally:
        proc.terminate()
        assert proc.wait(30) == 0


@pytest.mark.slow
def test_demo_view_serves_the_page_while_the_whole_pipeline_runs(tmp_path: Path) -> None:
    """``perception demo --view``: router, the four nodes, the simulator and the viewer as
    processes; the page in Chromium shows the tracker's confirmed tracks, live."""
    port = free_port()
    demo = subprocess.Popen(
        [sys.executable, "-m", "perception", "demo", "--view", "--view-port", str(port), "--duration", "25",
         "--no-view", "--log-dir", str(tmp_path)],
        stdout=subprocess.PIPE, stderr=subprocess.STDOUT, env={**os.environ, "RUST_LOG": "error"})
    try:
        with Browser() as browser:
            try:
                ids = browser.open_until(f"http://127.0.0.1:{port}/",
                                         "(() => { const ids = [...document.querySelectorAll('#tracks [data-track-id]')]"
                                         ".map(e => +e.dataset.trackId); return ids.length ? ids : null; })()",
                                         timeout_s=120, retry_s=15, alive=lambda: demo.poll() is None)
            except TimeoutError:
                ids = None
            assert ids, (tmp_path / "processes.log").read_text()
            healthy = browser.wait_for(
                "[...document.querySelectorAll('#nodes [data-health=\"ok\"]')].map(e => e.dataset.node)", 20)
            assert {"detector", "localizer", "embedder", "tracker"} <= set(healthy)
            assert browser.wait_for("document.getElementById('camera').naturalWidth", 20) == 320
        out, _ = demo.communicate(timeout=120)
        assert demo.returncode == 0, out.decode()
        assert b"live page is on" in out
        assert (tmp_path / "tracks.png").is_file(), "the demo draws its run"
    finally:
        if demo.poll() is None:
            demo.terminate()
            demo.wait(60)
