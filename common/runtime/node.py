"""One shape for every pipeline node, and one runner from flags to a clean exit.

A node is an object with ``poll(now)`` and ``close()`` (and, if it waits on a clock,
``deadline(now)``) that declares its inputs and outputs once, through its
:class:`NodeIO`:

.. code-block:: python

    class Echo(Node):
        name = "echo"

        def __init__(self, transport, keys, config, counters=None):
            super().__init__(transport, keys, counters)
            self.inp = self.io.subscribe(keys.frames("head"), RGBDFrame, FRAMES)
            self.out = self.io.publisher(keys.detections("head"), Detections, RELIABLE)

        def poll(self, now):
            out = []
            while (got := self.inp.try_recv()) is not None:
                ...  # publish, and append what was published to out
            return out

The status counters and liveliness (:class:`common.runtime.service.ServiceRuntime`) read the
declared subscriptions and publishers; nothing is listed by hand. :func:`run_node` does
the rest, the same way for every node: flags -> layered config (defaults, the file's
section for this node, ``PERCEPTION_<NODE>__FIELD``, flags) -> start-up checks -> the
Zenoh transport -> the node -> liveliness and status -> the loop -> clean shutdown.

Exit codes: 0 after SIGINT/SIGTERM, 2 for a configuration or start-up error (a message
naming the problem, no traceback, never worth a restart), 130 for a second Ctrl-C.
"""

from __future__ import annotations

import argparse
import logging
import time
from pathlib import Path
from typing import Any, Callable, ClassVar, Mapping, TypeVar

from pydantic import BaseModel

from common.runtime.cli_util import CliError, add_key_arguments, keys_from_args
from common.runtime.config import ConfigError, load_config
from common.messages.keys import Delivery, Keys
from common.runtime.service import Counters, ServiceRuntime, Shutdown
from common.runtime.settings import add_settings_epilog
from common.messages.schemas import Message
from common.transport.base import (BasePublisher, BaseSubscription, Publisher, QueryHandler, RawPublisher,
                                   RawSubscription, Subscription, Transport, wait_any)
from common.transport.zenoh_config import add_zenoh_arguments
from common.transport.zenoh import open_transport_from_args

__all__ = ["Node", "NodeIO", "add_node_arguments", "load_node_config", "run_node", "settings_summary"]

log = logging.getLogger(__name__)

M = TypeVar("M", bound=Message)
C = TypeVar("C", bound=BaseModel)

#: How long the loop sleeps waiting for input when a node asks for no earlier poll.
IDLE_WAIT_S = 0.2


class NodeIO:
    """A node's declared subscriptions, publishers and queryables on one transport."""

    def __init__(self, transport: Transport) -> None:
        self.transport = transport
        self.subscriptions: list[BaseSubscription] = []
        self.publishers: list[BasePublisher] = []
        self._undeclare: list[Callable[[], None]] = []

    def subscribe(self, key: str, model: type[M] | None, delivery: Delivery) -> Subscription[M]:
        sub: Subscription[M] = self.transport.subscribe(key, model, delivery)
        self.subscriptions.append(sub)
        return sub

    def publisher(self, key: str, model: type[M], delivery: Delivery) -> Publisher[M]:
        pub = self.transport.publisher(key, model, delivery)
        self.publishers.append(pub)
        return pub

    def subscribe_raw(self, key: str, delivery: Delivery, *, history: int = 0) -> RawSubscription:
        """Foreign payloads (another middleware's, such as ROS 2's CDR), counted like the others."""
        sub = self.transport.subscribe_raw(key, delivery, history=history)
        self.subscriptions.append(sub)
        return sub

    def raw_publisher(self, key: str, delivery: Delivery, *, cache: int = 0) -> RawPublisher:
        pub = self.transport.raw_publisher(key, delivery, cache=cache)
        self.publishers.append(pub)
        return pub

    def serve(self, key: str, handler: QueryHandler) -> None:
        self._undeclare.append(self.transport.serve(key, handler))

    def add(self, *items: BaseSubscription | BasePublisher) -> None:
        """Declare subscriptions or publishers made elsewhere (tools that build their own)."""
        for item in items:
            (self.subscriptions if isinstance(item, BaseSubscription) else self.publishers).append(item)

    def wait(self, timeout: float) -> bool:
        """Sleep until any subscription has input or ``timeout`` s pass."""
        if not self.subscriptions:
            time.sleep(max(0.0, timeout))
            return False
        return wait_any(self.subscriptions, self.transport.notify, max(0.0, timeout))

    def close(self) -> None:
        for fn in self._undeclare:
            fn()
        self._undeclare.clear()
        for item in [*self.subscriptions, *self.publishers]:
            item.close()


class Node:
    """Base of the pipeline nodes: ``io``, ``keys``, ``counters`` and the two loop methods."""

    #: The service name in keys, status and logs.
    name: ClassVar[str] = ""

    def __init__(self, transport: Transport, keys: Keys, counters: Counters | None = None) -> None:
        self.transport = transport
        self.keys = keys
        self.io = NodeIO(transport)
        self.counters = counters if counters is not None else Counters()

    def poll(self, now: float) -> list[Any]:
        """Do the work that has arrived by ``now`` (monotonic seconds); returns what was published."""
        raise NotImplementedError

    def deadline(self, now: float) -> float | None:
        """How soon (s) the node needs a poll even if no input arrives (a join's timeout);
        None means "when input arrives"."""
        return None

    def describe(self) -> str:
        """One line for the start-up log."""
        return ", ".join(s.key for s in self.io.subscriptions) + " -> " + ", ".join(p.key for p in self.io.publishers)

    def close(self) -> None:
        """Release the node's declarations (subclasses flush their state first)."""
        self.io.close()

    def run(self, shutdown: Shutdown, clock: Callable[[], float] = time.monotonic) -> None:
        """Poll until ``shutdown`` is set, sleeping on the inputs in between."""
        while not shutdown.is_set():
            wait = self.deadline(clock())
            self.io.wait(IDLE_WAIT_S if wait is None else min(IDLE_WAIT_S, wait))
            self.poll(clock())


def add_node_arguments(parser: argparse.ArgumentParser, name: str, settings: type[BaseModel] | None = None) -> None:
    """The flags every node has: its settings file, the key namespace and Zenoh's flags; with the
    node's ``settings`` model, its settings listed at the end of ``--help``."""
    if settings is not None:
        add_settings_epilog(parser, settings, name)
    parser.add_argument("--service-config", type=Path, default=None, metavar="FILE",
                        help=f"YAML/JSON settings; its '{name}' section if it has one, else the whole file "
                             f"(env PERCEPTION_{name.upper()}__FIELD overrides it, flags override both)")
    add_key_arguments(parser)
    add_zenoh_arguments(parser)


def _prune(tree: Mapping[str, Any]) -> dict[str, Any]:
    """``tree`` without None leaves and empty sub-mappings (unset flags override nothing)."""
    out: dict[str, Any] = {}
    for k, v in tree.items():
        if isinstance(v, Mapping):
            v = _prune(v)
            if v:
                out[k] = v
        elif v is not None:
            out[k] = v
    return out


def _text(value: Any) -> str | None:
    """A scalar setting as text, or None if ``value`` is not a scalar."""
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, (str, int, float, Path)):
        return str(value)
    return None


def settings_summary(config: BaseModel) -> dict[str, str]:
    """``config``'s top-level settings as text, for the status (``perception doctor`` reads them).

    A scalar is written as is, a list of scalars comma-separated, a mapping as its keys
    (``appearance: colour,trinet``), a list of records as how many there are; nested
    sections and unset (None) values are left out.
    """
    out: dict[str, str] = {}
    for name in type(config).model_fields:
        value = getattr(config, name)
        if value is None or isinstance(value, BaseModel):
            continue
        if isinstance(value, Mapping):
            out[name] = ",".join(sorted(str(k) for k in value))
        elif isinstance(value, (list, tuple)):
            items = [_text(v) for v in value]
            out[name] = ",".join(t for t in items if t is not None) if all(t is not None for t in items) else str(len(value))
        elif (text := _text(value)) is not None:
            out[name] = text
    return out


#: Set by ``perception launch`` for a service whose settings come from its launch file: what to
#: name in a configuration error instead of the temporary file they were written to.
CONFIG_ORIGIN_ENV = "PERCEPTION_CONFIG_ORIGIN"


def load_node_config(model: type[C], name: str, path: str | Path | None, overrides: Mapping[str, Any],
                     base: Mapping[str, Any] | None = None) -> C:
    """Defaults -> ``base`` (a preset) -> ``path`` (section ``name`` if present) -> ``PERCEPTION_<NAME>__*``
    -> overrides.

    A bad value is a :class:`CliError` naming the field, the file and how to fix it (the launch
    file and its entry when ``perception launch`` wrote the file).
    """
    import os

    env = f"PERCEPTION_{name.upper()}"
    try:
        return load_config(model, path, env_prefix=env, overrides=_prune(overrides), section=name, base=base)
    except ConfigError as exc:
        origin = os.environ.get(CONFIG_ORIGIN_ENV, "")
        text = str(exc).replace(str(path), origin) if origin and path is not None else str(exc)
        where = origin if origin and path is not None else (path or "the flags")
        raise CliError(f"{text}\n(fix it in {where} or the {env}__* environment)") from exc


def run_node(args: argparse.Namespace, name: str, config_model: type[C], overrides: Mapping[str, Any],
             build: Callable[..., Node], *, prepare: Callable[[C], Mapping[str, Any]] | None = None,
             adjust: Callable[[C], C] | None = None, base: Mapping[str, Any] | None = None) -> int:
    """Run one node from its parsed flags until SIGINT/SIGTERM; the process's exit status.

    ``prepare(config)`` runs before the transport opens (load a model, check a file) and
    returns extra keyword arguments for ``build``; ``adjust(config)`` may rewrite the
    validated config (flags that cannot be plain overrides); ``base`` is a layer of settings under
    the ``--service-config`` file's (a preset). A ``ValueError`` (or
    ``ConfigError``) from either, or from ``build``, stops the node with exit status 2.
    """
    config = load_node_config(config_model, name, getattr(args, "service_config", None), overrides, base)
    if adjust is not None:
        config = adjust(config)
    keys = keys_from_args(args)
    try:
        prepared = dict(prepare(config)) if prepare is not None else {}
    except (ValueError, ConfigError) as exc:
        raise CliError(str(exc)) from exc
    transport = open_transport_from_args(args)
    counters = Counters()
    with transport, Shutdown() as shutdown:
        # the node subscribes before its liveliness token appears: 'alive' means 'listening'
        try:
            node = build(transport, keys, config, counters, **prepared)
        except (ValueError, ConfigError) as exc:
            raise CliError(f"cannot start the {name}: {exc}") from exc
        try:
            with ServiceRuntime(name, transport, keys, counters=counters, io=node.io,
                                settings=settings_summary(config)):
                log.info("%s: %s", name, node.describe())
                node.run(shutdown)
        finally:
            node.close()
    return 0
