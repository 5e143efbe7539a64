"""``perception launch`` as a child process of a test, its merged output collected line by line."""

from __future__ import annotations

import os
import re
import subprocess
import sys
import threading
from collections.abc import Callable
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
CHILD = str(ROOT / "tests" / "helpers" / "launch_child.py")
PY = sys.executable
TIMEOUT = 60.0  # generous: the test machine is shared and slow


class Launch:
    """``python -m perception launch FILE`` with its merged output collected line by line."""

    def __init__(self, file: Path, env: dict[str, str] | None = None, *args: str) -> None:
        full_env = {**os.environ, "PY": PY, "CHILD": CHILD, "RUST_LOG": "error", **(env or {})}
        self.proc = subprocess.Popen([PY, "-m", "perception", "launch", str(file), "--color", "never", *args],
                                     stdout=subprocess.PIPE, stderr=subprocess.STDOUT, env=full_env, cwd=ROOT)
        self.lines: list[str] = []
        self._cond = threading.Condition()
        self._reader = threading.Thread(target=self._read, daemon=True)
        self._reader.start()

    def _read(self) -> None:
        assert self.proc.stdout is not None
        for raw in self.proc.stdout:
            with self._cond:
                self.lines.append(raw.decode(errors="replace").rstrip("\n"))
                self._cond.notify_all()

    def wait_for(self, predicate: Callable[[list[str]], bool], what: str, timeout: float = TIMEOUT) -> None:
        with self._cond:
            if not self._cond.wait_for(lambda: predicate(self.lines) or self.proc.poll() is not None, timeout):
                pytest.fail(f"timed out waiting for {what}; output:\n" + "\n".join(self.lines))
            if not predicate(self.lines):
                pytest.fail(f"launcher exited ({self.proc.returncode}) before {what}; output:\n" + "\n".join(self.lines))

    def count(self, pattern: str) -> int:
        with self._cond:
            return sum(1 for line in self.lines if re.search(pattern, line))

    def finish(self, timeout: float = TIMEOUT) -> int:
        rc = self.proc.wait(timeout=timeout)
        self._reader.join(timeout=10)
        return rc

    def output(self) -> str:
        with self._cond:
            return "\n".join(self.lines)

    def kill(self) -> None:
        if self.proc.poll() is None:
            self.proc.kill()
            self.proc.wait()
