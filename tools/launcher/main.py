"""``perception launch FILE``: start the processes of a launch file and supervise them."""

from __future__ import annotations

import argparse
import logging
import os
import shutil
import sys
import tempfile
from pathlib import Path

from common.runtime.cli_util import CliError
from common.messages.keys import DEFAULT_PREFIX, DEFAULT_ROBOT, Keys
from common.transport.zenoh_config import ZenohOptions
from tools.launcher.launchfile import LaunchFile, LaunchFileError, load_launch_file
from tools.launcher.plan import build_plan, render_plan, services_connect
from tools.launcher.report import FailureReport
from tools.launcher.supervisor import Supervisor

log = logging.getLogger(__name__)

DESCRIPTION = """\
Start the router and services described by a launch file (see deploy/*.yaml) as
supervised child processes, in order: the router first (waited for until it accepts
TCP connections), then the services.

- Every child's output is forwarded with its name as a prefix: '[tracker]  ...'.
- A child that crashes is restarted with exponential backoff (restart: always,
  on-failure or never; backoff: initial_s, x2, max_s; reset after stable_after_s).
- A child that exits with status 2 (a configuration or start-up error, e.g. a
  missing model file) is never restarted: the launcher says once which one stopped
  and its error line, and `perception status` / `perception doctor` list it as failed.
- SIGINT (Ctrl-C) or SIGTERM stops everything: SIGTERM to each child's process group
  in reverse start order, SIGKILL after its stop_timeout_s, the router last. A second
  Ctrl-C kills at once. Exit status 0 after a clean stop.
- ${VAR} and ${VAR:-default} in the file are taken from the environment.
- A bad launch file is reported, naming the field, before anything starts.

Examples:
  perception launch deploy/single-pc.yaml
  ROBOT=mbot NAV_PC=192.168.1.20 perception launch deploy/hri-pc.yaml --dry-run
  perception launch deploy/single-pc.yaml --only router tracker"""


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("file", type=Path, metavar="FILE.yaml", help="launch file")
    parser.add_argument("--dry-run", action="store_true",
                        help="validate the file and print what would be started (commands, env, configs), start nothing")
    parser.add_argument("--only", nargs="+", action="extend", default=[], metavar="NAME",
                        help="start only these entries (service names and/or 'router'); commas also separate")
    parser.add_argument("--color", choices=("auto", "always", "never"), default="auto",
                        help="colour the name prefixes (auto: when stdout is a terminal and NO_COLOR is unset)")


def _check_programs(launch: LaunchFile, names: set[str]) -> list[str]:
    """Problems with the programs to start: unknown perception commands, missing executables."""
    from perception.cli import COMMANDS

    problems = []
    for i, s in enumerate(launch.services):
        if s.name not in names:
            continue
        where = f"services[{i}] ({s.name})"
        if s.command is not None and s.command not in COMMANDS:
            problems.append(f"{where}.command: {s.command!r} is not a perception command "
                            f"(installed: {', '.join(sorted(COMMANDS))})")
        if s.exec_ is not None and shutil.which(s.exec_[0]) is None:
            problems.append(f"{where}.exec: program {s.exec_[0]!r} not found (give a path or put it on PATH)")
    return problems


def _check_security(launch: LaunchFile, names: set[str]) -> list[str]:
    """Problems with the certificates, keys and credentials the started entries will read."""
    import zenoh

    from common.transport.zenoh_security import SecurityError, read_credentials, secure_config

    checks: list[tuple[Path | None, Path | None]] = [(launch.zenoh.config, launch.zenoh.credentials)]
    if launch.router is not None and "router" in names:
        checks.append((launch.router.config, launch.router.credentials))
    checks += [(None, s.credentials) for s in launch.services if s.name in names]
    problems: list[str] = []
    for config, credentials in checks:
        try:
            if config is not None:
                secure_config(zenoh.Config.from_file(str(config)), config, None)
            if credentials is not None:
                read_credentials(credentials)
        except SecurityError as exc:
            if str(exc) not in problems:
                problems.append(str(exc))
        except zenoh.ZError as exc:
            problems.append(f"Zenoh config {config} cannot be used: {exc}")
    return problems


def failure_report(launch: LaunchFile) -> FailureReport:
    """Where services that stop for good are reported: the services' router and key space."""
    robot = launch.robot or os.environ.get("PERCEPTION_ROBOT") or DEFAULT_ROBOT
    prefix = launch.key_prefix or os.environ.get("PERCEPTION_KEY_PREFIX") or DEFAULT_PREFIX
    options = ZenohOptions(mode="client", connect=services_connect(launch) or [], config_file=launch.zenoh.config,
                           credentials=launch.zenoh.credentials)
    return FailureReport(Keys(robot=robot, prefix=prefix), options,
                         {s.name: s.command for s in launch.services if s.command is not None})


def main(args: argparse.Namespace) -> int:
    only = [n for item in args.only for n in item.split(",") if n]
    try:
        launch = load_launch_file(args.file, os.environ)
        with tempfile.TemporaryDirectory(prefix="perception-launch-") as config_dir:
            plan = build_plan(launch, os.environ, Path(config_dir), only, origin=str(args.file))
            problems = _check_programs(launch, {p.name for p in plan}) + _check_security(launch, {p.name for p in plan})
            if args.dry_run:
                print(render_plan(launch, plan, os.environ))
                for p in problems:
                    log.warning("%s", p)
                return 0
            if problems:
                raise CliError(f"cannot launch {args.file}:\n  " + "\n  ".join(problems))
            colour = args.color == "always" or (
                args.color == "auto" and sys.stdout.isatty() and "NO_COLOR" not in os.environ)
            log.info("launching %s: %s", args.file, ", ".join(p.name for p in plan))
            report = failure_report(launch)
            try:
                # the report's session goes through the launched router: closed before it stops (a
                # Zenoh session left to a router that is gone can abort the launcher at exit)
                return Supervisor(plan, sys.stdout.buffer, colour=colour, on_failed=report,
                                  before_last=report.close).run()
            finally:
                report.close()
    except LaunchFileError as exc:
        raise CliError(str(exc)) from exc
