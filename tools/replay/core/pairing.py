"""Pair colour and depth images into RGB-D frames by stamp.

Input comes in recording order, each stream with non-decreasing stamps. A colour image
is paired with the depth image nearest in stamp, within ``tolerance_ns``. It is decided
as soon as a depth image stamped at or after it has arrived (no later depth can be
nearer), or once the colour stream is ``hold_ns`` ahead (the depth is missing), or at
the end of the input. Generic over the payload type, so it is tested with plain ints.
"""

from __future__ import annotations

from collections import deque
from dataclasses import dataclass, field
from typing import Generic, TypeVar

__all__ = ["PairStats", "RgbdPairer"]

P = TypeVar("P")


@dataclass
class PairStats:
    paired: int = 0
    rgb_without_depth: int = 0
    depth_unused: int = 0


@dataclass
class RgbdPairer(Generic[P]):
    """Nearest-stamp pairing of colour and depth images.

    ``expect_depth=False`` (no depth topic) releases every colour image at once, alone.
    Outputs are ``(rgb_stamp_ns, rgb, depth or None)`` in colour-stamp order.
    """

    tolerance_ns: int = 20_000_000
    hold_ns: int = 1_000_000_000
    expect_depth: bool = True
    stats: PairStats = field(default_factory=PairStats)
    _rgb: deque[tuple[int, P]] = field(default_factory=deque)
    _depth: deque[tuple[int, P]] = field(default_factory=deque)

    def add_rgb(self, stamp_ns: int, rgb: P) -> list[tuple[int, P, P | None]]:
        self._rgb.append((stamp_ns, rgb))
        return self._release(final=False)

    def add_depth(self, stamp_ns: int, depth: P) -> list[tuple[int, P, P | None]]:
        self._depth.append((stamp_ns, depth))
        return self._release(final=False)

    def flush(self) -> list[tuple[int, P, P | None]]:
        out = self._release(final=True)
        self.stats.depth_unused += len(self._depth)
        self._depth.clear()
        return out

    def _release(self, final: bool) -> list[tuple[int, P, P | None]]:
        out: list[tuple[int, P, P | None]] = []
        while self._rgb:
            stamp, rgb = self._rgb[0]
            if not self.expect_depth:
                self._rgb.popleft()
                out.append((stamp, rgb, None))
                continue
            depth_caught_up = bool(self._depth) and self._depth[-1][0] >= stamp
            rgb_ran_ahead = self._rgb[-1][0] - stamp > self.hold_ns
            if not (final or depth_caught_up or rgb_ran_ahead):
                break
            self._rgb.popleft()
            out.append((stamp, rgb, self._take_depth(stamp)))
        return out

    def _take_depth(self, stamp: int) -> P | None:
        # Drop depth images too old for this (and so for any later) colour image.
        while self._depth and self._depth[0][0] < stamp - self.tolerance_ns:
            self._depth.popleft()
            self.stats.depth_unused += 1
        best_i, best_gap = -1, self.tolerance_ns + 1
        for i, (d_stamp, _) in enumerate(self._depth):
            gap = abs(d_stamp - stamp)
            if gap < best_gap:
                best_i, best_gap = i, gap
            if d_stamp > stamp:
                break
        if best_i < 0:
            self.stats.rgb_without_depth += 1
            return None
        for _ in range(best_i):  # older than the chosen one: no later colour image is nearer
            self._depth.popleft()
            self.stats.depth_unused += 1
        self.stats.paired += 1
        return self._depth.popleft()[1]
