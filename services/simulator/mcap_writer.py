"""A small MCAP writer: one channel per key, msgpack messages, JSON schemas in the file.

Each channel's schema is named after the message type (``perception.RGBDFrame``) and holds
its pydantic JSON schema; the schema version is in the channel metadata. ``log_time`` and
``publish_time`` are the message's ``header.stamp_ns``.
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import BinaryIO

from mcap.writer import Writer

from common.codec import encode
from common.schemas import Message

__all__ = ["McapSink"]


class McapSink:
    """Write messages to an MCAP file; use as a context manager (the file is finished on exit)."""

    def __init__(self, path: Path, library: str = "people-perception simulator") -> None:
        self.path = Path(path)
        self._handle: BinaryIO = self.path.open("wb")
        self._writer = Writer(self._handle)
        self._writer.start(profile="", library=library)
        self._schemas: dict[str, int] = {}
        self._channels: dict[str, int] = {}
        self.counts: dict[str, int] = {}

    def _channel(self, key: str, msg: Message) -> int:
        if key not in self._channels:
            name = msg.SCHEMA_NAME
            if name not in self._schemas:
                data = json.dumps(type(msg).model_json_schema()).encode()
                self._schemas[name] = self._writer.register_schema(name=name, encoding="jsonschema", data=data)
            self._channels[key] = self._writer.register_channel(
                topic=key,
                message_encoding="msgpack",
                schema_id=self._schemas[name],
                metadata={"schema_name": name, "schema_version": str(msg.SCHEMA_VERSION)},
            )
        return self._channels[key]

    def write(self, key: str, msg: Message) -> None:
        """Append ``msg`` on channel ``key`` at its header stamp."""
        channel = self._channel(key, msg)
        stamp = msg.header.stamp_ns
        self._writer.add_message(
            channel, log_time=stamp, data=encode(msg), publish_time=stamp, sequence=msg.header.seq % 2**32
        )
        self.counts[key] = self.counts.get(key, 0) + 1

    def close(self) -> None:
        if not self._handle.closed:
            self._writer.finish()
            self._handle.close()

    def __enter__(self) -> McapSink:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()
