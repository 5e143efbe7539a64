"""``perception router``: a Zenoh router in this Python process (no zenohd needed)."""

from __future__ import annotations

import argparse
import logging
import sys


from common.runtime.cli_util import CliError
from common.runtime.service import Shutdown
from common.transport.zenoh_config import ZenohFlagError, ZenohOptions, add_zenoh_arguments, options_from_args
from common.transport.zenoh import TransportError, open_session

log = logging.getLogger(__name__)

DEFAULT_LISTEN = "tcp/127.0.0.1:7447"
HELP = "run a Zenoh router in this process"
DESCRIPTION = f"""\
Run a Zenoh router in this Python process; the services connect to it as clients.
By default it listens on {DEFAULT_LISTEN} (this machine only) with multicast
scouting off. On a robot with two PCs run one router per PC, listening on the
PC's LAN address, and connect them with --connect tcp/OTHER_PC:7447.
It prints 'router ready' once it accepts connections and stops on SIGINT/SIGTERM."""


def add_arguments(parser: argparse.ArgumentParser) -> None:
    add_zenoh_arguments(parser, default_mode="router")
    parser.add_argument("--access-control", action="store_true",
                        help="enforce each service's least-privilege rules (perception certs --acl prints them); "
                             "the clients must then log in with their own credentials")


def router_options(args: argparse.Namespace) -> ZenohOptions:
    try:
        opts = options_from_args(args)
    except ZenohFlagError as exc:
        raise CliError(str(exc)) from exc
    if opts.mode != "router":
        raise CliError("perception router always runs in router mode; drop --mode")
    opts.access_control = bool(getattr(args, "access_control", False))
    if not opts.listen and opts.config_file is None:
        opts.listen = [DEFAULT_LISTEN]
    return opts


def main(args: argparse.Namespace) -> int:
    opts = router_options(args)
    with Shutdown() as shutdown:
        try:
            session = open_session(opts)
        except TransportError as exc:
            raise CliError(str(exc)) from exc
        try:
            print(f"router ready: {opts.describe()} (zid {session.zid()})", flush=True)
            shutdown.wait()
        finally:
            session.close()
    print("router stopped", file=sys.stderr, flush=True)
    return 0
