"""Typed publish/subscribe over Zenoh, and the interface every transport implements.

Services are handed a :class:`Transport` and never open a session themselves; tests hand
them a :class:`common.transport.memory.MemoryTransport` instead, with the same behaviour.

Subscriptions deliver into an :class:`Inbox` from the transport's receive thread:

* ``latest`` delivery keeps only the newest sample; every overwritten sample counts as
  dropped. Image frames use it, so a slow model never builds a queue.
* otherwise a bounded FIFO keeps up to ``queue`` samples; the oldest is dropped, and
  counted, when it overflows.

Payloads are decoded on the consumer's thread in :meth:`Subscription.recv`; a payload
that fails to decode is logged (at most once per second per subscription), counted as
``invalid`` and skipped.
"""

from __future__ import annotations

import logging
import threading
import time
import uuid
from abc import ABC, abstractmethod
from collections import deque
from dataclasses import dataclass, field
from typing import Any, Callable, Generic, Iterable, TypeVar

from common.messages.codec import DecodeError, decode, decode_any, encode
from common.messages.keys import Delivery
from common.runtime.ratelog import RateLimitedLog
from common.messages.schemas import Message

__all__ = ["BasePublisher", "BaseSubscription", "Closer", "Inbox", "Publisher", "QueryHandler", "RawPublisher", "RawSample", "RawSubscription", "Received",
           "Subscription", "SubscriptionStats", "Transport", "wait_any"]

log = logging.getLogger(__name__)
M = TypeVar("M", bound=Message)

#: A queryable's handler: (key, selector parameters) -> the messages to reply with.
QueryHandler = Callable[[str, dict[str, str]], Iterable[Message]]


@dataclass
class SubscriptionStats:
    received: int = 0
    dropped: int = 0
    invalid: int = 0


@dataclass(frozen=True)
class Received(Generic[M]):
    msg: M
    key: str
    recv_ns: int


class Inbox:
    """Where a transport's receive thread leaves raw payloads for one subscription."""

    def __init__(self, delivery: Delivery, notify: threading.Condition) -> None:
        self.delivery = delivery
        #: Set by a transport that keeps samples itself until they are read (``delivery.wake``
        #: False): returns the next ``(key, payload, recv_ns)`` or None.
        self.pull: Callable[[], tuple[str, Any, int] | None] | None = None
        self._items: deque[tuple[str, bytes | Any, int]] = deque(maxlen=1 if delivery.latest else delivery.queue)
        self._cond = notify
        self.stats = SubscriptionStats()

    def push(self, key: str, payload: Any) -> None:
        with self._cond:
            self.stats.received += 1
            if len(self._items) == self._items.maxlen:
                self.stats.dropped += 1
            self._items.append((key, payload, time.time_ns()))
            self._cond.notify_all()

    def pop(self) -> tuple[str, Any, int] | None:
        with self._cond:
            if self._items:
                return self._items.popleft()
        if self.pull is not None and (item := self.pull()) is not None:
            self.stats.received += 1
            return item
        return None

    def __len__(self) -> int:
        return len(self._items)


def _bytes(payload: Any) -> bytes | bytearray:
    """The payload of what an inbox holds: bytes (the in-memory transport) or a ``zenoh.Sample``."""
    return payload if isinstance(payload, (bytes, bytearray)) else payload.payload.to_bytes()


class BaseSubscription:
    """What every subscription has: its key, its inbox's counts, waiting and closing."""

    def __init__(self, key: str, inbox: Inbox, notify: threading.Condition, undeclare: Callable[[], None]) -> None:
        self.key = key
        self._inbox = inbox
        self._cond = notify
        self._undeclare = undeclare
        self.closed = False

    @property
    def stats(self) -> SubscriptionStats:
        return self._inbox.stats

    def pending(self) -> int:
        return len(self._inbox)

    def close(self) -> None:
        if not self.closed:
            self.closed = True
            self._undeclare()
            with self._cond:
                self._cond.notify_all()


class Subscription(BaseSubscription, Generic[M]):
    """A typed subscription. ``recv`` returns the next decodable message or ``None``."""

    def __init__(self, key: str, model: type[M] | None, inbox: Inbox, notify: threading.Condition,
                 undeclare: Callable[[], None], max_bytes: int | None = None) -> None:
        super().__init__(key, inbox, notify, undeclare)
        self.model = model
        self._max_bytes = max_bytes
        self._log = RateLimitedLog(log)
        self.last_error: DecodeError | None = None

    def try_recv(self) -> Received[M] | None:
        """The next message if one is waiting (invalid payloads are counted and skipped)."""
        while (item := self._inbox.pop()) is not None:
            if (got := self._decode(*item)) is not None:
                return got
        return None

    def _decode(self, key: str, payload: Any, recv_ns: int) -> Received[M] | None:
        data = _bytes(payload)
        try:
            msg = decode(self.model, data, max_bytes=self._max_bytes) if self.model else decode_any(data, max_bytes=self._max_bytes)
        except DecodeError as exc:
            self._inbox.stats.invalid += 1
            self.last_error = exc
            self._log.warning("invalid", "dropping invalid payload on %s (%d so far): %s", key,
                              self._inbox.stats.invalid, exc)
            return None
        return Received(msg, key, recv_ns)  # type: ignore[arg-type]

    def take_newest(self) -> tuple[Received[M] | None, list[int]]:
        """Everything pending at once: the newest decodable message, and every arrival's
        ``recv_ns`` (oldest first).

        For readers that show only the latest state but still count every arrival (the
        viewer): older payloads are dropped without being decoded, which is most of the cost
        of a stream of images. Nothing is counted as dropped; an undecodable newest payload
        is counted as invalid and the one before it is tried.
        """
        items: list[tuple[str, Any, int]] = []
        while (item := self._inbox.pop()) is not None:
            items.append(item)
        arrivals = [recv_ns for _, _, recv_ns in items]
        for item in reversed(items):
            if (got := self._decode(*item)) is not None:
                return got, arrivals
        return None, arrivals

    def try_recv_raw(self) -> tuple[str, bytes, int] | None:
        """The next payload as it arrived, ``(key, bytes, recv_ns)``, without decoding it.

        For tools that inspect payloads themselves (``perception doctor`` reads an invalid
        frame's fields to say what is wrong with it); nothing is counted as invalid.
        """
        item = self._inbox.pop()
        if item is None:
            return None
        key, payload, recv_ns = item
        return key, bytes(_bytes(payload)), recv_ns

    def recv(self, timeout: float | None = None) -> Received[M] | None:
        """Wait up to ``timeout`` seconds (forever if None) for the next message."""
        deadline = None if timeout is None else time.monotonic() + timeout
        while True:
            got = self.try_recv()
            if got is not None or self.closed:
                return got
            with self._cond:
                if self._inbox:
                    continue
                remaining = None if deadline is None else deadline - time.monotonic()
                if remaining is not None and remaining <= 0:
                    return None
                self._cond.wait(remaining if remaining is not None else 0.5)


def wait_any(subs: Iterable[BaseSubscription], notify: threading.Condition, timeout: float) -> bool:
    """Wait until any of ``subs`` has a pending payload, or ``timeout`` seconds pass."""
    subs = list(subs)
    with notify:
        return notify.wait_for(lambda: any(s.pending() for s in subs), timeout)


class BasePublisher:
    """What every publisher has: its key, its counts, its subscribers' presence and closing."""

    def __init__(self, key: str, matching: Callable[[], bool], undeclare: Callable[[], None]) -> None:
        self.key = key
        self._matching = matching
        self._undeclare = undeclare
        self.published = 0
        #: Puts made while no subscriber matched (e.g. during a router outage): those are lost.
        self.unmatched = 0
        self.closed = False

    def _sent(self) -> None:
        self.published += 1
        if not self._matching():
            self.unmatched += 1

    def has_subscribers(self) -> bool:
        return self._matching()

    def close(self) -> None:
        if not self.closed:
            self.closed = True
            self._undeclare()


class Publisher(BasePublisher, Generic[M]):
    """Publishes messages of one type on one key."""

    def __init__(self, key: str, model: type[M], send: Callable[[bytes], None], matching: Callable[[], bool],
                 undeclare: Callable[[], None]) -> None:
        super().__init__(key, matching, undeclare)
        self.model = model
        self._send = send

    def put(self, msg: M) -> None:
        if not isinstance(msg, self.model):
            raise TypeError(f"publisher on {self.key} takes {self.model.__name__}, got {type(msg).__name__}")
        self._send(encode(msg))
        self._sent()

    def put_encoded(self, data: bytes) -> None:
        """Publish a payload that is already an encoded message of this publisher's type.

        For replaying recordings without a decode/encode round trip; the caller vouches
        for the bytes (subscribers still validate them).
        """
        self._send(data)
        self.published += 1

    def wait_for_subscribers(self, timeout: float) -> bool:
        """Wait until at least one subscriber matches, up to ``timeout`` s."""
        deadline = time.monotonic() + timeout
        while not self._matching():
            if time.monotonic() >= deadline:
                return False
            time.sleep(0.01)
        return True


@dataclass(frozen=True)
class RawSample:
    """A sample of a foreign format (another middleware's payload), as it arrived."""

    key: str
    payload: bytes
    attachment: bytes | None
    recv_ns: int


class RawSubscription(BaseSubscription):
    """Undecoded samples with their attachments: for bridges to other middlewares on the same
    Zenoh (ROS 2's rmw_zenoh), whose payloads are not this project's messages."""

    def try_recv(self) -> RawSample | None:
        item = self._inbox.pop()
        if item is None:
            return None
        key, payload, recv_ns = item
        if isinstance(payload, tuple):  # the in-memory transport's (payload, attachment)
            data, attachment = payload
        else:  # a zenoh.Sample
            data = payload.payload.to_bytes()
            attachment = payload.attachment.to_bytes() if payload.attachment is not None else None
        return RawSample(key, bytes(data), attachment, recv_ns)


class RawPublisher(BasePublisher):
    """Publishes payloads of a foreign format, each with an attachment, on one key."""

    def __init__(self, key: str, send: Callable[[bytes, bytes | None], None], matching: Callable[[], bool],
                 undeclare: Callable[[], None]) -> None:
        super().__init__(key, matching, undeclare)
        self._send = send

    def put(self, payload: bytes, attachment: bytes | None = None) -> None:
        self._send(payload, attachment)
        self._sent()


class Closer:
    """Adapts an undeclare function to the ``close()`` protocol."""

    def __init__(self, fn: Callable[[], None]) -> None:
        self._fn: Callable[[], None] | None = fn

    def close(self) -> None:
        fn, self._fn = self._fn, None
        if fn is not None:
            fn()


@dataclass
class Token:
    """A declared liveliness token; ``close`` withdraws it."""

    key: str
    _undeclare: Callable[[], None] = field(repr=False)

    def close(self) -> None:
        fn, self._undeclare = self._undeclare, lambda: None
        fn()


class Transport(ABC):
    """Typed messaging: pub/sub, liveliness and queries. Use as a context manager."""

    def __init__(self) -> None:
        #: Notified whenever any subscription of this transport receives a payload.
        self.notify = threading.Condition()
        self._closeables: list[Any] = []
        self.closed = False
        #: What :meth:`session_id` says for a transport without a Zenoh session (the in-memory one).
        self._session_id = uuid.uuid4().hex

    @abstractmethod
    def publisher(self, key: str, model: type[M], delivery: Delivery) -> Publisher[M]: ...

    @abstractmethod
    def _subscribe(self, key: str, inbox: Inbox) -> Callable[[], None]:
        """Start delivering samples on ``key`` into ``inbox``; returns the undeclare function."""

    def subscribe(self, key: str, model: type[M] | None, delivery: Delivery, *, max_bytes: int | None = None) -> Subscription[M]:
        """Subscribe to ``key`` (may hold wildcards). ``model=None`` accepts any message type."""
        inbox = Inbox(delivery, self.notify)
        undeclare = self._subscribe(key, inbox)
        sub: Subscription[M] = Subscription(key, model, inbox, self.notify, undeclare, max_bytes)
        self._closeables.append(sub)
        return sub

    def session_id(self) -> str:
        """This participant's id as text (Zenoh's session id, in hex): unique on the network."""
        return self._session_id

    def raw_publisher(self, key: str, delivery: Delivery, *, cache: int = 0) -> RawPublisher:
        """A publisher of foreign payloads with attachments; ``cache`` > 0 keeps the last
        ``cache`` samples for late subscribers that ask for history (Zenoh's advanced publisher)."""
        raise NotImplementedError(f"{type(self).__name__} carries no foreign payloads")

    def subscribe_raw(self, key: str, delivery: Delivery, *, history: int = 0) -> RawSubscription:
        """Subscribe to foreign payloads on ``key``; ``history`` > 0 also asks publishers that keep
        a cache for their last ``history`` samples, now and when such a publisher appears later
        (Zenoh's advanced subscriber: how rmw_zenoh serves transient-local topics)."""
        inbox = Inbox(delivery, self.notify)
        undeclare = self._subscribe_raw(key, inbox, history)
        sub = RawSubscription(key, inbox, self.notify, undeclare)
        self._closeables.append(sub)
        return sub

    def _subscribe_raw(self, key: str, inbox: Inbox, history: int) -> Callable[[], None]:
        raise NotImplementedError(f"{type(self).__name__} carries no foreign payloads")

    @abstractmethod
    def declare_token(self, key: str) -> Token: ...

    @abstractmethod
    def alive(self, pattern: str, timeout: float = 1.0) -> list[str]:
        """Keys of the liveliness tokens alive now that match ``pattern``."""

    @abstractmethod
    def watch_alive(self, pattern: str, callback: Callable[[str, bool], None]) -> Callable[[], None]:
        """Call ``callback(key, alive)`` as tokens appear and vanish (present ones first)."""

    @abstractmethod
    def serve(self, key: str, handler: QueryHandler) -> Callable[[], None]:
        """Answer queries on ``key`` with the messages ``handler`` returns."""

    @abstractmethod
    def query(self, selector: str, timeout: float = 1.0) -> list[tuple[str, Message]]:
        """Ask every queryable matching ``selector`` (``key?a=1``); undecodable replies are skipped."""

    def _close_session(self) -> None:
        """Release the underlying session (after every declaration is undeclared)."""

    def close(self) -> None:
        if self.closed:
            return
        self.closed = True
        for c in reversed(self._closeables):
            try:
                c.close()
            except Exception as exc:  # a failing undeclare must not keep the session open
                log.warning("error while closing %r: %s", c, exc)
        self._closeables.clear()
        self._close_session()

    def __enter__(self) -> Transport:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


def parse_parameters(params: str) -> dict[str, str]:
    """``"a=1;b=2"`` (Zenoh selector parameters, ``&`` also accepted) as a dict."""
    out: dict[str, str] = {}
    for part in params.replace("&", ";").split(";"):
        if part:
            k, _, v = part.partition("=")
            out[k] = v
    return out
