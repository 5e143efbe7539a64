"""A pan/tilt head that obeys velocity commands (the attention node's HeadCommand).

The angles are integrated in simulated time: a command sets the joint rates from the
moment it is applied until a newer one comes or its ``timeout_s`` runs out (then the head
stops, as a real head's driver does when its commander goes quiet). Rates are clipped to
the head's own limits and the angles to its joint range.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

__all__ = ["CommandedHead"]


@dataclass
class CommandedHead:
    """Pan and tilt (rad) integrated from commanded rates; ``angles(t)`` needs non-decreasing ``t``."""

    pan: float = 0.0
    tilt: float = 0.1
    max_rate: float = 2.0  # rad/s, the motors' limit
    pan_range: tuple[float, float] = (-2.6, 2.6)
    tilt_range: tuple[float, float] = (-0.6, 0.9)
    _t: float = 0.0
    _pan_rate: float = 0.0
    _tilt_rate: float = 0.0
    _until: float = -np.inf

    def _advance(self, t: float) -> None:
        if t <= self._t:
            return
        moving = max(0.0, min(t, self._until) - self._t)
        self.pan = float(np.clip(self.pan + self._pan_rate * moving, *self.pan_range))
        self.tilt = float(np.clip(self.tilt + self._tilt_rate * moving, *self.tilt_range))
        self._t = t

    def command(self, t: float, pan_rate: float, tilt_rate: float, timeout_s: float) -> None:
        """Turn at these rates (rad/s) from ``t`` on, for at most ``timeout_s``."""
        self._advance(t)
        self._pan_rate = float(np.clip(pan_rate, -self.max_rate, self.max_rate))
        self._tilt_rate = float(np.clip(tilt_rate, -self.max_rate, self.max_rate))
        self._until = max(t, self._t) + timeout_s

    def angles(self, t: float) -> tuple[float, float]:
        """(pan, tilt) at ``t``."""
        self._advance(t)
        return self.pan, self.tilt
