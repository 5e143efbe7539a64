"""Flags and helpers shared by every ``perception`` sub-command."""

from __future__ import annotations

import argparse
import logging
import os
import sys

from common.messages.keys import DEFAULT_PREFIX, DEFAULT_ROBOT, Keys

__all__ = ["CliError", "add_key_arguments", "check_input_file", "fail", "keys_from_args", "setup_logging"]


class CliError(Exception):
    """A user-facing error: the command prints it and exits non-zero, without a traceback."""


def check_input_file(path: str | os.PathLike[str], expected: str) -> None:
    """A CliError naming ``path`` when it is missing or a directory; ``expected`` says what to give."""
    if os.path.isdir(path):
        raise CliError(f"{path} is a directory; give a file ({expected})")
    if not os.path.isfile(path):
        raise CliError(f"{path}: no such file ({expected})")


def fail(message: str, code: int = 2) -> int:
    """Print ``perception: error: message`` to stderr and return ``code``."""
    print(f"perception: error: {message}", file=sys.stderr)
    return code


def setup_logging(verbose: int = 0, quiet: bool = False) -> None:
    level = logging.WARNING if quiet else (logging.DEBUG if verbose > 1 else logging.INFO)
    logging.basicConfig(level=level, format="%(asctime)s %(levelname).1s %(name)s: %(message)s", datefmt="%H:%M:%S")


def add_key_arguments(parser: argparse.ArgumentParser) -> None:
    g = parser.add_argument_group("keys")
    g.add_argument("--robot", default=None,
                   help=f"robot name in every key (env PERCEPTION_ROBOT, default {DEFAULT_ROBOT!r})")
    g.add_argument("--key-prefix", default=None,
                   help=f"first key segment(s) (env PERCEPTION_KEY_PREFIX, default {DEFAULT_PREFIX!r})")


def keys_from_args(args: argparse.Namespace) -> Keys:
    robot = args.robot or os.environ.get("PERCEPTION_ROBOT") or DEFAULT_ROBOT
    prefix = args.key_prefix or os.environ.get("PERCEPTION_KEY_PREFIX") or DEFAULT_PREFIX
    try:
        return Keys(robot=robot, prefix=prefix)
    except ValueError as exc:
        raise CliError(f"{exc} (set with --robot/--key-prefix)") from exc
