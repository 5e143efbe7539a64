"""Laser scans from files: ROS 1 bags, ROS 2 bags (sqlite3 or mcap folders), and this project's
own MCAP recordings (``perception record``), without a ROS install."""

from __future__ import annotations

from pathlib import Path
from typing import Iterator

from common.messages.codec import decode
from common.messages.schemas import LaserScan

__all__ = ["ScanFileError", "read_scans"]

_ROS_TYPES = ("sensor_msgs/msg/LaserScan", "sensor_msgs/LaserScan")


class ScanFileError(ValueError):
    """A file that holds no readable scans of the topic asked for; the message says which there are."""


def read_scans(path: Path, topic: str | None = None) -> Iterator[tuple[str, LaserScan]]:
    """Every laser scan in ``path`` (of ``topic``, or of every laser topic) as (topic, scan), in
    the file's order. A recording's topic is its key; ``--topic scans/rear`` or ``rear`` match
    it by its end. Each scan's ``header.source`` is its topic's name (``/rear_scan`` ->
    ``rear_scan``), its ``seq`` its index on that topic."""
    path = Path(path)
    if not path.exists():
        raise ScanFileError(f"{path} does not exist")
    if path.suffix == ".mcap" and _is_recording(path):
        yield from _recording(path, topic)
    else:
        yield from _bag(path, topic)


def _chosen(topics: list[str], topic: str | None, path: Path) -> set[str]:
    if topic is None:
        chosen = set(topics)
    else:
        want = topic.strip("/")
        chosen = {t for t in topics if t.strip("/") == want or t.strip("/").endswith("/" + want)}
    if not chosen:
        found = ", ".join(sorted(topics)) or "none"
        raise ScanFileError(f"{path}: no laser scans on topic {topic!r} (laser topics: {found}); give --topic")
    return chosen


def _source(topic: str) -> str:
    return topic.strip("/").replace("/", "_") or "scan"


def _bag(path: Path, topic: str | None) -> Iterator[tuple[str, LaserScan]]:
    from rosbags.highlevel import AnyReader, AnyReaderError
    from rosbags.typesys import Stores, get_typestore

    try:
        reader = AnyReader([path], default_typestore=get_typestore(Stores.ROS1_NOETIC))
        reader.open()
    except (AnyReaderError, OSError, ValueError, KeyError) as exc:
        raise ScanFileError(f"{path} is not a readable ROS bag or recording ({type(exc).__name__}: {exc})") from exc
    try:
        lasers = [c for c in reader.connections if c.msgtype in _ROS_TYPES]
        chosen = _chosen(sorted({c.topic for c in lasers}), topic, path)
        seq: dict[str, int] = {}
        for conn, _, raw in reader.messages(connections=[c for c in lasers if c.topic in chosen]):
            seq[conn.topic] = seq.get(conn.topic, -1) + 1
            yield conn.topic, LaserScan.from_ros(reader.deserialize(raw, conn.msgtype), _source(conn.topic),
                                                 seq[conn.topic])
    finally:
        reader.close()


def _is_recording(path: Path) -> bool:
    from mcap.reader import make_reader

    with path.open("rb") as f:
        try:
            summary = make_reader(f).get_summary()
        except Exception:  # noqa: BLE001 - mcap raises many kinds on a foreign file
            return False
    return summary is not None and any(ch.message_encoding == "msgpack" for ch in summary.channels.values())


def _recording(path: Path, topic: str | None) -> Iterator[tuple[str, LaserScan]]:
    from mcap.reader import make_reader

    with path.open("rb") as f:
        reader = make_reader(f)
        summary = reader.get_summary()
        assert summary is not None
        lasers = {ch.topic for ch in summary.channels.values()
                  if summary.schemas.get(ch.schema_id) is not None
                  and summary.schemas[ch.schema_id].name == LaserScan.SCHEMA_NAME}
        chosen = _chosen(sorted(lasers), topic, path)
        for _, channel, message in reader.iter_messages(topics=sorted(chosen)):
            yield channel.topic, decode(LaserScan, message.data)
