"""``perception keys``: the key expressions of a robot."""

from __future__ import annotations

import argparse

from common.runtime.cli_util import add_key_arguments, keys_from_args
from common.messages.keys import STREAMS

DESCRIPTION = "Print every key expression of the robot, its message type, publishers, subscribers and delivery policy."


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--markdown", action="store_true", help="print the README's markdown table")
    add_key_arguments(parser)


def main(args: argparse.Namespace) -> int:
    keys = keys_from_args(args)
    if args.markdown:
        print(keys.markdown_table())
        return 0
    for s in STREAMS:
        key = f"{keys.base}/" + s.template.format(camera="{camera}", laser="{laser}", service="{service}", instance="{instance}")
        policy = s.delivery.describe() if s.delivery else s.kind
        print(f"{key}\n    {s.message}: {s.publishers} -> {s.subscribers}; {policy}")
    return 0
