"""An in-process transport with the same interface and behaviour as the Zenoh one.

Several :class:`MemoryTransport` objects on one :class:`MemoryBus` talk to each other as
if they were separate processes: payloads go through the real codec, key expressions
match with Zenoh's ``*`` and ``**`` rules, and liveliness tokens vanish when their
transport closes. Services can so be tested without a router.
"""

from __future__ import annotations

import threading
from collections import deque
from typing import Any, Callable

from common.messages.codec import DecodeError, decode_any, encode
from common.messages.keys import Delivery
from common.messages.schemas import Message
from common.transport.base import Closer, Inbox, Publisher, QueryHandler, RawPublisher, Token, Transport, parse_parameters

__all__ = ["MemoryBus", "MemoryTransport", "key_matches"]


def _match_chunks(pattern: list[str], key: list[str]) -> bool:
    if not pattern:
        return not key
    head = pattern[0]
    if head == "**":
        return any(_match_chunks(pattern[1:], key[i:]) for i in range(len(key) + 1))
    if not key:
        return False
    return (head == "*" or head == key[0]) and _match_chunks(pattern[1:], key[1:])


def key_matches(pattern: str, key: str) -> bool:
    """Whether concrete ``key`` is matched by ``pattern`` (``*`` one chunk, ``**`` any)."""
    return _match_chunks(pattern.split("/"), key.split("/"))


def keys_intersect(a: str, b: str) -> bool:
    """Whether two expressions, either possibly with wildcards, can match a common key."""
    return key_matches(a, b) or key_matches(b, a)


class MemoryBus:
    """The shared medium of a set of in-memory transports."""

    def __init__(self) -> None:
        self.lock = threading.RLock()
        self.subscribers: list[tuple[str, Inbox]] = []
        self.tokens: list[str] = []
        self.watchers: list[tuple[str, Callable[[str, bool], None]]] = []
        self.queryables: list[tuple[str, QueryHandler]] = []
        #: Foreign-payload publishers that keep their last samples for late subscribers.
        self.caches: list[tuple[str, deque[tuple[bytes, bytes | None]]]] = []

    def transport(self) -> MemoryTransport:
        return MemoryTransport(self)

    def _token_event(self, key: str, alive: bool) -> None:
        for pattern, cb in list(self.watchers):
            if keys_intersect(pattern, key):
                cb(key, alive)


class MemoryTransport(Transport):
    """One participant on a :class:`MemoryBus`."""

    def __init__(self, bus: MemoryBus | None = None) -> None:
        super().__init__()
        self.bus = bus if bus is not None else MemoryBus()

    def _remove(self, registry: list[Any], entry: Any) -> Callable[[], None]:
        def undeclare() -> None:
            with self.bus.lock:
                if entry in registry:
                    registry.remove(entry)

        return undeclare

    def publisher(self, key: str, model: type, delivery: Delivery) -> Publisher:  # type: ignore[type-arg]
        def send(data: bytes) -> None:
            with self.bus.lock:
                targets = [inbox for pattern, inbox in self.bus.subscribers if keys_intersect(pattern, key)]
            for inbox in targets:
                inbox.push(key, data)

        def matching() -> bool:
            with self.bus.lock:
                return any(keys_intersect(p, key) for p, _ in self.bus.subscribers)

        pub: Publisher[Any] = Publisher(key, model, send, matching, lambda: None)
        self._closeables.append(pub)
        return pub

    def _subscribe(self, key: str, inbox: Inbox) -> Callable[[], None]:
        entry = (key, inbox)
        with self.bus.lock:
            self.bus.subscribers.append(entry)
        return self._remove(self.bus.subscribers, entry)

    def raw_publisher(self, key: str, delivery: Delivery, *, cache: int = 0) -> RawPublisher:
        kept: deque[tuple[bytes, bytes | None]] = deque(maxlen=max(cache, 1))
        if cache > 0:
            with self.bus.lock:
                self.bus.caches.append((key, kept))

        def send(payload: bytes, attachment: bytes | None) -> None:
            with self.bus.lock:
                targets = [inbox for pattern, inbox in self.bus.subscribers if keys_intersect(pattern, key)]
                if cache > 0:
                    kept.append((payload, attachment))
            for inbox in targets:
                inbox.push(key, (payload, attachment))

        def matching() -> bool:
            with self.bus.lock:
                return any(keys_intersect(p, key) for p, _ in self.bus.subscribers)

        def undeclare() -> None:
            with self.bus.lock:
                self.bus.caches[:] = [c for c in self.bus.caches if c[1] is not kept]

        pub = RawPublisher(key, send, matching, undeclare)
        self._closeables.append(pub)
        return pub

    def _subscribe_raw(self, key: str, inbox: Inbox, history: int) -> Callable[[], None]:
        with self.bus.lock:
            if history > 0:
                for pub_key, kept in self.bus.caches:
                    if keys_intersect(key, pub_key):
                        for payload in list(kept)[-history:]:
                            inbox.push(pub_key, payload)
            return self._subscribe(key, inbox)

    def declare_token(self, key: str) -> Token:
        with self.bus.lock:
            self.bus.tokens.append(key)
            self.bus._token_event(key, True)

        def undeclare() -> None:
            with self.bus.lock:
                if key in self.bus.tokens:
                    self.bus.tokens.remove(key)
                    self.bus._token_event(key, False)

        token = Token(key, undeclare)
        self._closeables.append(token)
        return token

    def alive(self, pattern: str, timeout: float = 1.0) -> list[str]:
        with self.bus.lock:
            return sorted({k for k in self.bus.tokens if keys_intersect(pattern, k)})

    def watch_alive(self, pattern: str, callback: Callable[[str, bool], None]) -> Callable[[], None]:
        entry = (pattern, callback)
        with self.bus.lock:
            for k in self.bus.tokens:
                if keys_intersect(pattern, k):
                    callback(k, True)
            self.bus.watchers.append(entry)
        undeclare = self._remove(self.bus.watchers, entry)
        self._closeables.append(Closer(undeclare))
        return undeclare

    def serve(self, key: str, handler: QueryHandler) -> Callable[[], None]:
        entry = (key, handler)
        with self.bus.lock:
            self.bus.queryables.append(entry)
        closer = Closer(self._remove(self.bus.queryables, entry))
        self._closeables.append(closer)
        return closer.close  # undeclaring twice (here and at close) is harmless

    def query(self, selector: str, timeout: float = 1.0) -> list[tuple[str, Message]]:
        key, _, params = selector.partition("?")
        with self.bus.lock:
            handlers = [(k, h) for k, h in self.bus.queryables if keys_intersect(k, key)]
        out: list[tuple[str, Message]] = []
        for qkey, handler in handlers:
            try:
                replies = list(handler(key, parse_parameters(params)))
            except (ValueError, KeyError, LookupError):
                continue
            for msg in replies:
                try:
                    out.append((qkey, decode_any(encode(msg))))
                except DecodeError:
                    continue
        return out
