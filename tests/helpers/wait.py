"""Waiting for something to happen: poll a condition until a deadline, never sleep a fixed time.

A fixed ``time.sleep`` is too short on a loaded machine (a flaky test) and too long on an idle
one (a slow test); :func:`wait_until` returns as soon as the condition holds and fails, naming
what it waited for, only when a generous deadline has passed.
"""

from __future__ import annotations

import time
from typing import Callable, TypeVar

__all__ = ["wait_until"]

T = TypeVar("T")


def wait_until(predicate: Callable[[], T], timeout: float, interval: float = 0.02,
               what: str | Callable[[], str] = "the condition") -> T:
    """Call ``predicate`` every ``interval`` s until it returns something truthy; that value.

    AssertionError naming ``what`` once ``timeout`` s have passed (``what`` may be a callable,
    called then, e.g. to add a log's tail). An exception the predicate raises (an assertion
    that a child process is still running) ends the wait at once.
    """
    deadline = time.monotonic() + timeout
    while True:
        value = predicate()
        if value:
            return value
        if time.monotonic() >= deadline:
            raise AssertionError(f"timed out after {timeout:g} s waiting for {what() if callable(what) else what}")
        time.sleep(interval)  # the poll interval, not a wait
