"""Draw the README's pictures from real runs (none is drawn by hand).

  docs/demo-plot.png     the demo's scenario run through the four nodes in one process
                         (tools/demo/inprocess.py, deterministic), plotted as
                         ``perception evaluate --plot`` draws it
  docs/viewer-page.png   headless Chromium's screenshot of ``perception view`` while
                         ``perception demo --view`` runs the whole pipeline as processes
                         (``changing-clothes-in-view``, 11 s in: a person came back)
  docs/soak.png          the hour-long soak's RSS and CPU per process, from its recorded
                         samples (benchmarks/results/soak_3600s.json; the hour is not re-run)

Run from the repository root: ``.venv/bin/python scripts/readme_images.py`` (needs the
``view`` extra, and Debian's ``chromium`` for the screenshot; about a minute).
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from common.transport.router_process import free_port  # noqa: E402
from tests.helpers.chromium import Browser  # noqa: E402
from tools.demo.inprocess import run_chain  # noqa: E402


def plot(out: Path, scenario: str, duration_s: float) -> None:
    result = run_chain(scenario, duration_s=duration_s, plot=out)
    print(result.table)
    print(f"wrote {out}")


def soak_plot(out: Path, samples: Path) -> None:
    from benchmarks import soak
    print(f"wrote {soak.plot_soak(json.loads(samples.read_text()), out)}")


def screenshot(out: Path, scenario: str, settle_s: float) -> None:
    port = free_port()
    with tempfile.TemporaryDirectory(prefix="perception-readme-") as tmp:
        demo = subprocess.Popen(
            [sys.executable, "-m", "perception", "demo", "--scenario", scenario, "--view", "--view-port", str(port),
             "--duration", str(settle_s + 40), "--no-view", "--log-dir", tmp],
            stdout=subprocess.DEVNULL, stderr=subprocess.STDOUT, cwd=ROOT, env={**os.environ, "RUST_LOG": "error"})
        try:
            with Browser(width=1280, height=800) as browser:
                browser.open_until(f"http://127.0.0.1:{port}/",
                                   "document.querySelectorAll('#tracks [data-track-id]').length > 0",
                                   timeout_s=120, retry_s=10, alive=lambda: demo.poll() is None)
                time.sleep(settle_s)  # let the trails grow and the rates settle
                browser.wait_for("document.getElementById('camera').naturalWidth > 0", 20)
                out.write_bytes(browser.screenshot())
                print(f"wrote {out}")
        finally:
            demo.terminate()
            demo.wait(60)


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--scenario", default="still", help="the plotted run's scenario")
    parser.add_argument("--duration", type=float, default=30.0, help="simulated seconds of the plotted run")
    # a person has walked out and come back by 6.4 s: the page shows the ID decision beside the tracks
    parser.add_argument("--page-scenario", default="changing-clothes-in-view", help="the screenshot's scenario")
    parser.add_argument("--settle", type=float, default=11.0, help="seconds the page runs before the screenshot")
    parser.add_argument("--only", choices=("plot", "screenshot", "soak"), default=None)
    args = parser.parse_args()
    (ROOT / "docs").mkdir(exist_ok=True)
    if args.only in (None, "plot"):
        plot(ROOT / "docs" / "demo-plot.png", args.scenario, args.duration)
    if args.only in (None, "screenshot"):
        screenshot(ROOT / "docs" / "viewer-page.png", args.page_scenario, args.settle)
    if args.only in (None, "soak"):
        soak_plot(ROOT / "docs" / "soak.png", ROOT / "benchmarks" / "results" / "soak_3600s.json")
    return 0


if __name__ == "__main__":
    sys.exit(main())
