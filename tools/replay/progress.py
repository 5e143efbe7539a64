"""Replay progress: one ``\\r``-refreshed line on a terminal, periodic log lines otherwise."""

from __future__ import annotations

import logging
import sys
import time
from typing import TextIO

from tools.replay.core.timeline import RateMeter

__all__ = ["Progress"]

log = logging.getLogger(__name__)


class Progress:
    """Position in the file (s and %), messages sent, achieved msg/s, MB/s and speed.

    ``stream`` is written to only when it is a TTY; otherwise a log line goes out every
    ``log_period_s`` seconds. ``enabled=False`` shows nothing.
    """

    def __init__(self, total_s: float, stream: TextIO | None = None, enabled: bool = True,
                 log_period_s: float = 5.0, refresh_s: float = 0.1) -> None:
        self.total_s = total_s
        self.stream = stream if stream is not None else sys.stderr
        self.enabled = enabled
        self.tty = enabled and self.stream.isatty()
        self.period_s = refresh_s if self.tty else log_period_s
        self.meter = RateMeter()
        self.sent = 0
        self._last_show = time.monotonic()
        self._wall0 = time.monotonic()
        self._pos0: float | None = None
        self._pos = 0.0
        self._drawn = False

    def restart(self) -> None:
        """A new pass over the file (``--loop``): speed is measured afresh."""
        self._wall0 = time.monotonic()
        self._pos0 = None

    def update(self, position_s: float, nbytes: int) -> None:
        self.sent += 1
        self.meter.add(nbytes)
        now = time.monotonic()
        if self._pos0 is None:
            self._pos0, self._wall0 = position_s, now
        self._pos = position_s
        if self.enabled and now - self._last_show >= self.period_s:
            self._last_show = now
            self._show()

    def line(self) -> str:
        msgs, bps = self.meter.rates()
        pct = 100.0 * self._pos / self.total_s if self.total_s > 0 else 100.0
        wall = time.monotonic() - self._wall0
        speed = (self._pos - (self._pos0 or 0.0)) / wall if wall > 0 else 0.0
        return (f"{self._pos:7.1f}/{self.total_s:.1f} s {min(pct, 100.0):5.1f}%  {self.sent} msgs  "
                f"{msgs:6.1f} msg/s  {bps / 1e6:6.1f} MB/s  x{speed:.2f}")

    def _show(self) -> None:
        if self.tty:
            self.stream.write("\r" + self.line() + "\x1b[K")
            self.stream.flush()
            self._drawn = True
        else:
            log.info("replay: %s", self.line())

    def close(self) -> None:
        if self.tty and self._drawn:
            self.stream.write("\r" + self.line() + "\x1b[K\n")
            self.stream.flush()
