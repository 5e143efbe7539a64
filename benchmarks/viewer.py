"""Viewer overhead benchmark: what ``perception view`` with one browser attached costs.

    python benchmarks/viewer.py [--fps 30] [--seconds 15]

A router process and a publisher (this process) sending the pipeline's streams for one
camera at --fps: 320x240 RGB frames, detections, localized detections, embeddings, tracks
of two people, transforms, and a status once a second as each node publishes it
(tests/fixtures/viewer_scene.py). First without a
viewer, then with ``perception view`` and headless Chromium showing its page. Prints the
CPU time of the viewer process and of the router (per cent of one core) in each phase:
the viewer's overhead is its own CPU plus the router's increase. Chromium's own CPU is
the browser's, not the pipeline's, and is not counted.
"""

from __future__ import annotations

import argparse
import os
import subprocess
import sys
import threading
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from common.messages.keys import Keys  # noqa: E402
from common.transport.router_process import RouterProcess, free_port  # noqa: E402
from common.transport.zenoh_config import ZenohOptions  # noqa: E402
from common.transport.zenoh import open_transport  # noqa: E402
from tests.fixtures.viewer_scene import ScenePublisher  # noqa: E402
from tests.helpers.chromium import Browser  # noqa: E402

_TCK = os.sysconf("SC_CLK_TCK")


def cpu_s(pid: int) -> float:
    fields = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()
    return (int(fields[11]) + int(fields[12])) / _TCK


def measure(pids: dict[str, int], seconds: float) -> dict[str, float]:
    start = {n: cpu_s(p) for n, p in pids.items()}
    t0 = time.monotonic()
    time.sleep(seconds)
    wall = time.monotonic() - t0
    return {n: 100.0 * (cpu_s(p) - start[n]) / wall for n, p in pids.items()}


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--fps", type=float, default=30.0)
    ap.add_argument("--seconds", type=float, default=15.0)
    args = ap.parse_args()
    keys = Keys(robot=f"viewerbench{os.getpid()}")
    router = RouterProcess()
    router.start()
    transport = open_transport(ZenohOptions(mode="client", connect=[router.endpoint], connect_timeout_s=5.0))
    pub = ScenePublisher(transport, keys, status_every_s=1.0)  # as the nodes publish theirs
    stop = threading.Event()
    sent = [0]

    def loop() -> None:
        t0 = time.monotonic()
        period = 1.0 / args.fps
        while not stop.is_set():
            pub.step(time.monotonic() - t0)
            sent[0] += 1
            stop.wait(max(0.0, t0 + sent[0] * period - time.monotonic()))

    thread = threading.Thread(target=loop, daemon=True)
    thread.start()
    viewer = None
    try:
        time.sleep(2.0)
        assert router.proc is not None
        base = measure({"router": router.proc.pid}, args.seconds)
        port = free_port()
        viewer = subprocess.Popen([sys.executable, "-m", "perception", "-q", "view", "--port", str(port),
                                   "--robot", keys.robot, "--connect", router.endpoint],
                                  stdout=subprocess.DEVNULL, stderr=subprocess.STDOUT,
                                  env={**os.environ, "RUST_LOG": "error"})
        with Browser() as browser:
            browser.open_until(f"http://127.0.0.1:{port}/", "document.querySelectorAll('#tracks [data-track-id]').length > 0",
                               timeout_s=60, retry_s=5)
            browser.wait_for("document.getElementById('camera').naturalWidth > 0", 20)
            time.sleep(2.0)
            sent0 = sent[0]
            seen = measure({"router": router.proc.pid, "viewer": viewer.pid}, args.seconds)
            rate = (sent[0] - sent0) / args.seconds
            version = browser.evaluate("fetch('/api/state').then(r => r.json()).then(s => s.version)")
    finally:
        stop.set()
        thread.join(5)
        if viewer is not None:
            viewer.terminate()
            viewer.wait(30)
        transport.close()
        router.stop()
    overhead = seen["viewer"] + seen["router"] - base["router"]
    print(f"frames published: {rate:.1f} Hz at 320x240 (asked {args.fps:g} Hz), {args.seconds:g} s per phase")
    print(f"router without viewer     {base['router']:5.1f} % of one core")
    print(f"router with viewer        {seen['router']:5.1f} %")
    print(f"viewer (page, 1 browser)  {seen['viewer']:5.1f} %   page states served up to version {version}")
    print(f"viewer overhead           {overhead:5.1f} % of one core (viewer + router increase)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
