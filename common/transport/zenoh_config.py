"""Zenoh session configuration from a JSON5 file and/or the flags of zenoh-python's examples.

Flags: ``--mode``, ``--connect``, ``--listen``, ``--config``, ``--no-multicast-scouting``,
plus ``--connect-timeout`` and ``--credentials``. The environment variable
``PERCEPTION_ZENOH_CONNECT`` (comma-separated endpoints) sits between the file and the
flags, ``PERCEPTION_ZENOH_CONFIG`` names a config file when ``--config`` is not given and
``PERCEPTION_ZENOH_CREDENTIALS`` a credentials file when ``--credentials`` is not given.
TLS files in the config file are resolved against its folder and checked
(:mod:`common.transport.zenoh_security`).

Defaults are the robot's: a client of the local router at ``tcp/127.0.0.1:7447``, with
fast reconnect retries (a restarted router is rejoined in about 0.1 s rather than 4 s).
"""

from __future__ import annotations

import argparse
import json
import os
from pathlib import Path
from typing import Literal

from pydantic import BaseModel, Field, ValidationError, field_validator

__all__ = ["DEFAULT_ROUTER", "SHM_THRESHOLD_BYTES", "ZenohFlagError", "ZenohOptions", "add_zenoh_arguments",
           "build_zenoh_config", "options_from_args"]

DEFAULT_ROUTER = "tcp/127.0.0.1:7447"
_RETRY = {"period_init_ms": 100, "period_max_ms": 500, "period_increase_factor": 2}
#: Only messages of at least this size go through Zenoh's shared memory (its default is
#: 3,072 B). The first time a process publishes a message over the threshold it creates a
#: 16 MiB pool, and every process that receives from the pool maps all of it: with 3 KB,
#: an Embeddings or Tracks message with one person more than usual made the router, the
#: embedder and the tracker grow 16-27 MiB each, mid-run (the soak's RSS steps). Messages of
#: a few KB gain nothing from shared memory; camera frames (hundreds of KB) still use it.
SHM_THRESHOLD_BYTES = 65536
_SHM_THRESHOLD_KEY = "transport/shared_memory/transport_optimization/message_size_threshold"


class ZenohOptions(BaseModel):
    """How to open a Zenoh session."""

    mode: Literal["client", "peer", "router"] = "client"
    connect: list[str] = Field(default_factory=list)
    listen: list[str] = Field(default_factory=list)
    config_file: Path | None = None
    multicast_scouting: bool = False
    connect_timeout_s: float = Field(default=10.0, description="how long open() waits for the router; <0 waits forever")
    shared_memory: bool = True
    access_control: bool = Field(default=False, description="routers: enforce common.transport.acl's least-privilege rules")
    credentials: Path | None = Field(default=None, description="USER:PASSWORD file (mode 0600) for Zenoh's "
                                     "user/password authentication")
    timestamping: bool = Field(default=False, description="timestamp every sample, as rmw_zenoh's sessions do (a "
                                                          "transient-local ROS 2 publisher, a cached one, needs it)")

    @field_validator("connect", "listen")
    @classmethod
    def _endpoints(cls, v: list[str]) -> list[str]:
        for e in v:
            proto, sep, addr = e.partition("/")
            if not sep or not addr or proto not in {"tcp", "udp", "tls", "quic", "ws", "unixsock-stream", "unixpipe", "serial"}:
                hint = f"; did you mean tcp/{e}?" if not sep else ""
                raise ValueError(f"endpoint {e!r} is not of the form PROTO/ADDRESS, e.g. tcp/192.168.1.10:7447{hint}")
        return v

    @field_validator("config_file")
    @classmethod
    def _exists(cls, v: Path | None) -> Path | None:
        if v is not None and not v.is_file():
            raise ValueError(f"Zenoh config file {v} does not exist")
        return v

    def effective_connect(self) -> list[str]:
        """The endpoints a client connects to: the given ones, else the local router."""
        if self.connect or self.mode != "client" or self.config_file is not None:
            return self.connect
        return [DEFAULT_ROUTER]

    def describe(self) -> str:
        parts = [self.mode]
        if self.effective_connect():
            parts.append("connect " + ",".join(self.effective_connect()))
        if self.listen:
            parts.append("listen " + ",".join(self.listen))
        if self.config_file:
            parts.append(f"config {self.config_file}")
        if self.credentials:
            parts.append(f"credentials {self.credentials}")
        return ", ".join(parts)


def add_zenoh_arguments(parser: argparse.ArgumentParser, *, default_mode: str = "client") -> None:
    """Add the zenoh-python example flags to ``parser``."""
    g = parser.add_argument_group("Zenoh")
    g.add_argument("--mode", "-m", choices=("client", "peer", "router"), default=None,
                   help=f"Zenoh session mode (default: {default_mode})")
    g.add_argument("--connect", "-e", action="append", default=None, metavar="ENDPOINT",
                   help=f"endpoint to connect to, repeatable (default for clients: {DEFAULT_ROUTER})")
    g.add_argument("--listen", "-l", action="append", default=None, metavar="ENDPOINT",
                   help="endpoint to listen on, repeatable, e.g. tcp/127.0.0.1:7447")
    g.add_argument("--config", "-c", type=Path, default=None, metavar="FILE",
                   help="Zenoh JSON5 config file; the flags above override it")
    g.add_argument("--no-multicast-scouting", dest="multicast_scouting", action="store_false", default=None,
                   help="disable multicast scouting (the default here; see --multicast-scouting)")
    g.add_argument("--multicast-scouting", dest="multicast_scouting", action="store_true",
                   help="enable multicast discovery of peers on the LAN")
    g.add_argument("--connect-timeout", type=float, default=None, metavar="S",
                   help="seconds to wait for the router at start-up, -1 to wait forever (default 10)")
    g.add_argument("--credentials", type=Path, default=None, metavar="FILE",
                   help="USER:PASSWORD file (mode 0600) for the router's password check, e.g. "
                        "deploy/secure/certs/credentials/monitor.txt (env PERCEPTION_ZENOH_CREDENTIALS)")
    parser.set_defaults(_zenoh_default_mode=default_mode)


def options_from_args(args: argparse.Namespace) -> ZenohOptions:
    """Layer defaults, ``PERCEPTION_ZENOH_*`` environment and flags into options."""
    values: dict[str, object] = {"mode": getattr(args, "_zenoh_default_mode", "client")}
    env_connect = os.environ.get("PERCEPTION_ZENOH_CONNECT")
    if env_connect:
        values["connect"] = [e.strip() for e in env_connect.split(",") if e.strip()]
    env_config = os.environ.get("PERCEPTION_ZENOH_CONFIG")
    if env_config:
        values["config_file"] = Path(env_config)
    env_credentials = os.environ.get("PERCEPTION_ZENOH_CREDENTIALS")
    if env_credentials:
        values["credentials"] = Path(env_credentials)
    flags = {
        "mode": args.mode,
        "connect": args.connect,
        "listen": args.listen,
        "config_file": args.config,
        "multicast_scouting": args.multicast_scouting,
        "connect_timeout_s": args.connect_timeout,
        "credentials": getattr(args, "credentials", None),
    }
    values.update({k: v for k, v in flags.items() if v is not None})
    try:
        return ZenohOptions.model_validate(values)
    except ValidationError as exc:
        raise ZenohFlagError("; ".join(_flag_message(e) for e in exc.errors(include_url=False))) from exc


class ZenohFlagError(ValueError):
    """A Zenoh flag (or its ``PERCEPTION_ZENOH_*`` variable) that cannot be used: one line naming it."""


_FLAG_OF = {"mode": "--mode", "connect": "--connect", "listen": "--listen", "config_file": "--config",
            "multicast_scouting": "--multicast-scouting", "connect_timeout_s": "--connect-timeout",
            "credentials": "--credentials"}


def _flag_message(error: object) -> str:
    err = dict(error)  # type: ignore[call-overload]
    field = str(err["loc"][0]) if err.get("loc") else ""
    msg = str(err["msg"]).removeprefix("Value error, ")
    return f"{_FLAG_OF.get(field, field)}: {msg}" if field else msg


def build_zenoh_config(opts: ZenohOptions) -> "zenoh.Config":  # type: ignore[name-defined]  # noqa: F821
    """The ``zenoh.Config`` for ``opts``: file first, then the explicit settings on top.

    Raises :class:`common.transport.zenoh_security.SecurityError` naming a missing, unreadable or
    expired certificate, or a key or credentials file that others can read.
    """
    import zenoh

    from common.transport.zenoh_security import secure_config

    conf = zenoh.Config.from_file(str(opts.config_file)) if opts.config_file else zenoh.Config()
    secure_config(conf, opts.config_file, opts.credentials)
    if opts.config_file is None or json.loads(conf.get_json(_SHM_THRESHOLD_KEY)) == 3072:  # a file's own value stays
        conf.insert_json5(_SHM_THRESHOLD_KEY, str(SHM_THRESHOLD_BYTES))
    conf.insert_json5("mode", json.dumps(opts.mode))
    connect = opts.effective_connect()
    if connect:
        conf.insert_json5("connect/endpoints", json.dumps(connect))
    if opts.listen:
        conf.insert_json5("listen/endpoints", json.dumps(opts.listen))
    conf.insert_json5("scouting/multicast/enabled", json.dumps(opts.multicast_scouting))
    if opts.mode != "router" or connect:
        timeout_ms = -1 if opts.connect_timeout_s < 0 else int(opts.connect_timeout_s * 1000)
        conf.insert_json5("connect/timeout_ms", json.dumps(timeout_ms))
        conf.insert_json5("connect/exit_on_failure", "false" if opts.mode == "router" else "true")
        conf.insert_json5("connect/retry", json.dumps(_RETRY))
    if not opts.shared_memory:
        conf.insert_json5("transport/shared_memory/enabled", "false")
    if opts.timestamping:
        conf.insert_json5("timestamping/enabled", "true")
    if opts.access_control:
        from common.transport.acl import access_control

        conf.insert_json5("access_control", json.dumps(access_control()))
    return conf
