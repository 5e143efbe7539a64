"""What can be replayed: MCAP recordings of the perception streams, ROS 1 and ROS 2 bags.

:func:`open_source` looks at the file itself (magic bytes, ``metadata.yaml``), not at its
name. A source lists its streams up front (key -> message type), yields :class:`Item`
in recording order and summarises itself for ``perception inspect``. Every failure is a
:class:`SourceError` whose text names the file and the problem.
"""

from __future__ import annotations

import logging
import struct
from collections import Counter
from pathlib import Path
from typing import Any, BinaryIO, Iterator

from common.messages.schemas import MESSAGE_TYPES, Message
from tools.replay.bag_source import BagOptions, BagSource
from tools.replay.source_base import Item, Source, SourceError, StreamSummary, Summary

__all__ = ["Item", "McapSource", "Source", "SourceError", "StreamSummary", "Summary", "open_source"]

log = logging.getLogger(__name__)

MCAP_MAGIC = b"\x89MCAP0\r\n"
ROSBAG1_MAGIC = b"#ROSBAG V2.0"
#: Message encoding of the channels ``perception record`` writes.
MSGPACK = "msgpack"


def _mcap_errors() -> tuple[type[BaseException], ...]:
    from mcap.exceptions import McapError

    return (McapError, struct.error, ValueError, EOFError, OSError, KeyError, AssertionError)


class McapSource(Source):
    """An MCAP file written by ``perception record``: msgpack payloads, topic = Zenoh key.

    Channels with another message encoding, or a schema this build does not know, are
    skipped and listed. ServiceStatus channels are kept in the file but never replayed
    (they would impersonate services that are not running), unless ``keep_status`` asks
    for them (``perception doctor --recording`` reads them).
    """

    def __init__(self, path: Path, keep_status: bool = False) -> None:
        super().__init__(path)
        self.keep_status = keep_status
        from mcap.reader import make_reader

        self._file: BinaryIO = path.open("rb")
        try:
            self._reader = make_reader(self._file)
        except _mcap_errors() as exc:
            self._file.close()
            raise SourceError(path, f"not a readable MCAP file ({type(exc).__name__}: {exc})") from exc
        try:
            self._summary = self._reader.get_summary()
        except _mcap_errors() as exc:  # no valid footer: cut off, read what is there
            log.debug("%s: no summary (%s), reading linearly", path, exc)
            self._summary = None
        self._truncated = self._summary is None
        self._streams: dict[str, type[Message]] = {}
        self._channels: dict[int, str] = {}
        if self._summary is not None:
            for ch in self._summary.channels.values():
                self._consider(ch, self._summary.schemas.get(ch.schema_id))
        else:
            self._discover_channels()

    def _discover_channels(self) -> None:
        """Without a summary, find the channels by reading the file once."""
        n = 0
        try:
            for schema, channel, _ in self._messages():
                self._consider(channel, schema)
                n += 1
        except _mcap_errors() as exc:
            if n == 0:
                self._file.close()
                if type(exc).__name__ == "EndOfFile":
                    raise SourceError(self.path, "truncated before its first complete chunk: no message can be read "
                                      "(the recorder was killed?)") from exc
                raise SourceError(self.path, f"not a readable MCAP file ({type(exc).__name__}: {exc})") from exc

    def _consider(self, channel: object, schema: object) -> bool:
        ch_id, topic = channel.id, channel.topic  # type: ignore[attr-defined]
        if ch_id in self._channels:
            return True
        encoding = channel.message_encoding  # type: ignore[attr-defined]
        name = schema.name if schema is not None else ""  # type: ignore[attr-defined]
        model = MESSAGE_TYPES.get(name)
        if encoding != MSGPACK:
            self.skipped[topic] = f"message encoding {encoding!r} is not {MSGPACK!r} (not a perception recording)"
        elif model is None:
            self.skipped[topic] = f"schema {name!r} is unknown to this build"
        elif name == "perception.ServiceStatus" and not self.keep_status:
            self.skipped[topic] = "service status is not replayed"
        else:
            self._channels[ch_id] = topic
            self._streams[topic] = model
            return True
        return False

    def streams(self) -> dict[str, type[Message]]:
        return dict(self._streams)

    def _messages(self) -> Iterator[tuple[Any, Any, Any]]:
        if not self._truncated:
            return self._reader.iter_messages(log_time_order=True)
        from mcap.reader import NonSeekingReader

        self._file.seek(0)  # written in receive order, so file order is log-time order
        return NonSeekingReader(self._file).iter_messages(log_time_order=False)

    def items(self) -> Iterator[Item]:
        n = 0
        try:
            for schema, channel, message in self._messages():
                if channel.id not in self._channels:
                    continue
                n += 1
                yield Item(message.publish_time, message.log_time, channel.topic,
                           self._streams[channel.topic], payload=message.data)
        except _mcap_errors() as exc:
            if type(exc).__name__ == "EndOfFile":
                raise SourceError(self.path, f"truncated after {n} messages: the file ends mid-record (the recorder "
                                  "was killed?); the messages before the cut were replayed") from exc
            what = "not a readable MCAP file" if n == 0 else f"damaged after {n} messages"
            raise SourceError(self.path, f"{what} ({type(exc).__name__}: {exc})") from exc
        if self._truncated:
            raise SourceError(self.path, f"truncated: the file ends without its summary after {n} messages "
                              "(the recorder was killed?); the messages before the cut were replayed")

    def summary(self) -> Summary:
        if self._summary is None or self._summary.statistics is None:
            return self._scan_summary()
        st = self._summary.statistics
        streams = []
        for ch_id, ch in sorted(self._summary.channels.items(), key=lambda kv: kv[1].topic):
            schema = self._summary.schemas.get(ch.schema_id)
            streams.append(StreamSummary(ch.topic, schema.name if schema else "?", st.channel_message_counts.get(ch_id, 0),
                                         self.skipped.get(ch.topic, "")))
        extra = [f"{m.name}: {dict(m.metadata)}" for m in self._reader.iter_metadata()]
        return Summary("MCAP", streams, st.message_start_time, st.message_end_time, extra)

    def _scan_summary(self) -> Summary:
        counts: Counter[str] = Counter()
        names: dict[str, str] = {}
        start, end = 0, 0
        try:
            for schema, channel, message in self._messages():
                counts[channel.topic] += 1
                names[channel.topic] = schema.name if schema else "?"
                start = message.log_time if not start else min(start, message.log_time)
                end = max(end, message.log_time)
        except _mcap_errors() as exc:
            note = f"truncated or damaged after {sum(counts.values())} messages ({type(exc).__name__})"
        else:
            note = "no summary section (recording not finished?); counted by reading every message"
        streams = [StreamSummary(t, names[t], c) for t, c in sorted(counts.items())]
        return Summary("MCAP", streams, start, end, [note])

    def close(self) -> None:
        self._file.close()


def _mcap_profile(path: Path) -> str:
    from mcap.reader import make_reader

    try:
        with path.open("rb") as f:
            return str(make_reader(f).get_header().profile)
    except _mcap_errors():
        return ""  # McapSource reports what is wrong with it


def open_source(path: Path | str, bag_options: BagOptions | None = None, *, keep_status: bool = False) -> Source:
    """Open an MCAP recording, a ROS 1 ``.bag`` or a ROS 2 bag folder (``keep_status``: see :class:`McapSource`)."""
    p = Path(path)
    if not p.exists():
        raise SourceError(p, "no such file or directory")
    if p.is_dir() or p.suffix in (".db3",) or (p.suffix == ".mcap" and (p.parent / "metadata.yaml").is_file()):
        bag = p if p.is_dir() else p.parent
        if not (bag / "metadata.yaml").is_file():
            raise SourceError(p, "a folder, but not a ROS 2 bag (no metadata.yaml in it)")
        return BagSource(bag, bag_options or BagOptions())
    try:
        with p.open("rb") as f:
            head = f.read(16)
    except OSError as exc:
        raise SourceError(p, f"cannot be read ({exc.strerror or exc})") from exc
    if not head:
        raise SourceError(p, "the file is empty")
    if head.startswith(MCAP_MAGIC):
        if _mcap_profile(p) == "ros2":  # a ROS 2 bag's MCAP file on its own (no metadata.yaml)
            return BagSource(p, bag_options or BagOptions())
        return McapSource(p, keep_status)
    if head.startswith(ROSBAG1_MAGIC):
        return BagSource(p, bag_options or BagOptions())
    raise SourceError(p, "not an MCAP recording, a ROS 1 bag or a ROS 2 bag folder (unknown file format)")
