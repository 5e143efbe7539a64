"""The Zenoh implementation of :class:`common.transport.base.Transport`."""

from __future__ import annotations

import argparse
import logging
import time
from typing import Any, Callable

import zenoh
from zenoh import ext as zext

from common.messages.codec import DecodeError, decode_any, encode
from common.messages.keys import Delivery
from common.messages.schemas import Message
from common.transport.base import Closer, Inbox, Publisher, QueryHandler, RawPublisher, Token, Transport, parse_parameters
from common.transport.zenoh_config import ZenohOptions, build_zenoh_config
from common.transport.zenoh_security import SecurityError

__all__ = ["TransportError", "ZenohTransport", "open_transport", "open_transport_from_args"]

log = logging.getLogger(__name__)
_ENCODING = "application/msgpack"


class TransportError(RuntimeError):
    """The Zenoh session could not be opened; the message says what to try."""


def open_session(opts: ZenohOptions) -> zenoh.Session:
    """Open a Zenoh session, turning the usual failures into an actionable message."""
    try:
        conf = build_zenoh_config(opts)
    except zenoh.ZError as exc:
        raise TransportError(f"invalid Zenoh configuration ({opts.describe()}): {exc}") from exc
    except SecurityError as exc:
        raise TransportError(str(exc)) from exc
    try:
        return zenoh.open(conf)
    except zenoh.ZError as exc:
        text = str(exc)
        if "Address already in use" in text:
            hint = "another process listens on that endpoint; pick another port with --listen"
        elif opts.mode == "client" and _secured(conf):
            hint = ("the router refused the session or did not answer: check the credentials (user and password), "
                    "that the certificates come from the router's CA, and that the endpoint is tls/ for a TLS router")
        elif opts.mode == "client":
            hint = ("no Zenoh router answered; start one with `perception router`, point --connect at "
                    "yours, or use --mode peer")
        else:
            hint = "check the endpoints and the config file"
        raise TransportError(f"could not open a Zenoh session ({opts.describe()}): {text.split(' at ')[0]}. {hint}") from exc


def _secured(conf: zenoh.Config) -> bool:
    """Whether ``conf`` authenticates with a password or a TLS certificate."""
    return any(conf.get_json(k) != "null" for k in ("transport/auth/usrpwd/user", "transport/link/tls/root_ca_certificate"))


def _arrival_ns(sample: zenoh.Sample) -> int:
    """UNIX ns of the sample's timestamp (Zenoh's NTP64 counts from the UNIX epoch), or now."""
    ts = sample.timestamp
    if ts is None:
        return time.time_ns()
    return int(ts.get_time_as_ntp64().as_nanos())


def _matching(pub: Any) -> bool:
    status = pub.matching_status
    return bool(getattr(status, "matching", status))


class ZenohTransport(Transport):
    """Typed pub/sub, liveliness and queries on one Zenoh session, which it owns."""

    def __init__(self, session: zenoh.Session) -> None:
        super().__init__()
        self.session = session

    def publisher(self, key: str, model: type, delivery: Delivery) -> Publisher:  # type: ignore[type-arg]
        pub = self.session.declare_publisher(
            key,
            encoding=zenoh.Encoding(_ENCODING),
            congestion_control=zenoh.CongestionControl.DROP if delivery.congestion == "drop" else zenoh.CongestionControl.BLOCK,
            priority=zenoh.Priority.DATA,
            express=delivery.express,
        )
        # Track matching through a listener so put() need not ask the session each time.
        state = {"matching": _matching(pub)}
        listener = pub.declare_matching_listener(lambda st: state.__setitem__("matching", bool(st.matching)))

        def undeclare() -> None:
            try:
                listener.undeclare()
            finally:
                pub.undeclare()  # even when the listener's undeclare fails

        wrapped: Publisher[Any] = Publisher(key, model, pub.put, lambda: state["matching"], undeclare)
        self._closeables.append(wrapped)
        return wrapped

    def _subscribe(self, key: str, inbox: Inbox) -> Callable[[], None]:
        if not inbox.delivery.wake:
            return self._subscribe_polled(key, inbox)

        def on_sample(sample: zenoh.Sample) -> None:
            if sample.kind == zenoh.SampleKind.PUT:
                inbox.push(str(sample.key_expr), sample)

        sub = self.session.declare_subscriber(key, on_sample)
        return sub.undeclare

    def _subscribe_polled(self, key: str, inbox: Inbox) -> Callable[[], None]:
        """Samples wait in Zenoh's ring channel (the newest ``queue``) until the inbox is read:
        no Python callback runs per sample. The arrival time is the router's timestamp of the
        sample when it has one (samples through a router do), else the time it is read."""
        delivery = inbox.delivery
        sub = self.session.declare_subscriber(key, zenoh.handlers.RingChannel(1 if delivery.latest else delivery.queue))

        def pull() -> tuple[str, Any, int] | None:
            while (sample := sub.try_recv()) is not None:
                if sample.kind == zenoh.SampleKind.PUT:
                    return str(sample.key_expr), sample, _arrival_ns(sample)
            return None

        inbox.pull = pull
        return sub.undeclare

    def session_id(self) -> str:
        return str(self.session.zid())

    def raw_publisher(self, key: str, delivery: Delivery, *, cache: int = 0) -> RawPublisher:
        options = dict(congestion_control=zenoh.CongestionControl.DROP if delivery.congestion == "drop"
                       else zenoh.CongestionControl.BLOCK, express=delivery.express)
        if cache > 0:
            pub = zext.declare_advanced_publisher(self.session, key, cache=zext.CacheConfig(max_samples=cache),
                                                       publisher_detection=True, **options)
        else:
            pub = self.session.declare_publisher(key, **options)
        state = {"matching": True if cache > 0 else _matching(pub)}
        listener = None if cache > 0 else pub.declare_matching_listener(
            lambda st: state.__setitem__("matching", bool(st.matching)))

        def send(payload: bytes, attachment: bytes | None) -> None:
            pub.put(payload, attachment=attachment)

        def undeclare() -> None:
            try:
                if listener is not None:
                    listener.undeclare()
            finally:
                pub.undeclare()  # even when the listener's undeclare fails

        wrapped = RawPublisher(key, send, lambda: state["matching"], undeclare)
        self._closeables.append(wrapped)
        return wrapped

    def _subscribe_raw(self, key: str, inbox: Inbox, history: int) -> Callable[[], None]:
        def on_sample(sample: zenoh.Sample) -> None:
            if sample.kind == zenoh.SampleKind.PUT:
                inbox.push(str(sample.key_expr), sample)

        if history > 0:
            sub = zext.declare_advanced_subscriber(
                self.session, key, on_sample,
                history=zext.HistoryConfig(detect_late_publishers=True, max_samples=history),
                subscriber_detection=True)
        else:
            sub = self.session.declare_subscriber(key, on_sample)
        return sub.undeclare

    def declare_token(self, key: str) -> Token:
        tok = self.session.liveliness().declare_token(key)
        token = Token(key, tok.undeclare)
        self._closeables.append(token)
        return token

    def alive(self, pattern: str, timeout: float = 1.0) -> list[str]:
        keys = {str(r.ok.key_expr) for r in self.session.liveliness().get(pattern, timeout=timeout) if r.ok is not None}
        return sorted(keys)

    def watch_alive(self, pattern: str, callback: Callable[[str, bool], None]) -> Callable[[], None]:
        def on_sample(sample: zenoh.Sample) -> None:
            callback(str(sample.key_expr), sample.kind == zenoh.SampleKind.PUT)

        sub = self.session.liveliness().declare_subscriber(pattern, on_sample, history=True)
        closer = Closer(sub.undeclare)
        self._closeables.append(closer)
        return closer.close  # undeclaring twice (here and at close) is harmless

    def serve(self, key: str, handler: QueryHandler) -> Callable[[], None]:
        def on_query(query: zenoh.Query) -> None:
            params = parse_parameters(str(query.parameters))
            try:
                replies = list(handler(str(query.key_expr), params))
            except (ValueError, KeyError, LookupError) as exc:
                query.reply_err(f"bad query {query.selector}: {exc}".encode())
                return
            for msg in replies:
                query.reply(key, encode(msg), encoding=zenoh.Encoding(_ENCODING))

        q = self.session.declare_queryable(key, on_query)
        closer = Closer(q.undeclare)
        self._closeables.append(closer)
        return closer.close  # undeclaring twice (here and at close) is harmless

    def query(self, selector: str, timeout: float = 1.0) -> list[tuple[str, Message]]:
        out: list[tuple[str, Message]] = []
        for reply in self.session.get(selector, timeout=timeout):
            if reply.ok is None:
                log.warning("query %s answered with an error: %s", selector, reply.err.payload.to_bytes().decode(errors="replace"))
                continue
            try:
                out.append((str(reply.ok.key_expr), decode_any(reply.ok.payload.to_bytes())))
            except DecodeError as exc:
                log.warning("query %s: undecodable reply from %s: %s", selector, reply.ok.key_expr, exc)
        return out

    def _close_session(self) -> None:
        self.session.close()


def open_transport(opts: ZenohOptions) -> ZenohTransport:
    """Open a Zenoh session per ``opts`` and wrap it; raises :class:`TransportError`."""
    log.info("opening Zenoh session: %s", opts.describe())
    return ZenohTransport(open_session(opts))


def open_transport_from_args(args: argparse.Namespace) -> ZenohTransport:
    """The transport of a command's Zenoh flags; a bad flag or no router is a :class:`CliError`."""
    from common.runtime.cli_util import CliError
    from common.transport.zenoh_config import options_from_args

    try:
        return open_transport(options_from_args(args))
    except (TransportError, ValueError) as exc:  # pydantic's ValidationError is a ValueError
        raise CliError(str(exc)) from exc
