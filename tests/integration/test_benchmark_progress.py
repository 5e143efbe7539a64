"""Progress of the long benchmarks: on a terminal a bar with a count and an ETA on stderr, and the
same results on stdout; off a terminal no bar at all. A hand-advanced bar (``progress_bar``)
keeps printed lines whole by writing them above itself."""

from __future__ import annotations

import fcntl
import io
import os
import re
import struct
import subprocess
import sys
import termios
import threading
from pathlib import Path

import pytest

from common.runtime.progress import progress_bar

ROOT = Path(__file__).resolve().parents[2]
#: The tracker benchmark cut to 3 cases (about a second): 1 person x 1 gallery, and two `track` files.
TRACKER_BENCH = [sys.executable, str(ROOT / "benchmarks" / "tracker.py"), "--reps", "3", "--people", "1",
                 "--gallery", "10", "--offline-frames", "10", "--profiles", "robust"]


def _run_with_stderr_on_a_terminal(argv: list[str]) -> tuple[int, str, str]:
    """Run with stderr on an 80x24 pseudo-terminal and stdout in a pipe; (status, stdout, what the terminal showed)."""
    main, child = os.openpty()
    fcntl.ioctl(child, termios.TIOCSWINSZ, struct.pack("HHHH", 24, 80, 0, 0))  # a terminal has a size
    proc = subprocess.Popen(argv, stdout=subprocess.PIPE, stderr=child, cwd=ROOT, env={**os.environ, "RUST_LOG": "error"})
    os.close(child)
    out: list[bytes] = []
    reader = threading.Thread(target=lambda: out.append(proc.stdout.read() if proc.stdout else b""))
    reader.start()
    shown = b""
    while True:
        try:
            chunk = os.read(main, 4096)
        except OSError:  # EIO: the child closed the terminal
            break
        if not chunk:
            break
        shown += chunk
    os.close(main)
    status = proc.wait(120)
    reader.join(30)
    return status, b"".join(out).decode(), shown.decode(errors="replace")


def _shape(stdout: str) -> list[str]:
    """The results' lines without their measured numbers."""
    return [re.sub(r"\d+(\.\d+)?", "#", line) for line in stdout.splitlines()]


def test_the_tracker_benchmark_shows_a_bar_only_on_a_terminal() -> None:
    status, stdout, shown = _run_with_stderr_on_a_terminal(TRACKER_BENCH)
    assert status == 0, shown[-2000:]
    assert "tracker" in shown and "/3" in shown and "case" in shown, shown[-2000:]
    assert "<" in shown  # tqdm's elapsed<remaining (the ETA)
    assert "\r" not in stdout and "case/s" not in stdout  # the bar never reaches the results
    res = subprocess.run(TRACKER_BENCH, capture_output=True, text=True, timeout=120, cwd=ROOT, check=False)
    assert res.returncode == 0, res.stderr
    assert "/3" not in res.stderr and "\r" not in res.stderr
    assert _shape(res.stdout) == _shape(stdout)
    assert "| 1 |" in res.stdout and "perception track (robust), 10 people" in res.stdout


def test_a_hidden_bar_counts_nothing_and_leaves_stdout_alone(capsys: pytest.CaptureFixture[str]) -> None:
    out = sys.stdout
    with progress_bar(5, desc="work") as bar:  # pytest's stderr is not a terminal
        assert sys.stdout is out
        bar.update()
        print("row 1")
    captured = capsys.readouterr()
    assert captured.out == "row 1\n" and captured.err == ""


class _Terminal(io.StringIO):
    def isatty(self) -> bool:
        return True


def test_lines_printed_under_a_shown_bar_go_above_it_whole(monkeypatch: pytest.MonkeyPatch) -> None:
    err, out = _Terminal(), _Terminal()
    monkeypatch.setattr(sys, "stderr", err)
    monkeypatch.setattr(sys, "stdout", out)
    with progress_bar(2, desc="work", unit="case") as bar:
        print("| a |", end="")
        assert out.getvalue() == ""  # half a line waits for its end
        print(" 1 |")
        bar.update()
        print("tail without newline", end="")
    assert sys.stdout is out
    assert out.getvalue() == "| a | 1 |\ntail without newline"
    assert "work" in err.getvalue() and "0/2" in err.getvalue() and "case" in err.getvalue()
