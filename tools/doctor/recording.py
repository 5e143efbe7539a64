"""Read a recording for the doctor: an MCAP file of ``perception record`` (service statuses
included), or a ROS 1 / ROS 2 bag, message by message at its receive (log) time."""

from __future__ import annotations

from pathlib import Path

from tools.doctor.collect import Observer
from tools.replay.sources import SourceError, open_source

__all__ = ["read_recording"]


def read_recording(path: Path, observer: Observer) -> tuple[float, list[str]]:
    """Feed ``observer`` every message of ``path``; returns (the span in seconds, notes).

    The notes say what could not be read (a truncated file keeps what came before the cut).
    Raises :class:`SourceError` when the file cannot be read at all.
    """
    source = open_source(path, keep_status=True)
    notes = [f"{topic}: {why}" for topic, why in sorted(source.skipped.items())]
    first = last = 0
    try:
        for item in source.items():
            observer.payload(item.key, item.encoded(), item.log_ns)
            first = item.log_ns if not first else min(first, item.log_ns)
            last = max(last, item.log_ns)
    except SourceError as exc:
        if not first:
            raise
        notes.append(exc.problem)
    finally:
        source.close()
    return max(0.0, (last - first) / 1e9), notes
