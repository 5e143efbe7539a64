"""``perception selfcheck``: a router plus one message of every type, sent and received."""

from __future__ import annotations

import argparse
import time


from common.runtime.cli_util import CliError, add_key_arguments, keys_from_args
from common.messages.codec import encode
from common.messages.keys import RELIABLE, Keys
from common.transport.router_process import RouterProcess
from common.runtime.service import ServiceRuntime
from common.messages.samples import example_messages
from common.transport.base import Transport
from common.transport.zenoh_config import ZenohFlagError, ZenohOptions, add_zenoh_arguments, options_from_args
from common.transport.zenoh import TransportError, open_transport

DESCRIPTION = """\
Check the messaging layer end to end. Unless --connect is given, start a local
'perception router' child process on a free loopback port. Then open a publishing
and a subscribing client session, send one message of every schema through the
router, check that each arrives equal to what was sent, and list the live services
(the self-check registers itself). Exits 0 when every message made it."""


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--timeout", type=float, default=5.0, metavar="S", help="per-message receive timeout (default 5)")
    add_key_arguments(parser)
    add_zenoh_arguments(parser)


def exchange(pub_t: Transport, sub_t: Transport, keys: Keys, timeout: float) -> list[tuple[str, int, float, bool]]:
    """Send each example message on its own key; (type, bytes, round-trip ms, equal) per message."""
    results = []
    for i, msg in enumerate(example_messages()):
        key = f"{keys.base}/selfcheck/{type(msg).__name__}{i}"
        sub = sub_t.subscribe(key, type(msg), RELIABLE)
        pub = pub_t.publisher(key, type(msg), RELIABLE)
        if not pub.wait_for_subscribers(timeout):
            raise CliError(f"no subscriber matched {key} within {timeout} s; is the router reachable?")
        t0 = time.perf_counter()
        pub.put(msg)
        got = sub.recv(timeout)
        dt_ms = (time.perf_counter() - t0) * 1e3
        results.append((type(msg).SCHEMA_NAME, len(encode(msg)), dt_ms, got is not None and got.msg == msg))
        sub.close()
        pub.close()
    return results


def _client(opts: ZenohOptions) -> Transport:
    try:
        return open_transport(opts)
    except TransportError as exc:
        raise CliError(str(exc)) from exc


def main(args: argparse.Namespace) -> int:
    keys = keys_from_args(args)
    try:
        opts = options_from_args(args)
    except ZenohFlagError as exc:
        raise CliError(str(exc)) from exc
    router = None
    if not opts.connect and opts.config_file is None and opts.mode == "client":
        router = RouterProcess().start()
        opts.connect = [router.endpoint]
        print(f"started perception router on {router.endpoint} (pid {router.proc.pid if router.proc else '?'})")
    try:
        with _client(opts) as pub_t, _client(opts) as sub_t, ServiceRuntime("selfcheck", pub_t, keys):
            results = exchange(pub_t, sub_t, keys, args.timeout)
            print(f"\n{'message':<34} {'bytes':>8} {'round trip':>12}  result")
            for name, size, ms, ok in results:
                print(f"{name:<34} {size:>8} {ms:>9.2f} ms  {'ok' if ok else 'FAILED'}")
            live = sub_t.alive(keys.alive())
            print(f"\nlive services: {', '.join('/'.join(keys.parse_alive(k)) for k in live) or 'none'}")
    finally:
        if router is not None:
            router.stop()
    failed = [r[0] for r in results if not r[3]]
    if failed:
        print(f"\nFAILED: {', '.join(failed)}")
        return 1
    print(f"\nall {len(results)} message types went through the router and decoded equal")
    return 0
