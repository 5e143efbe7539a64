"""From a validated launch file to the exact processes to start (argv, environment, policy)."""

from __future__ import annotations

import re
import shlex
import sys
from collections.abc import Collection, Mapping, Sequence
from pathlib import Path

import yaml

from common.runtime.node import CONFIG_ORIGIN_ENV
from tools.launcher.launchfile import LaunchFile, LaunchFileError, RouterSpec, ServiceSpec
from tools.launcher.supervisor import ProcessSpec

__all__ = ["build_plan", "connectable", "perception_argv", "render_plan", "router_port", "services_connect"]

ROUTER_NAME = "router"
_TCP = re.compile(r"^(tcp|tls)/(\[[0-9A-Fa-f:.]+\]|[^:/\[\]]+):(\d+)$")


def perception_argv(command: str, *args: str) -> list[str]:
    """How to run ``perception COMMAND ARGS``: this interpreter, so the venv needs no PATH."""
    return [sys.executable, "-m", "perception", command, *args]


def connectable(endpoint: str) -> str:
    """A listen endpoint as a local client would dial it (``0.0.0.0`` -> ``127.0.0.1``)."""
    m = _TCP.match(endpoint)
    if m is None:
        return endpoint
    host = {"0.0.0.0": "127.0.0.1", "[::]": "[::1]"}.get(m.group(2), m.group(2))
    return f"{m.group(1)}/{host}:{m.group(3)}"


def router_port(router: RouterSpec) -> tuple[str, int] | None:
    """(host, port) to poll for readiness: the first TCP or TLS listen endpoint, or None."""
    for ep in router.listen:
        m = _TCP.match(connectable(ep))
        if m is not None:
            return m.group(2).strip("[]"), int(m.group(3))
    return None


def _router_spec(launch: LaunchFile, base_env: Mapping[str, str]) -> ProcessSpec:
    r = launch.router
    assert r is not None
    args = [f"--listen={e}" for e in r.listen] + [f"--connect={e}" for e in r.connect] + ["--no-multicast-scouting"]
    if r.config is not None:
        args += ["--config", str(r.config)]
    if r.credentials is not None:
        args += ["--credentials", str(r.credentials)]
    return ProcessSpec(
        name=ROUTER_NAME, argv=perception_argv("router", *args, *r.args), env={**base_env, **r.env},
        restart="always", backoff_initial_s=r.backoff.initial_s, backoff_max_s=r.backoff.max_s,
        stable_after_s=r.backoff.stable_after_s, stop_timeout_s=r.stop_timeout_s, stop_last=True,
        ready_tcp=router_port(r), ready_timeout_s=r.ready_timeout_s,
    )


def _config_file(s: ServiceSpec, config_dir: Path) -> Path | None:
    if s.config is None or isinstance(s.config, Path):
        return s.config
    section = s.section()
    data = {section: s.config} if section else s.config
    config_dir.mkdir(parents=True, exist_ok=True)
    path = config_dir / f"{s.name}.yaml"
    path.write_text(f"# written by perception launch for service {s.name!r}\n"
                    + yaml.safe_dump(data, sort_keys=False, default_flow_style=False), encoding="utf-8")
    return path


def _service_spec(launch: LaunchFile, s: ServiceSpec, connect: list[str] | None, base_env: Mapping[str, str],
                  config_dir: Path, origin: str = "") -> ProcessSpec:
    env = {**base_env, **s.env}
    if origin and s.config is not None and not isinstance(s.config, Path):
        env[CONFIG_ORIGIN_ENV] = f"{origin}, the config of service {s.name!r}"
    connect = s.connect if s.connect is not None else connect
    if connect:
        env["PERCEPTION_ZENOH_CONNECT"] = ",".join(connect)
    if s.credentials is not None:
        env["PERCEPTION_ZENOH_CREDENTIALS"] = str(s.credentials)
    config = _config_file(s, config_dir)
    if s.exec_ is not None:
        argv = [*s.exec_, *([s.config_flag, str(config)] if config else []), *s.args]
    else:
        assert s.command is not None
        flags: list[str] = []
        if s.common_flags:
            if launch.robot is not None:
                flags += ["--robot", launch.robot]
            flags += [f"--connect={e}" for e in connect or []]
            if launch.zenoh.config is not None:
                flags += ["--config", str(launch.zenoh.config)]
            if s.credentials is not None:
                flags += ["--credentials", str(s.credentials)]
        if config is not None:
            flags += [s.config_flag, str(config)]
        argv = perception_argv(s.command, *flags, *s.args)
    return ProcessSpec(
        name=s.name, argv=argv, env=env, restart=s.restart, backoff_initial_s=s.backoff.initial_s,
        backoff_max_s=s.backoff.max_s, stable_after_s=s.backoff.stable_after_s, stop_timeout_s=s.stop_timeout_s,
        no_restart_status=tuple(s.restart_prevent_exit_status),
    )


def services_connect(launch: LaunchFile) -> list[str] | None:
    """The router endpoints ``command:`` services connect to: ``zenoh.connect``, else the
    router's first listen endpoint, else None (the services' own default)."""
    if launch.zenoh.connect is not None:
        return list(launch.zenoh.connect)
    if launch.router is not None:
        return [connectable(launch.router.listen[0])]
    return None


def build_plan(launch: LaunchFile, environ: Mapping[str, str], config_dir: Path,
               only: Collection[str] = (), origin: str = "") -> list[ProcessSpec]:
    """The processes to start, in start order (router first), with inline configs written to ``config_dir``.

    ``only`` names the entries to start (services and/or ``router``); empty means every
    enabled entry. Naming a disabled service starts it. ``origin``: the launch file, named in a
    service's configuration errors instead of the temporary file its inline ``config`` is written to.
    """
    names = ([ROUTER_NAME] if launch.router is not None else []) + [s.name for s in launch.services]
    unknown = sorted(set(only) - set(names))
    if unknown:
        raise LaunchFileError(f"--only names {', '.join(map(repr, unknown))} not in the launch file "
                              f"(entries: {', '.join(names)})")
    base_env = {**environ, **launch.env, "PYTHONUNBUFFERED": "1"}
    if launch.robot is not None:
        base_env["PERCEPTION_ROBOT"] = launch.robot
    if launch.key_prefix is not None:
        base_env["PERCEPTION_KEY_PREFIX"] = launch.key_prefix
    if launch.zenoh.config is not None:
        base_env["PERCEPTION_ZENOH_CONFIG"] = str(launch.zenoh.config)
    connect = services_connect(launch)
    plan: list[ProcessSpec] = []
    if launch.router is not None and (not only or ROUTER_NAME in only):
        plan.append(_router_spec(launch, base_env))
    for s in launch.services:
        if (s.name in only) if only else s.enabled:
            plan.append(_service_spec(launch, s, connect, base_env, config_dir, origin))
    if not plan:
        raise LaunchFileError("nothing to start: every service is disabled (enabled: false) or left out by --only")
    return plan


def render_plan(launch: LaunchFile, plan: list[ProcessSpec], environ: Mapping[str, str]) -> str:
    """A human-readable description of ``plan`` for ``--dry-run``."""
    started = {p.name for p in plan}
    lines = [f"robot: {launch.robot or '(services default)'}"]
    for i, p in enumerate(plan, 1):
        policy = f"restart {p.restart}" + (
            "" if p.restart == "never" else f", backoff {p.backoff_initial_s:g}s x2 up to {p.backoff_max_s:g}s, "
            f"reset after {p.stable_after_s:g}s") + (
            f", never after exit status {', '.join(map(str, p.no_restart_status))}" if p.no_restart_status else "")
        lines.append(f"{i}. {p.name}: {policy}; stop: SIGTERM, SIGKILL after {p.stop_timeout_s:g}s")
        if p.ready_tcp is not None:
            lines.append(f"   waits until {p.ready_tcp[0]}:{p.ready_tcp[1]} accepts TCP (up to {p.ready_timeout_s:g}s)")
        lines.append(f"   $ {shlex.join(p.argv)}")
        changed = {k: v for k, v in p.env.items() if environ.get(k) != v and k != "PYTHONUNBUFFERED"}
        for k, v in sorted(changed.items()):
            lines.append(f"   env {k}={v}")
        for path in _config_paths(p.argv):
            temporary = path.parent.name.startswith("perception-launch-")
            lines.append(f"   config {path}{' (a new temporary file at each launch)' if temporary else ''}:")
            lines += [f"     | {line}" for line in path.read_text().splitlines() if not line.startswith("#")]
    skipped = [s.name for s in launch.services if s.name not in started]
    if skipped:
        lines.append(f"not started (disabled or not in --only): {', '.join(skipped)}")
    return "\n".join(lines)


def _config_paths(argv: Sequence[str]) -> list[Path]:
    return [Path(a) for a in argv if a.endswith((".yaml", ".yml")) and Path(a).is_file()]
