"""Start ``perception router`` as a child process on loopback, for the demo, self-check and tests."""

from __future__ import annotations

import os
from typing import Any
import signal
import socket
import subprocess
import sys
import tempfile
import time

__all__ = ["RouterProcess", "free_port", "wait_for_port"]


def free_port(host: str = "127.0.0.1") -> int:
    """A TCP port that nothing listens on right now."""
    with socket.socket(socket.AF_INET, socket.SOCK_STREAM) as s:
        s.bind((host, 0))
        return int(s.getsockname()[1])


def wait_for_port(host: str, port: int, timeout: float, proc: subprocess.Popen[bytes] | None = None) -> bool:
    """Poll until ``host:port`` accepts a TCP connection (or ``proc`` exits, or time runs out)."""
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        if proc is not None and proc.poll() is not None:
            return False
        try:
            with socket.create_connection((host, port), timeout=0.2):
                return True
        except OSError:
            time.sleep(0.02)
    return False


class RouterProcess:
    """A ``perception router`` child process listening on ``tcp/HOST:PORT``, multicast off."""

    def __init__(self, port: int | None = None, host: str = "127.0.0.1", extra_args: tuple[str, ...] = (),
                 log_path: str | None = None) -> None:
        self.host = host
        self.port = port or free_port(host)
        self.extra_args = extra_args
        self.log_path = log_path
        self.proc: subprocess.Popen[bytes] | None = None
        self._log: Any = None

    @property
    def endpoint(self) -> str:
        return f"tcp/{self.host}:{self.port}"

    def start(self, timeout: float = 15.0) -> RouterProcess:
        cmd = [sys.executable, "-m", "perception", "-q", "router", "--listen", self.endpoint,
               "--no-multicast-scouting", *self.extra_args]
        # A file, not a pipe: a pipe nobody reads would block a chatty router.
        # "a+b": appended to, and readable back when the router fails to start
        self._log = open(self.log_path, "a+b") if self.log_path else tempfile.TemporaryFile()  # noqa: SIM115
        env = {**os.environ, "RUST_LOG": os.environ.get("RUST_LOG", "error")}
        self.proc = subprocess.Popen(cmd, stdout=self._log, stderr=subprocess.STDOUT, env=env)
        if not wait_for_port(self.host, self.port, timeout, self.proc):
            self.stop()
            self._log.seek(0)
            err = self._log.read()[-2000:]
            raise RuntimeError(f"router on {self.endpoint} did not come up within {timeout} s: {err.decode(errors='replace').strip()}")
        return self

    def kill(self) -> None:
        """SIGKILL, as a crash would."""
        if self.proc is not None and self.proc.poll() is None:
            self.proc.send_signal(signal.SIGKILL)
            self.proc.wait(timeout=10)

    def stop(self, timeout: float = 5.0) -> None:
        """SIGTERM, then SIGKILL if it does not exit in time."""
        if self.proc is None:
            return
        if self.proc.poll() is None:
            self.proc.terminate()
            try:
                self.proc.wait(timeout=timeout)
            except subprocess.TimeoutExpired:
                self.kill()
        self.proc = None

    def __enter__(self) -> RouterProcess:
        return self.start() if self.proc is None else self

    def __exit__(self, *exc: object) -> None:
        self.stop()
