"""The ``perception`` command: one entry point, sub-commands imported only when used."""

from __future__ import annotations

import argparse
import importlib
import importlib.util
import sys
from types import ModuleType

from common.runtime.cli_util import CliError, fail, setup_logging
from common.messages.registry import NODES

#: name -> (module, one-line help). Each module has add_arguments(parser) and main(args) -> int,
#: and may have a DESCRIPTION string for its --help.
COMMANDS: dict[str, tuple[str, str]] = {}

#: Packages whose ``commands`` module adds to COMMANDS (a ``COMMANDS`` dict of the same
#: shape): the system's small commands, every node of the registry, then the tools that are
#: not nodes. Those modules only name modules, so ``perception --help`` stays fast.
COMMAND_PACKAGES = (
    "tools.system",
    *dict.fromkeys(n.package for n in NODES),
    "tools.evaluation",
    "tools.replay",
    "tools.simulator",
    "tools.launcher",
    "tools.demo",
    "tools.doctor",
)


def _discover() -> None:
    for package in COMMAND_PACKAGES:
        name = f"{package}.commands"
        if importlib.util.find_spec(package) is None or importlib.util.find_spec(name) is None:
            continue
        for cmd, entry in importlib.import_module(name).COMMANDS.items():
            if cmd in COMMANDS and COMMANDS[cmd] != entry:
                raise RuntimeError(f"command {cmd!r} is defined by both {COMMANDS[cmd][0]} and {entry[0]}")
            COMMANDS[cmd] = entry


_discover()


def _load(name: str) -> ModuleType:
    return importlib.import_module(COMMANDS[name][0])


def build_parser(only: str | None = None) -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="perception",
        description="Detect, localize, re-identify and track people around a robot, as Zenoh services.",
        epilog="Run 'perception COMMAND --help' for the options of one command.",
    )
    parser.add_argument("-v", "--verbose", action="count", default=0, help="more log output (-vv for debug)")
    parser.add_argument("-q", "--quiet", action="store_true", help="only warnings and errors")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND", required=True)
    for name, (_, help_text) in COMMANDS.items():
        if only is not None and name != only:
            sub.add_parser(name, help=help_text)
            continue
        module = _load(name)
        p = sub.add_parser(name, help=help_text, description=getattr(module, "DESCRIPTION", help_text),
                           formatter_class=argparse.RawDescriptionHelpFormatter)
        module.add_arguments(p)
    return parser


def main(argv: list[str] | None = None) -> int:
    argv = sys.argv[1:] if argv is None else argv
    chosen = next((a for a in argv if a in COMMANDS), None)
    parser = build_parser(only=chosen if chosen is not None else "")
    args = parser.parse_args(argv)
    setup_logging(args.verbose, args.quiet)
    try:
        return int(_load(args.command).main(args) or 0)
    except CliError as exc:
        return fail(str(exc))
    except KeyboardInterrupt:
        return 130


if __name__ == "__main__":
    sys.exit(main())
