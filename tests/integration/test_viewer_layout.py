"""The operator's page fills the window at common sizes, with its labels inside the camera image.

The viewer node and its HTTP server run in this process on the in-memory transport, fed the
test scene (two people, IDs 7 and 12); headless Chromium loads the page at 1280x800 and
1920x1080 and the panels' boxes are read through the DevTools protocol. Skipped, saying
why, when no Chromium is installed (Debian: ``apt-get install chromium``).
"""

from __future__ import annotations

import threading
import time
from typing import Iterator

import pytest

from common.messages.keys import Keys
from common.transport.memory import MemoryBus
from tests.fixtures.viewer_scene import IDS, ScenePublisher
from tests.helpers.chromium import Browser, chromium_path
from tools.viewer.config import ViewerConfig
from tools.viewer.node import ViewerNode
from tools.viewer.web import LatestState, WebServer

pytestmark = pytest.mark.skipif(
    chromium_path() is None, reason="no Chromium installed (apt-get install chromium) for the browser test")
KEYS = Keys(robot="viewerlayout")
PANELS = ("map-panel", "camera-panel", "tracks-panel", "stages-panel", "nodes-panel")


@pytest.fixture(scope="module")
def page_url() -> Iterator[str]:
    """The page of a viewer fed the test scene at 10 Hz from a thread until the tests end."""
    bus = MemoryBus()
    state = LatestState()
    node = ViewerNode(bus.transport(), KEYS, ViewerConfig(), state=state)
    scene = ScenePublisher(bus.transport(), KEYS)
    server = WebServer("127.0.0.1", 0, state)
    server.start()
    stop = threading.Event()

    def loop() -> None:
        t0 = time.monotonic()
        while not stop.wait(0.1):
            scene.step(time.monotonic() - t0)
            node.poll(time.monotonic())

    thread = threading.Thread(target=loop, daemon=True)
    thread.start()
    try:
        yield server.url
    finally:
        stop.set()
        thread.join(5)
        server.close()
        node.close()


_BOXES = """(() => Object.fromEntries(%s.map(id => {
  const r = document.getElementById(id).getBoundingClientRect();
  return [id, [r.left, r.top, r.width, r.height]];
})))()""" % list(PANELS)


@pytest.mark.parametrize(("width", "height"), [(1280, 800), (1920, 1080)])
def test_the_panels_fill_the_window(page_url: str, width: int, height: int) -> None:
    with Browser(width=width, height=height) as browser:
        browser.open_until(page_url, "document.querySelectorAll('#tracks [data-track-id]').length >= 2")
        assert browser.wait_for("document.getElementById('camera').naturalWidth", 30) == 320
        boxes = browser.evaluate(_BOXES)
        for name, (left, top, w, h) in boxes.items():
            assert w > 0.25 * width and h > 0.12 * height, f"{name} is collapsed at {width}x{height}: {w:.0f}x{h:.0f}"
            assert left >= 0 and left + w <= width + 1, f"{name} is outside the window at {width}x{height}"
        covered = sum(w * h for _, _, w, h in boxes.values())
        assert covered > 0.75 * width * height, f"the panels cover {covered / (width * height):.0%} of {width}x{height}"
        # the map and the camera are drawn at their displayed size, and the image is big
        assert browser.evaluate("document.getElementById('map').width") >= 0.4 * width
        assert browser.evaluate("document.getElementById('camera').getBoundingClientRect().height") > 0.25 * height
        # every column has its unit (or is a name, a state, a count)
        heads = browser.evaluate("[...document.querySelectorAll('#tracks th, #stages th')].map(t => t.textContent)")
        assert {"speed (m/s)", "x (m)", "y (m)", "age (s)", "rate (Hz)", "latency p50 (ms)", "p95 (ms)"} <= set(heads)
        assert sorted(browser.evaluate(
            "[...document.querySelectorAll('#tracks [data-track-id]')].map(e => +e.dataset.trackId)")) == list(IDS)


def test_id_labels_stay_inside_the_camera_image(page_url: str) -> None:
    """Boxes at the image's corners get their labels drawn inside the image (the page's own
    drawing, its canvas calls recorded and mapped to where they show on the page)."""
    with Browser(width=1280, height=800) as browser:
        browser.open_until(page_url, "!!(window.state ?? state)?.image")
        got = browser.evaluate("""(() => {
          const texts = [], rects = [];
          const overlay = document.getElementById('overlay'), ctx = overlay.getContext('2d');
          // a point drawn at (x, y), in CSS pixels of the overlay as displayed
          const at = (x, y) => {
            const p = ctx.getTransform().transformPoint(new DOMPoint(x, y));
            return [p.x * overlay.clientWidth / overlay.width, p.y * overlay.clientHeight / overlay.height];
          };
          ctx.fillText = function (t, x, y) { texts.push([t, ...at(x, y), ...at(x + this.measureText(t).width, y)]); };
          ctx.fillRect = function (x, y, w, h) { rects.push([...at(x, y), ...at(x + w, y + h)]); };
          const w = state.image.width, h = state.image.height;
          state.boxes = [{bbox: [w - 6, 0, w, 40], id: 7, colour: '#ffffff'},
                         {bbox: [0, h - 10, 8, h], id: 12, colour: '#ffffff'}];
          drawOverlay();
          const img = document.getElementById('camera').getBoundingClientRect();
          const cv = document.getElementById('overlay').getBoundingClientRect();
          const k = Math.min(img.width / w, img.height / h);
          const ox = (img.width - w * k) / 2, oy = (img.height - h * k) / 2;
          return {texts, rects, image: [img.left - cv.left + ox, img.top - cv.top + oy, w * k, h * k]};
        })()""")
        x0, y0, iw, ih = got["image"]
        assert [t[0] for t in got["texts"]] == ["ID 7", "ID 12"]
        inside = lambda x, y: x0 - 0.5 <= x <= x0 + iw + 0.5 and y0 - 0.5 <= y <= y0 + ih + 0.5  # noqa: E731
        for _, x1, y1, x2, y2 in got["texts"]:  # each label's start and end, in CSS pixels of the overlay
            assert inside(x1, y1) and inside(x2, y2), (got, x0, y0, iw, ih)
        for x1, y1, x2, y2 in got["rects"]:  # and its background
            assert inside(x1, y1) and inside(x2, y2), (got, x0, y0, iw, ih)
