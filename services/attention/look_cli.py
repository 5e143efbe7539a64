"""``perception look``: tell the running attention node whom to look at."""

from __future__ import annotations

import argparse
import json
import sys

from common.runtime.cli_util import add_key_arguments, keys_from_args
from common.messages.schemas import AttentionReply
from common.transport.zenoh_config import add_zenoh_arguments
from common.transport.zenoh import open_transport_from_args

DESCRIPTION = """\
Tell the running attention node whom the head should keep in view: a track ID (as
published on tracks), 'nearest' (the nearest confirmed person, kept until lost, then
the nearest again), 'lock' (the nearest confirmed person now, then that ID: when they are
lost the head waits for their ID to come back) or 'none' (the head returns to its rest pose). Without a target, print what it looks at now.

Exit status: 0 when the node took the request, 1 when it refused it (an unknown ID: the
reply lists the IDs tracked now), 2 when no attention node answered.

examples:
  perception look 3
  perception look lock
  perception look nearest --robot mbot --connect tcp/192.168.1.20:7447
  perception look"""


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("target", nargs="?", default=None, metavar="ID|nearest|lock|none",
                        help="whom to look at; leave out to print the node's state")
    parser.add_argument("--json", action="store_true", help="print the node's reply as JSON")
    parser.add_argument("--timeout", type=float, default=3.0, metavar="S", help="how long to wait (default 3)")
    add_key_arguments(parser)
    add_zenoh_arguments(parser)


def describe(reply: AttentionReply) -> str:
    if reply.error:
        return reply.error
    following = f", following ID {reply.following_id}" if reply.following_id >= 0 else ""
    what = {"none": "no one", "nearest": "the nearest person",
            "lock": "the nearest person, to lock onto", "id": f"ID {reply.requested_id}"}[reply.mode]
    known = ", ".join(map(str, reply.known_ids)) or "none"
    return f"looking at {what}{following} (tracks now: {known})"


def main(args: argparse.Namespace) -> int:
    keys = keys_from_args(args)
    selector = keys.attention_query() + ("" if args.target is None else f"?target={args.target.strip()}")
    with open_transport_from_args(args) as transport:
        replies = [m for _, m in transport.query(selector, timeout=args.timeout) if isinstance(m, AttentionReply)]
    if not replies:
        print(f"perception look: error: no attention node answered on {keys.attention_query()} within "
              f"{args.timeout:g} s; is it running? (perception status)", file=sys.stderr)
        return 2
    status = 0
    for reply in replies:
        print(json.dumps(reply.model_dump(mode="json")) if args.json else describe(reply))
        status = max(status, 1 if reply.error else 0)
    return status
