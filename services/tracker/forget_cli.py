"""``perception forget``: ask the running tracker to forget a person, or everyone."""

from __future__ import annotations

import argparse
import json
import sys

from common.runtime.cli_util import add_key_arguments, keys_from_args
from common.messages.schemas import ForgetReply
from common.transport.zenoh_config import add_zenoh_arguments
from common.transport.zenoh import open_transport_from_args

HELP = "make the running tracker forget a person's appearance (privacy), or everyone's"
DESCRIPTION = """\
Ask the running tracker to forget a person: their remembered descriptors and online
classifiers go from its ID memory and from the memory file, which it rewrites at once.
A person tracked right now keeps their ID while they stay in view, but their track
loses its appearance history and learns none; when they come back later they get a new
ID. `--all` forgets everyone. The tracker also forgets on its own the IDs it has not
seen for `retention_s` (7 days by default).

Exit status: 0 when the tracker forgot something, 1 when it knows no such ID, 2 when no
tracker answered (is it running? `perception status`).

examples:
  perception forget 7
  perception forget --all --robot mbot --connect tcp/192.168.1.20:7447"""


def add_arguments(parser: argparse.ArgumentParser) -> None:
    which = parser.add_mutually_exclusive_group(required=True)
    which.add_argument("id", nargs="?", type=int, help="the ID to forget (as published on tracks)")
    which.add_argument("--all", action="store_true", help="forget everyone the tracker remembers or tracks")
    parser.add_argument("--json", action="store_true", help="print the tracker's reply as JSON")
    parser.add_argument("--timeout", type=float, default=3.0, metavar="S",
                        help="how long to wait for the tracker (default 3)")
    add_key_arguments(parser)
    add_zenoh_arguments(parser)


def describe(reply: ForgetReply) -> str:
    if reply.error:
        return reply.error
    if not reply.forgotten_ids:
        return "the tracker remembered nobody: nothing to forget"
    live = ""
    if reply.live_tracks_cleared:
        live = f"; live tracks {reply.live_tracks_cleared} keep their ID without appearance"
    return (f"forgot ID(s) {reply.forgotten_ids}: {reply.descriptors_removed} descriptors and "
            f"{reply.classifiers_removed} classifiers removed, the memory file rewritten{live}")


def main(args: argparse.Namespace) -> int:
    if args.id is not None and args.id < 1:
        print(f"perception forget: error: IDs are positive integers, got {args.id}", file=sys.stderr)
        return 2
    keys = keys_from_args(args)
    selector = keys.forget_query() + ("?all=1" if args.all else f"?id={args.id}")
    with open_transport_from_args(args) as transport:
        replies = [m for _, m in transport.query(selector, timeout=args.timeout) if isinstance(m, ForgetReply)]
    if not replies:
        print(f"perception forget: error: no tracker answered on {keys.forget_query()} within {args.timeout:g} s; "
              "is it running? (perception status)", file=sys.stderr)
        return 2
    status = 0
    for reply in replies:
        if args.json:
            print(json.dumps(reply.model_dump(mode="json")))
        else:
            print(describe(reply))
        if reply.error:
            status = 1
    return status
