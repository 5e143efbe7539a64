"""Log a recurring problem at most once per period, saying how many were not logged.

A node that drops a bad input at 30 Hz must say so, but not 30 times a second. Each
*reason* (``"no_depth"``, ``"too_old"``...) has its own period, so one noisy reason does
not hide another.
"""

from __future__ import annotations

import logging
import time
from typing import Callable

__all__ = ["RateLimitedLog"]


class RateLimitedLog:
    """``warning``/``error``/``info`` at most once per ``period_s`` per reason.

    The line logged after a quiet period ends with ``(N more since the last report)``
    when N lines of that reason were held back.
    """

    def __init__(self, logger: logging.Logger, period_s: float = 1.0,
                 clock: Callable[[], float] = time.monotonic) -> None:
        self.logger = logger
        self.period_s = period_s
        self.clock = clock
        self._last: dict[str, float] = {}
        self._skipped: dict[str, int] = {}

    def log(self, level: int, reason: str, fmt: str, *args: object) -> bool:
        """Log unless ``reason`` was logged less than ``period_s`` ago; True if logged."""
        now = self.clock()
        last = self._last.get(reason)
        if last is not None and now - last < self.period_s:
            self._skipped[reason] = self._skipped.get(reason, 0) + 1
            return False
        skipped = self._skipped.pop(reason, 0)
        self._last[reason] = now
        self.logger.log(level, fmt + (f" ({skipped} more since the last report)" if skipped else ""), *args)
        return True

    def warning(self, reason: str, fmt: str, *args: object) -> bool:
        return self.log(logging.WARNING, reason, fmt, *args)

    def error(self, reason: str, fmt: str, *args: object) -> bool:
        return self.log(logging.ERROR, reason, fmt, *args)

    def info(self, reason: str, fmt: str, *args: object) -> bool:
        return self.log(logging.INFO, reason, fmt, *args)
