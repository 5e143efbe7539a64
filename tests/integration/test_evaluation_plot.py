"""``perception evaluate --plot``: a top-down PNG per sequence with the events marked."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from tools.evaluation.evaluate import evaluate_tables
from tools.evaluation.plot import SequencePlot, plot_sequences
from tools.evaluation.readers import TrackTable

pytest.importorskip("matplotlib", reason="plots need matplotlib (the 'view' extra)")

GT = """frame,id,x,y,z
1,1,0.0,0.0,1.0
1,2,5.0,0.0,1.0
2,1,0.0,0.5,1.0
2,2,5.0,0.5,1.0
3,1,0.0,1.0,1.0
4,1,0.0,1.5,1.0
5,1,0.0,2.0,1.0
"""
# track 8 takes person 1 over in frame 4 (an ID switch), track 9 is a false positive,
# and person 1 is missed in frame 3
TRACKS = """frame,stamp,id,x,y,z
1,0.0,7,0.1,0.0,1.0
1,0.0,8,5.0,0.2,1.0
2,0.1,7,0.1,0.5,1.0
2,0.1,8,5.0,0.6,1.0
2,0.1,9,2.5,2.5,1.0
4,0.3,8,0.2,1.5,1.0
5,0.4,8,0.2,2.0,1.0
"""


def _decode(png: Path) -> np.ndarray:
    import cv2

    img = cv2.imread(str(png), cv2.IMREAD_COLOR)
    assert img is not None
    return img


def test_cli_writes_the_plot_with_the_events(tmp_path: Path) -> None:
    (tmp_path / "gt.csv").write_text(GT)
    (tmp_path / "tracks.csv").write_text(TRACKS)
    out = tmp_path / "plots" / "run.png"
    res = subprocess.run([sys.executable, "-m", "perception", "evaluate", "--gt", str(tmp_path / "gt.csv"),
                          "--tracks", str(tmp_path / "tracks.csv"), "--plot", str(out)],
                         capture_output=True, text=True, timeout=120, check=False)
    assert res.returncode == 0, res.stderr
    assert f"plot: {out}" in res.stdout and "MOTA" in res.stdout
    img = _decode(out)
    assert img.shape[0] > 300 and img.shape[1] > 300 and img.std() > 5


def test_the_panel_counts_and_title_match_the_evaluation(tmp_path: Path) -> None:
    from io import StringIO

    def table(text: str, skip: int) -> TrackTable:
        rows = np.loadtxt(StringIO(text), delimiter=",", skiprows=1)
        return TrackTable.from_arrays(rows[:, 0], rows[:, skip], rows[:, skip + 1:skip + 4][:, :2])

    gt, hyp = table(GT, 1), table(TRACKS, 2)
    panel = SequencePlot("toy", gt, hyp)
    panel.result = evaluate_tables(gt, hyp, on_frame=panel.on_frame)
    events = panel.events.values()
    assert sum(len(e.switches) for e in events) == panel.result.id_switches == 1
    assert sum(len(e.false_positives) for e in events) == panel.result.false_positives == 1
    assert sum(len(e.misses) for e in events) == panel.result.misses == 1
    from matplotlib.figure import Figure

    fig = Figure()
    from tools.evaluation import plot

    ax = fig.subplots()
    plot._panel(ax, panel)
    title = ax.get_title()
    assert title.startswith("toy: MOTA") and "IDSW 1" in title
    labels = [t.get_text() for t in ax.get_legend().get_texts()]
    assert {"miss (1)", "false positive (1)", "ID switch (1)", "ground truth"} <= set(labels)
    out = plot_sequences([panel, panel], tmp_path / "two.png")
    assert _decode(out).shape[1] > _decode(plot_sequences([panel], tmp_path / "one.png")).shape[1]


def test_without_matplotlib_the_error_says_how_to_get_it(tmp_path: Path) -> None:
    (tmp_path / "gt.csv").write_text(GT)
    (tmp_path / "tracks.csv").write_text(TRACKS)
    code = ("import sys; sys.modules['matplotlib'] = None; from perception.cli import main; "
            f"sys.exit(main(['evaluate', '--gt', {str(tmp_path / 'gt.csv')!r}, '--tracks', "
            f"{str(tmp_path / 'tracks.csv')!r}, '--plot', {str(tmp_path / 'x.png')!r}]))")
    res = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120, check=False)
    assert res.returncode == 2 and "people-perception[view]" in res.stderr


def test_the_demo_chain_draws_its_run(tmp_path: Path) -> None:
    from tools.demo.inprocess import run_chain

    out = tmp_path / "demo.png"
    result = run_chain("still", duration_s=2.0, fps=5.0, width=160, height=120, plot=out)
    assert result.frames >= 10
    assert _decode(out).std() > 5
