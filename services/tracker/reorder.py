"""Out-of-order inputs (TU Ilmenau, section 4): apply in sensor-time order, rewinding if needed.

An input newer than everything applied is applied at once (an in-order stream costs no latency);
one that arrives late, but within ``window_s`` of the newest stamp, makes the buffer restore the
latest snapshot before it and apply the logged inputs from there in stamp order; anything older is
counted and dropped. An input still in the log may be *replaced* (``push(..., replace=True)``: a
frame applied by position alone whose appearance came late), with the same rewind. Snapshots are
taken at most every ``snapshot_period_s`` of sensor time (tracker snapshots share descriptors
copy-on-write: cheap), and the log keeps every input back to the oldest snapshot still needed.
A stamp far behind its source's newest is a new clock (a replay that loops), no late input:
:class:`ClockJumps` tells one, and :meth:`ReorderBuffer.reset` starts over.
"""

from __future__ import annotations

import bisect
from dataclasses import dataclass, field
from typing import Callable, Generic, TypeVar

__all__ = ["ClockJumps", "InputKey", "ReorderBuffer"]

In = TypeVar("In")  # an input
S = TypeVar("S")  # a snapshot of the consumer's state
R = TypeVar("R")  # what applying an input returns

#: (stamp_ns, source, seq): the sort order of inputs.
InputKey = tuple[int, str, int]
_BEFORE_ALL: InputKey = (-1, "", -1)


@dataclass
class ReorderBuffer(Generic[In, S, R]):
    """Applies inputs in key order through ``apply``; ``snapshot``/``restore`` rewind."""

    apply: Callable[[In], R]
    snapshot: Callable[[], S]
    restore: Callable[[S], None]
    window_ns: int = 500_000_000
    snapshot_period_ns: int = 100_000_000
    dropped_old: int = 0
    dropped_duplicate: int = 0
    rewinds: int = 0
    _log: list[tuple[InputKey, In]] = field(default_factory=list)
    _snaps: list[tuple[InputKey, S]] = field(default_factory=list)
    newest_ns: int | None = None

    def __post_init__(self) -> None:
        self._snaps.append((_BEFORE_ALL, self.snapshot()))

    def push(self, key: InputKey, item: In, replace: bool = False) -> list[R]:
        """Apply ``item``; the results of every input applied (several after a rewind, ``[]`` when
        dropped: too old, or a duplicate key). ``replace``: the input of the same key still in the
        log is replaced and everything from it on applied again (one no longer there: too old)."""
        if self.newest_ns is not None and key[0] < self.newest_ns - self.window_ns:
            self.dropped_old += 1
            return []
        pos, logged = self._find(key)
        if logged:
            if not replace or key < self._snaps[0][0]:
                self.dropped_duplicate += int(not replace)
                self.dropped_old += int(replace)
                return []
            del self._log[pos]
            results = self._rewind(key, item)
            self._prune()
            return results
        if replace:
            self.dropped_old += 1  # nothing to replace: it left the log (or never came)
            return []
        if pos == len(self._log):
            results = [self._apply(key, item)]
        elif key < self._snaps[0][0]:
            self.dropped_old += 1  # older than every snapshot kept: cannot be placed in order
            return []
        else:
            results = self._rewind(key, item)
        self._prune()
        return results

    def reset(self) -> None:
        """Forget every input and snapshot, and the newest stamp (a clock jump: stamps start
        over). The consumer's state now is the new starting point; the counts stay."""
        self._log.clear()
        self._snaps.clear()
        self.newest_ns = None
        self._snaps.append((_BEFORE_ALL, self.snapshot()))

    def rebase(self) -> None:
        """Make the consumer's state now the only one to rewind to: earlier snapshots may
        hold what must not come back (a forgotten person). Inputs older than the newest
        applied one are dropped as too old from now on."""
        last = self._log[-1:]
        self._log = list(last)
        self._snaps = [(last[0][0] if last else _BEFORE_ALL, self.snapshot())]

    def _find(self, key: InputKey) -> tuple[int, bool]:
        """Where ``key`` is, or would go, in the log, and whether it is there."""
        keys = [k for k, _ in self._log]
        pos = bisect.bisect_left(keys, key)
        return pos, pos < len(keys) and keys[pos] == key

    def get(self, key: InputKey) -> In | None:
        """The input logged under ``key`` (still replaceable), or None."""
        pos, logged = self._find(key)
        return self._log[pos][1] if logged else None

    def latest(self) -> tuple[InputKey, In] | None:
        """The newest input applied (key, input), or None."""
        return self._log[-1] if self._log else None

    def _apply(self, key: InputKey, item: In) -> R:
        if key[0] - self._snaps[-1][0][0] >= self.snapshot_period_ns:
            self._snaps.append((key, self.snapshot()))
        result = self.apply(item)
        self._log.append((key, item))
        self.newest_ns = key[0] if self.newest_ns is None else max(self.newest_ns, key[0])
        return result

    def _rewind(self, key: InputKey, item: In) -> list[R]:
        self.rewinds += 1
        # the latest snapshot taken before anything at or after ``key`` was applied
        i = bisect.bisect_right([k for k, _ in self._snaps], key) - 1
        snap_key, state = self._snaps[i]
        del self._snaps[i + 1 :]
        self.restore(state)
        split = bisect.bisect_left([k for k, _ in self._log], snap_key)
        replay = sorted(self._log[split:] + [(key, item)], key=lambda kv: kv[0])
        del self._log[split:]
        results = []
        for k, it in replay:
            if k == snap_key:
                # re-applying the input the snapshot was taken before: keep that snapshot
                results.append(self.apply(it))
                self._log.append((k, it))
            else:
                results.append(self._apply(k, it))
        return results

    def _prune(self) -> None:
        """Forget snapshots and inputs no accepted late input can need any more."""
        if self.newest_ns is None:
            return
        boundary = self.newest_ns - self.window_ns
        # keep the newest snapshot at or before the boundary, and everything after it
        keep = 0
        for j, (k, _) in enumerate(self._snaps):
            if k[0] <= boundary:
                keep = j
        if keep:
            del self._snaps[:keep]
        oldest = self._snaps[0][0]
        split = bisect.bisect_left([k for k, _ in self._log], oldest)
        if split:
            del self._log[:split]


@dataclass
class ClockJumps:
    """Watches each source's stamps for a jump back by more than ``jump_ns`` (a replay that
    loops, a sensor clock reset). Stamps that leap ahead are taken as they come: a long
    gap looks the same."""

    jump_ns: int
    newest: dict[str, int] = field(default_factory=dict)

    def check(self, source: str, stamp_ns: int) -> int:
        """How far (ns) ``stamp_ns`` is behind its source's newest stamp if that is a jump, else 0;
        after a jump the other sources are forgotten (everything starts over)."""
        newest = self.newest.get(source)
        if newest is not None and stamp_ns < newest - self.jump_ns:
            self.newest = {source: stamp_ns}
            return newest - stamp_ns
        self.newest[source] = stamp_ns if newest is None else max(newest, stamp_ns)
        return 0
