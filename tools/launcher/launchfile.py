"""The launch file: a validated YAML description of the processes ``perception launch`` runs.

Loading is three steps, all before anything is started:

1. parse the YAML (a mapping at the top);
2. substitute ``${VAR}``, ``${VAR:-default}`` (unset or empty) and ``${VAR-default}`` (unset
   only) in every string value from the environment; ``$$`` is a literal ``$``;
3. validate with pydantic (``extra="forbid"`` everywhere), resolving relative paths against
   the launch file's folder.

Any problem raises :class:`LaunchFileError` whose message names the file and the field,
e.g. ``services[1] (tracker).restart: Input should be 'always', 'on-failure' or 'never'``.
Service configs are passed through untouched: each service validates its own.
"""

from __future__ import annotations

import re
from collections.abc import Mapping
from pathlib import Path
from typing import Annotated, Any, Literal

import yaml
from pydantic import BaseModel, BeforeValidator, ConfigDict, Field, ValidationError, field_validator, model_validator

from common.runtime.settings import setting

from common.messages.keys import validate_chunk
from common.transport.zenoh_config import ZenohOptions

__all__ = ["Backoff", "LaunchFile", "LaunchFileError", "RouterSpec", "ServiceSpec", "ZenohDefaults",
           "load_launch_file", "substitute"]

_VAR = re.compile(r"\$(?:(\$)|\{([A-Za-z_][A-Za-z0-9_]*)(?:(:?-)([^}]*))?\}|(\{[^}]*\}?))")
_NAME = r"^[A-Za-z0-9][A-Za-z0-9_.-]*$"


class LaunchFileError(ValueError):
    """A launch file that cannot be used; the message names the file and the field."""


def _env_value(v: Any) -> Any:
    if isinstance(v, bool):
        return "true" if v else "false"
    return str(v) if isinstance(v, (int, float)) else v


#: A string that YAML may have typed as a number or boolean (``8080``, ``true``).
EnvValue = Annotated[str, BeforeValidator(_env_value)]
Arg = EnvValue
Endpoints = list[str]


def _check_endpoints(v: list[str]) -> list[str]:
    try:
        ZenohOptions(connect=v)
    except ValidationError as exc:
        raise ValueError(str(exc.errors(include_url=False)[0]["msg"]).removeprefix("Value error, ")) from exc
    return v


class _Strict(BaseModel):
    model_config = ConfigDict(extra="forbid", frozen=True)


class Backoff(_Strict):
    """Restart delays after a crash: ``initial_s``, doubled each time up to ``max_s``.

    Back to ``initial_s`` once the child has run ``stable_after_s`` without exiting.
    """

    initial_s: float = setting(0.5, "first restart delay", unit="s", gt=0.0, le=3600.0)
    max_s: float = setting(30.0, "longest restart delay", unit="s", gt=0.0, le=3600.0)
    stable_after_s: float = setting(10.0, "a run this long resets the delay to initial_s",
                                    unit="s", ge=0.0, le=86400.0)

    @model_validator(mode="after")
    def _ordered(self) -> Backoff:
        if self.max_s < self.initial_s:
            raise ValueError(f"max_s ({self.max_s}) must be at least initial_s ({self.initial_s})")
        return self


class RouterSpec(_Strict):
    """``perception router`` on this PC, started first and waited for until it accepts TCP."""

    listen: Endpoints = setting(description="endpoints this router listens on",
                                default_factory=lambda: ["tcp/127.0.0.1:7447"], min_length=1)
    connect: Endpoints = setting(description="other routers to connect to (the other PC's)", default_factory=list)
    config: Path | None = setting(None, "Zenoh JSON5 file; listen/connect above override it")
    credentials: Path | None = setting(None, "USER:PASSWORD file (mode 0600) the router presents to the other PC's "
                                       "router")
    args: list[Arg] = setting(description="extra flags for perception router", default_factory=list)
    env: dict[str, EnvValue] = setting(description="environment of the router's process", default_factory=dict)
    ready_timeout_s: float = setting(20.0, "how long to wait for the router to accept connections",
                                     unit="s", gt=0.0, le=600.0)
    stop_timeout_s: float = setting(5.0, "SIGTERM, then SIGKILL after this long", unit="s", gt=0.0, le=600.0)
    backoff: Backoff = setting(description="restart delays after a crash", default_factory=Backoff)

    @field_validator("listen", "connect")
    @classmethod
    def _ep(cls, v: list[str]) -> list[str]:
        return _check_endpoints(v)


class ZenohDefaults(_Strict):
    """Zenoh settings passed to every ``command:`` service (and as environment to ``exec:`` ones)."""

    connect: Endpoints | None = setting(None, "router endpoints; default: the router's first listen endpoint, else "
                                        "the services' own default (tcp/127.0.0.1:7447)")
    config: Path | None = setting(None, "Zenoh JSON5 file passed as --config")
    credentials: Path | None = setting(None, "USER:PASSWORD file (mode 0600) of the launcher's own session (it "
                                       "reports services that stopped for good)")

    @field_validator("connect")
    @classmethod
    def _ep(cls, v: list[str] | None) -> list[str] | None:
        return None if v is None else _check_endpoints(v)


class ServiceSpec(_Strict):
    """One supervised child: a ``perception`` sub-command or any program (``exec``)."""

    name: str = setting(..., "unique; prefixes the child's output", pattern=_NAME, max_length=40)
    command: str | None = setting(None, "perception sub-command, e.g. tracker", pattern=_NAME)
    exec_: list[Arg] | None = setting(None, "argv of a program to run instead of a perception sub-command",
                                      alias="exec", min_length=1)
    args: list[Arg] = setting(description="extra arguments, appended last", default_factory=list)
    config: dict[str, Any] | Path | None = setting(None, "inline mapping (written to a temp YAML under the section "
                                                   "named config_section) or a file path relative to the launch file; "
                                                   "passed with config_flag")
    config_flag: str = setting("--service-config", "the flag that takes the service's YAML config file",
                               pattern=r"^--?[A-Za-z0-9][A-Za-z0-9-]*$")
    config_section: str | None = setting(None, "top-level key an inline config is written under (default: the "
                                         "command's name; '' writes it as the whole file)")
    connect: Endpoints | None = setting(None, "overrides zenoh.connect for this service")
    credentials: Path | None = setting(None, "this service's USER:PASSWORD file (mode 0600), passed as --credentials "
                                       "(as PERCEPTION_ZENOH_CREDENTIALS to exec: programs)")
    common_flags: bool = setting(True, "pass --robot/--connect/--config (Zenoh) to the command")
    env: dict[str, EnvValue] = setting(description="environment of this child, over the file's env", default_factory=dict)
    restart: Literal["always", "on-failure", "never"] = setting("on-failure", "when to restart the child once it exits "
                                                                "(on-failure: a non-zero status)")
    restart_prevent_exit_status: list[Annotated[int, Field(ge=1, le=255)]] = setting(
        description="exit statuses never restarted, whatever restart says (systemd's RestartPreventExitStatus); 2 is "
                    "a perception command's configuration or start-up error", default_factory=lambda: [2])
    backoff: Backoff = setting(description="restart delays after a crash", default_factory=Backoff)
    stop_timeout_s: float = setting(10.0, "SIGTERM, then SIGKILL after this many seconds", unit="s", gt=0.0, le=600.0)
    enabled: bool = setting(True, "false: the service is in the file but not started")

    model_config = ConfigDict(extra="forbid", frozen=True, populate_by_name=True)

    @field_validator("connect")
    @classmethod
    def _ep(cls, v: list[str] | None) -> list[str] | None:
        return None if v is None else _check_endpoints(v)

    @model_validator(mode="after")
    def _one_program(self) -> ServiceSpec:
        if (self.command is None) == (self.exec_ is None):
            raise ValueError("give exactly one of 'command' (a perception sub-command) or 'exec' (an argv list)")
        return self

    def section(self) -> str | None:
        """The key an inline config is nested under in the written file (None: the whole file)."""
        if self.config_section is not None:
            return self.config_section or None
        return self.command


class LaunchFile(_Strict):
    """The whole launch file."""

    robot: str | None = setting(None, "robot name in every key (--robot)")
    key_prefix: str | None = setting(None, "first key segment(s) (--key-prefix env)")
    env: dict[str, EnvValue] = setting(description="environment for every child", default_factory=dict)
    router: RouterSpec | None = setting(None, "a router to start on this PC first; none: no router")
    zenoh: ZenohDefaults = setting(description="Zenoh settings of every service", default_factory=ZenohDefaults)
    services: list[ServiceSpec] = setting(description="the supervised children, started in this order",
                                          default_factory=list)

    @field_validator("robot")
    @classmethod
    def _robot(cls, v: str | None) -> str | None:
        return None if v is None else validate_chunk(v, "robot name")

    @model_validator(mode="after")
    def _unique(self) -> LaunchFile:
        seen: set[str] = {"router"} if self.router is not None else set()
        for s in self.services:
            if s.name in seen:
                why = "is the router's name" if s.name == "router" else "is used twice"
                raise ValueError(f"service name {s.name!r} {why}; names must be unique")
            seen.add(s.name)
        if not self.services and self.router is None:
            raise ValueError("nothing to launch: give a router and/or services")
        return self


def substitute(data: Any, environ: Mapping[str, str], where: str = "") -> Any:
    """``data`` with ``${VAR}`` references in its string values replaced from ``environ``."""
    if isinstance(data, dict):
        return {k: substitute(v, environ, f"{where}.{k}" if where else str(k)) for k, v in data.items()}
    if isinstance(data, list):
        return [substitute(v, environ, f"{where}[{i}]") for i, v in enumerate(data)]
    if not isinstance(data, str) or "$" not in data:
        return data

    def one(m: re.Match[str]) -> str:
        dollar, name, op, default, bad = m.groups()
        if dollar:
            return "$"
        if bad is not None:
            raise LaunchFileError(f"{where or '(root)'}: malformed reference '${bad}' "
                                  "(use ${VAR}, ${VAR:-default} or $$ for a literal $)")
        value = environ.get(name)
        if value is None or (op == ":-" and value == ""):
            if op is None:
                raise LaunchFileError(f"{where or '(root)'}: environment variable {name} is not set "
                                      f"(set it, or write ${{{name}:-default}})")
            return default
        return value

    return _VAR.sub(one, data)


def _field_path(loc: tuple[Any, ...], raw: Mapping[str, Any]) -> str:
    out = ""
    node: Any = raw
    for part in loc:
        if isinstance(part, int):
            out += f"[{part}]"
            try:
                node = node[part]
            except (IndexError, KeyError, TypeError):
                node = None
            if isinstance(node, dict) and isinstance(node.get("name"), str) and out.startswith("services"):
                out += f" ({node['name']})"
        else:
            out += f".{part}" if out else str(part)
            node = node.get(part) if isinstance(node, dict) else None
    return out or "(root)"


def _resolve(p: Path | None, base: Path, field: str) -> Path | None:
    if p is None:
        return None
    path = p.expanduser() if p.is_absolute() or str(p).startswith("~") else base / p
    if not path.is_file():
        hint = " (make the certificates and credentials with `perception certs DIR`)" if field.endswith("credentials") else ""
        raise LaunchFileError(f"{field}: file {path} does not exist{hint}")
    return path


def load_launch_file(path: str | Path, environ: Mapping[str, str]) -> LaunchFile:
    """Read, substitute and validate ``path``; relative file paths become absolute."""
    p = Path(path)
    try:
        raw = yaml.safe_load(p.read_text())
    except FileNotFoundError as exc:
        raise LaunchFileError(f"launch file {p} does not exist") from exc
    except (OSError, UnicodeDecodeError, yaml.YAMLError) as exc:
        raise LaunchFileError(f"launch file {p} cannot be read: {exc}") from exc
    if not isinstance(raw, dict):
        raise LaunchFileError(f"launch file {p} must hold a mapping (robot, router, zenoh, services...)")
    try:
        data = substitute(raw, environ)
        launch = LaunchFile.model_validate(data)
    except LaunchFileError as exc:
        raise LaunchFileError(f"invalid launch file {p}: {exc}") from exc
    except ValidationError as exc:
        lines = []
        for err in exc.errors(include_url=False):
            value = err.get("input")
            shown = "" if isinstance(value, (dict, list)) or value is None else f" (got {value!r})"
            msg = str(err["msg"]).removeprefix("Value error, ")
            if isinstance(value, bool) and err["type"] == "string_type":
                msg += "; YAML reads yes/no/on/off/true/false as booleans, quote the value"
            lines.append(f"{_field_path(tuple(err['loc']), data)}: {msg}{shown}")
        raise LaunchFileError(f"invalid launch file {p}:\n  " + "\n  ".join(lines)) from exc
    base = p.resolve().parent
    try:
        updates: dict[str, Any] = {}
        if launch.router is not None:
            updates["router"] = launch.router.model_copy(update={
                "config": _resolve(launch.router.config, base, "router.config"),
                "credentials": _resolve(launch.router.credentials, base, "router.credentials")})
        updates["zenoh"] = launch.zenoh.model_copy(update={
            "config": _resolve(launch.zenoh.config, base, "zenoh.config"),
            "credentials": _resolve(launch.zenoh.credentials, base, "zenoh.credentials")})
        services = []
        for i, s in enumerate(launch.services):
            where = f"services[{i}] ({s.name})"
            if isinstance(s.config, Path):
                s = s.model_copy(update={"config": _resolve(s.config, base, f"{where}.config")})
            if s.credentials is not None:
                s = s.model_copy(update={"credentials": _resolve(s.credentials, base, f"{where}.credentials")})
            services.append(s)
        updates["services"] = services
    except LaunchFileError as exc:
        raise LaunchFileError(f"invalid launch file {p}: {exc}") from exc
    return launch.model_copy(update=updates)
