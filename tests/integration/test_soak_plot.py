"""benchmarks/soak.py's plot (``--plot``, ``--plot-only``) on a small synthetic run: no hour-long soak."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path
from types import ModuleType
from typing import Any

import numpy as np
import pytest

pytest.importorskip("matplotlib", reason="plots need matplotlib (the 'view' extra)")

ROOT = Path(__file__).resolve().parents[2]
SOAK = ROOT / "benchmarks" / "soak.py"


@pytest.fixture(scope="module")
def soak() -> ModuleType:
    from benchmarks import soak

    return soak


def _run(kill_recorded: bool) -> dict[str, Any]:
    """Five samples a minute apart; the router killed just before the sample at 180 s (down at
    that sample, back with a new pid and one restart at 240 s); the tracker grows 10 %."""
    samples = []
    for i, t in enumerate((0.0, 60.0, 120.0, 180.0, 240.0)):
        router = ({"pid": 1, "rss_kib": 102400, "cpu_percent": 3.0, "restarts": 0} if i < 3 else
                  {"pid": 1, "rss_kib": None, "cpu_percent": 3.0, "restarts": 0} if i == 3 else
                  {"pid": 9, "rss_kib": 81920, "cpu_percent": None, "restarts": 1})
        samples.append({"t": t, "tracks_age_s": 0.0, "processes": {
            "router": router,
            "detector": {"pid": 2, "rss_kib": 153600, "cpu_percent": None if i == 0 else 60.0, "restarts": 0},
            "tracker": {"pid": 3, "rss_kib": 102400 + 2560 * i, "cpu_percent": None if i == 0 else 0.0, "restarts": 0},
        }})
    summary: dict[str, Any] = {"duration_s": 300.0, "fps": 30.0, "size": [320, 240], "growth_from_s": 60.0,
                               "rss_growth_percent": {"router": -20.0, "detector": 0.0, "tracker": 7.5}}
    if kill_recorded:
        summary["router_killed_at_s"] = 175.0
    return {"summary": summary, "samples": samples}


def test_the_router_kill_is_read_or_inferred(soak: ModuleType) -> None:
    assert soak.router_kill_time(_run(kill_recorded=True)) == 175.0
    # files written before the kill time was recorded: the last sample before the restart was seen
    assert soak.router_kill_time(_run(kill_recorded=False)) == 180.0
    no_kill = _run(kill_recorded=False)
    no_kill["samples"] = no_kill["samples"][:3]
    assert soak.router_kill_time(no_kill) is None


def test_the_figure_draws_rss_and_cpu_with_the_window_and_the_kill(soak: ModuleType) -> None:
    fig = soak.soak_figure(_run(kill_recorded=True))
    rss_ax, cpu_ax = fig.axes
    lines = {line.get_label(): line for line in rss_ax.get_lines()}
    tracker = lines["tracker (+7.5 %)"]
    assert list(tracker.get_xdata()) == [0.0, 1.0, 2.0, 3.0, 4.0]  # minutes
    assert list(tracker.get_ydata()) == [100.0, 102.5, 105.0, 107.5, 110.0]  # MiB
    router = np.asarray(lines["router (-20.0 %)"].get_ydata(), dtype=float)
    assert np.isnan(router[3]) and router[4] == 80.0  # down at the sample: a gap
    assert list(lines["minute 1: RSS growth measured from here"].get_xdata()) == [1.0, 1.0]
    assert list(lines["router killed (minute 3)"].get_xdata()) == [175.0 / 60.0] * 2
    cpu = [np.asarray(line.get_ydata(), dtype=float) for line in cpu_ax.get_lines()[:3]]
    assert np.isnan(cpu[0][4])  # the restarted router has no CPU share yet
    assert list(cpu[2][1:]) == [0.0] * 4  # an idle process is drawn at 0, not left out
    assert "5 min at 30 fps, 320x240" in fig.get_suptitle()


def test_plot_only_draws_an_earlier_runs_json(tmp_path: Path) -> None:
    data = tmp_path / "soak.json"
    data.write_text(json.dumps(_run(kill_recorded=False)))
    out = tmp_path / "plots" / "soak.png"
    res = subprocess.run([sys.executable, str(SOAK), "--plot-only", str(data), "--plot", str(out)],
                         capture_output=True, text=True, timeout=120, check=False, cwd=ROOT)
    assert res.returncode == 0, res.stderr
    assert f"wrote {out}" in res.stdout
    import cv2

    img = cv2.imread(str(out), cv2.IMREAD_COLOR)
    assert img is not None and img.shape[0] > 300 and img.shape[1] > 600 and img.std() > 5


def test_plot_only_without_a_plot_or_with_a_bad_file_fails_with_a_message(tmp_path: Path) -> None:
    bad = tmp_path / "bad.json"
    bad.write_text(json.dumps({"summary": {}, "samples": []}))
    res = subprocess.run([sys.executable, str(SOAK), "--plot-only", str(bad)],
                         capture_output=True, text=True, timeout=120, check=False, cwd=ROOT)
    assert res.returncode == 2 and "--plot-only needs --plot" in res.stderr
    res = subprocess.run([sys.executable, str(SOAK), "--plot-only", str(bad), "--plot", str(tmp_path / "x.png")],
                         capture_output=True, text=True, timeout=120, check=False, cwd=ROOT)
    assert res.returncode == 2 and "bad.json" in res.stderr and "no samples" in res.stderr
    assert not (tmp_path / "x.png").exists()


def test_latest_only_frame_skips_are_reported_apart_from_drops(soak: ModuleType) -> None:
    final = {"detector": {"drops": {"dropped_stale": 53.0}},
             "embedder": {"drops": {"dropped_stale": 1.0, "dropped_unpaired": 2.0}},
             "localizer": {"drops": {"dropped_no_depth_frame": 4.0, "dropped_no_transform": 1.0}},
             "tracker": {"drops": {"dropped_late_embeddings": 3.0}}, "router": {}}
    lost, skipped = soak.split_drops(final)
    assert skipped == {"detector": {"dropped_stale": 53.0}, "embedder": {"dropped_stale": 1.0},
                       "localizer": {"dropped_no_depth_frame": 4.0}}
    assert lost == {"embedder": {"dropped_unpaired": 2.0}, "localizer": {"dropped_no_transform": 1.0},
                    "tracker": {"dropped_late_embeddings": 3.0}}
