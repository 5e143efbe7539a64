"""Progress bars: on a terminal a count and an ETA, otherwise nothing at all."""

from __future__ import annotations

import fcntl
import io
import os
import struct
import subprocess
import sys
import termios
from pathlib import Path

import pytest

from common.runtime.progress import progress

KITTI = Path(__file__).resolve().parents[3] / "shared" / "data" / "kitti_ped_dev" / "dets_0000.csv"


def test_off_a_terminal_the_items_pass_through_unchanged() -> None:
    items = [1, 2, 3]
    assert progress(items, total=3) is items  # pytest's stderr is not a terminal


def test_on_a_terminal_the_bar_counts_and_keeps_the_items(monkeypatch: pytest.MonkeyPatch) -> None:
    err = io.StringIO()
    monkeypatch.setattr(sys, "stderr", err)
    assert list(progress(range(5), total=5, desc="work", unit="frame", enabled=True)) == [0, 1, 2, 3, 4]
    assert "work" in err.getvalue() and "0/5" in err.getvalue() and "frame" in err.getvalue()


def _run_on_a_terminal(argv: list[str]) -> tuple[int, str]:
    """Run a command with stderr on an 80x24 pseudo-terminal; (status, what the terminal showed)."""
    main, child = os.openpty()
    fcntl.ioctl(child, termios.TIOCSWINSZ, struct.pack("HHHH", 24, 80, 0, 0))  # a terminal has a size
    proc = subprocess.Popen(argv, stdout=subprocess.DEVNULL, stderr=child, env={**os.environ, "RUST_LOG": "error"})
    os.close(child)
    shown = b""
    while True:
        try:
            chunk = os.read(main, 4096)
        except OSError:
            break
        if not chunk:
            break
        shown += chunk
    os.close(main)
    return proc.wait(60), shown.decode(errors="replace")


def test_simulate_output_shows_its_progress_only_on_a_terminal(tmp_path: Path) -> None:
    cmd = [sys.executable, "-m", "perception", "simulate", "--scenario", "still", "--duration", "1", "--fps", "10",
           "--width", "96", "--height", "72"]
    status, shown = _run_on_a_terminal([*cmd, "--output", str(tmp_path / "a.mcap")])
    assert status == 0 and "simulate" in shown and "/10" in shown and "frame" in shown
    res = subprocess.run([*cmd, "--output", str(tmp_path / "b.mcap")], capture_output=True, text=True, timeout=60,
                         check=False)
    assert res.returncode == 0 and "/10" not in res.stderr and "\r" not in res.stderr


@pytest.mark.skipif(not KITTI.is_file(), reason="../shared/data/kitti_ped_dev is not there")
def test_track_shows_its_progress_on_a_terminal_and_writes_the_same_rows(tmp_path: Path) -> None:
    cmd = [sys.executable, "-m", "perception", "track", "--detections", str(KITTI)]
    status, shown = _run_on_a_terminal([*cmd, "--output", str(tmp_path / "a.csv")])
    assert status == 0 and "track" in shown and "frame" in shown, shown[-500:]
    res = subprocess.run([*cmd, "--output", str(tmp_path / "b.csv")], capture_output=True, text=True, timeout=60,
                         check=False)
    assert res.returncode == 0 and "\r" not in res.stderr
    assert (tmp_path / "a.csv").read_text() == (tmp_path / "b.csv").read_text()
