"""What every replayable source is made of: :class:`Source`, the :class:`Item` it yields,
its :class:`Summary` and :class:`SourceError`.

:mod:`tools.replay.bag_source` (ROS bags) and :mod:`tools.replay.sources` (MCAP
recordings, and :func:`~tools.replay.sources.open_source`, which opens either kind) both
build on it, so only ``sources`` imports ``bag_source``, never the other way round.
:mod:`tools.replay.sources` re-exports these names.
"""

from __future__ import annotations

import logging
from abc import ABC, abstractmethod
from collections import Counter
from dataclasses import dataclass, field
from pathlib import Path
from typing import Iterator

from common.messages.codec import encode
from common.messages.schemas import Message

__all__ = ["Item", "Source", "SourceError", "StreamSummary", "Summary"]

log = logging.getLogger(__name__)


class SourceError(Exception):
    """A recording that cannot be read; ``str()`` is ``"PATH: problem"``."""

    def __init__(self, path: Path | str, problem: str) -> None:
        self.path = str(path)
        self.problem = problem
        super().__init__(f"{path}: {problem}")


@dataclass
class Item:
    """One message to publish. ``payload`` (encoded) or ``message`` is set."""

    stamp_ns: int
    log_ns: int
    key: str
    model: type[Message]
    payload: bytes | None = None
    message: Message | None = None

    def encoded(self) -> bytes:
        if self.payload is None:
            assert self.message is not None
            self.payload = encode(self.message)
        return self.payload


@dataclass
class StreamSummary:
    name: str
    type: str
    count: int
    note: str = ""


@dataclass
class Summary:
    format: str
    streams: list[StreamSummary]
    start_ns: int
    end_ns: int
    extra: list[str] = field(default_factory=list)

    @property
    def duration_s(self) -> float:
        return max(0, self.end_ns - self.start_ns) / 1e9


class Source(ABC):
    """A readable recording."""

    def __init__(self, path: Path) -> None:
        self.path = path
        #: Channels/topics that are not replayed, with the reason.
        self.skipped: dict[str, str] = {}
        #: Messages that could not be converted: (stream, reason) -> count.
        self.problems: Counter[tuple[str, str]] = Counter()

    @abstractmethod
    def streams(self) -> dict[str, type[Message]]:
        """The keys this source publishes on, with their message type."""

    @abstractmethod
    def items(self) -> Iterator[Item]:
        """Every message, in recording order; raises :class:`SourceError` on a damaged file."""

    @abstractmethod
    def summary(self) -> Summary: ...

    def duration_s(self) -> float:
        return self.summary().duration_s

    def problem(self, stream: str, reason: str) -> None:
        """Count a message that could not be used; log the first of each kind."""
        if not self.problems[(stream, reason)]:
            log.warning("%s: %s: %s (further ones counted, not logged)", self.path, stream, reason)
        self.problems[(stream, reason)] += 1

    def close(self) -> None:
        """Release the file."""

    def __enter__(self) -> Source:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()
