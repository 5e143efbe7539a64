"""Waiting on a live ``perception record`` process through its status counters."""

from __future__ import annotations

import signal
import subprocess
import time

from common.messages.keys import Keys
from common.transport.base import Transport


def wait_recorded(client: Transport, keys: Keys, n: int, timeout_s: float) -> float:
    """Poll the recorder's ``recorded`` counter until it reaches ``n`` (or ``timeout_s``); its value."""
    deadline = time.monotonic() + timeout_s
    recorded = 0.0
    while time.monotonic() < deadline:
        replies = client.query(keys.status("record", "*"), timeout=2.0)
        recorded = max([m.extra.get("recorded", 0.0) for _, m in replies] + [0.0])
        if recorded >= n:
            return recorded
        time.sleep(0.1)  # polling a remote counter, not synchronising on time
    return recorded


def stop_recording(recorder: subprocess.Popen[str], timeout_s: float) -> tuple[str, str]:
    """Stop a ``perception record`` process as a user would (SIGINT) and return its (stdout,
    stderr); killed if it has not ended within ``timeout_s``."""
    recorder.send_signal(signal.SIGINT)
    try:
        return recorder.communicate(timeout=timeout_s)
    finally:
        if recorder.poll() is None:
            recorder.kill()
            recorder.wait()
