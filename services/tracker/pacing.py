"""When the tracker service publishes: once per input frame, or at a fixed rate (TU Ilmenau) with
the latest update's tracks predicted to the publish time.

* Once per frame (``output_rate_hz`` 0): the newest result after each push, once per input frame (a
  late frame applied behind a newer one changes what the next output shows, no second output); a
  frame of the newest instant applied behind another stream's of that instant (two detectors on
  one camera image) is published as its own frame.
* At a fixed rate: every period the latest result predicted to now in the sensor's clock; a long
  frame makes no burst, the next output comes a period on.
"""

from __future__ import annotations

from typing import Generic, TypeVar

from services.tracker.core import FrameResult
from services.tracker.reorder import InputKey

__all__ = ["Pacing"]

F = TypeVar("F")  # a frame as the reorder buffer keeps it


class Pacing(Generic[F]):
    """The output's timing; ``rate_hz`` 0: once per input frame."""

    def __init__(self, rate_hz: float) -> None:
        self.period = 1.0 / rate_hz if rate_hz > 0 else None
        self._next: float | None = None
        self._latest: tuple[F, FrameResult] | None = None
        self._published: set[InputKey] = set()  # once per frame: the frames published of the newest instant
        self._offset_ns: int | None = None  # sensor clock - this clock, at the newest frame

    def pushed(self, key: InputKey, frame: F, stamp_ns: int, result: FrameResult,
               now: float) -> tuple[F, FrameResult] | None:
        """After a push whose newest frame is ``frame`` (``key``, stamped ``stamp_ns``) with
        ``result``: what to publish now (once per frame), else None (kept for the fixed rate)."""
        if self.period is None:
            newest = max(self._published, default=None)
            if key in self._published or (newest is not None and key[0] < newest[0]):
                return None
            if newest is not None and key[0] > newest[0]:
                self._published.clear()
            self._published.add(key)
            return frame, result
        self._latest = (frame, result)  # published at the fixed rate, predicted to the publish time
        self._offset_ns = stamp_ns - int(now * 1e9)
        return None

    def tick(self, now: float) -> tuple[F, FrameResult, int] | None:
        """At the fixed rate: the latest frame and result and the sensor-clock stamp to
        predict them to, when an output is due; else None."""
        if self.period is None or self._latest is None or self._offset_ns is None:
            return None
        if self._next is None:
            self._next = now
        if now < self._next:
            return None
        self._next += self.period
        if self._next <= now:  # fell behind (a long frame): no burst, the next tick a period on
            self._next = now + self.period
        frame, result = self._latest
        return frame, result, int(now * 1e9) + self._offset_ns

    def deadline(self, now: float) -> float | None:
        """Seconds until the next fixed-rate output is due (None: none is)."""
        if self.period is None or self._next is None or self._latest is None:
            return None
        return max(0.0, self._next - now)

    def restart(self) -> None:
        """A new clock: the next frame is published whatever its key."""
        self._published.clear()
