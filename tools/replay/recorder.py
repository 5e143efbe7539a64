"""Write perception messages into an MCAP file that describes itself.

One channel per (Zenoh key, schema): topic = the key, message encoding ``msgpack`` (the
wire payload, :mod:`common.messages.codec`), schema = the message's schema name with encoding
``jsonschema`` and the pydantic model's JSON schema as data; the channel metadata holds
the schema version. ``log_time`` is the receive time, ``publish_time`` the message's
``header.stamp_ns``. A ``perception`` metadata record names the versions of every
schema, the key expressions recorded and the writer's version.
"""

from __future__ import annotations

import json
from collections import Counter
from pathlib import Path
from typing import Literal, Sequence

from common.messages.codec import encode
from common.messages.schemas import MESSAGE_TYPES, Message
from tools.replay.sources import MSGPACK

__all__ = ["McapRecorder"]

Compression = Literal["zstd", "lz4", "none"]


class McapRecorder:
    """Appends messages to ``path``; call :meth:`finish` (or use ``with``) to close the file.

    Messages are written in chunks of about ``chunk_size`` bytes (compressed together),
    so a recorder that is killed loses at most its last chunk.
    """

    def __init__(self, path: Path, *, compression: Compression = "zstd", key_exprs: Sequence[str] = (),
                 writer_version: str = "", chunk_size: int = 1024 * 1024) -> None:
        from mcap.writer import CompressionType, Writer

        comp = {"zstd": CompressionType.ZSTD, "lz4": CompressionType.LZ4, "none": CompressionType.NONE}[compression]
        self.path = path
        self._file = path.open("wb")
        self._writer = Writer(self._file, compression=comp, chunk_size=chunk_size)
        self._writer.start(profile="perception", library=f"people-perception {writer_version}".strip())
        self._writer.add_metadata("perception", {
            "schema_versions": json.dumps({name: m.SCHEMA_VERSION for name, m in sorted(MESSAGE_TYPES.items())}),
            "key_exprs": json.dumps(list(key_exprs)),
            "message_encoding": MSGPACK,
            "writer_version": writer_version,
        })
        self._schemas: dict[str, int] = {}
        self._channels: dict[tuple[str, str], int] = {}
        self._seq: Counter[int] = Counter()
        #: messages and bytes written per key
        self.counts: Counter[str] = Counter()
        self.bytes: Counter[str] = Counter()
        self.schema_of: dict[str, str] = {}
        self.finished = False

    def _channel(self, key: str, msg: Message) -> int:
        name = msg.SCHEMA_NAME
        ch = self._channels.get((key, name))
        if ch is None:
            schema_id = self._schemas.get(name)
            if schema_id is None:
                data = json.dumps(type(msg).model_json_schema()).encode()
                schema_id = self._schemas[name] = self._writer.register_schema(name=name, encoding="jsonschema", data=data)
            ch = self._channels[(key, name)] = self._writer.register_channel(
                topic=key, message_encoding=MSGPACK, schema_id=schema_id,
                metadata={"schema_version": str(msg.SCHEMA_VERSION)})
            self.schema_of[key] = name
        return ch

    def write(self, key: str, msg: Message, log_time_ns: int, payload: bytes | None = None) -> None:
        """Record ``msg`` received on ``key`` at ``log_time_ns`` (``payload``: its encoding, if at hand)."""
        data = payload if payload is not None else encode(msg)
        ch = self._channel(key, msg)
        self._seq[ch] += 1
        self._writer.add_message(channel_id=ch, log_time=log_time_ns, data=data,
                                 publish_time=msg.header.stamp_ns, sequence=self._seq[ch])
        self.counts[key] += 1
        self.bytes[key] += len(data)

    def finish(self) -> None:
        """Write the summary and close the file (idempotent)."""
        if not self.finished:
            self.finished = True
            try:
                self._writer.finish()
            finally:
                self._file.close()

    def __enter__(self) -> McapRecorder:
        return self

    def __exit__(self, *exc: object) -> None:
        self.finish()
