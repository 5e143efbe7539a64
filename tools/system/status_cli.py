"""``perception status``: the live services, found through liveliness, with their counters."""

from __future__ import annotations

import argparse
import json
import time


from common.runtime.cli_util import add_key_arguments, keys_from_args
from common.messages.keys import Keys
from common.messages.schemas import ServiceStatus
from common.transport.base import Transport
from common.transport.zenoh_config import add_zenoh_arguments
from common.transport.zenoh import open_transport_from_args

HELP = "list the live services with their host and counters"
DESCRIPTION = """\
List every live service instance of the robot (through Zenoh liveliness tokens),
with its host, uptime and message counters (received, published, dropped, invalid)
and its own extra counters. A service that died shows up as gone within about
10 ms of its death, even after SIGKILL. A service that `perception launch` stopped
for good (exit status 2, a configuration or start-up error) is listed as FAILED with
its error line, and the tracker's position-only counters next to it."""


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--json", action="store_true", help="print JSON instead of a table")
    parser.add_argument("--watch", type=float, default=None, metavar="S", help="refresh every S seconds until Ctrl-C (default: print once)")
    parser.add_argument("--timeout", type=float, default=1.0, metavar="S", help="how long to wait for answers (default 1)")
    add_key_arguments(parser)
    add_zenoh_arguments(parser)


def collect(transport: Transport, keys: Keys, timeout: float) -> list[tuple[str, str, ServiceStatus | None]]:
    """(service, instance, last status or None) for every live token, then every service a
    launcher reports as failed (stopped for good, so without a token)."""
    statuses = {
        (m.name, m.instance): m for _, m in transport.query(keys.status(), timeout=timeout) if isinstance(m, ServiceStatus)
    }
    out: list[tuple[str, str, ServiceStatus | None]] = []
    for key in transport.alive(keys.alive(), timeout=timeout):
        service, instance = keys.parse_alive(key)
        out.append((service, instance, statuses.pop((service, instance), None)))
    out += [(st.name, st.instance, st) for st in statuses.values() if st.state == "failed"]
    return out


#: Counters that say the tracker runs without appearance, shown next to a failed service.
POSITION_ONLY = ("position_only_frames", "position_only_timeout")


def position_only(rows: list[tuple[str, str, ServiceStatus | None]]) -> str:
    """The tracker's position-only counters, e.g. ``position_only_frames=120``, or ''."""
    counts = [f"{k}={st.extra.get(k, 0):g}" for name, _, st in rows
              if name == "tracker" and st is not None and st.state == "running" for k in POSITION_ONLY]
    return ", ".join(counts)


def render(rows: list[tuple[str, str, ServiceStatus | None]]) -> str:
    if not rows:
        return "no live services"
    head = f"{'service':<12} {'instance':<24} {'host':<16} {'uptime':>8} {'recv':>8} {'pub':>8} {'drop':>6} {'inval':>6}  extra"
    lines = [head, "-" * len(head)]
    tracker = position_only(rows)
    for service, instance, st in rows:
        if st is None:
            lines.append(f"{service:<12} {instance:<24} {'(no status reply)':<16}")
            continue
        if st.state == "failed":
            status = f"exit status {st.exit_status}" if st.exit_status is not None else "stopped"
            lines.append(f"{service:<12} {instance:<24} {st.host:<16} FAILED ({status}, not restarted)"
                         + (f"; tracker: {tracker}" if tracker and service != "tracker" else ""))
            lines.append(f"{'':<12} error: {st.error or '(none reported)'}")
            continue
        extra = ", ".join(f"{k}={v:g}" for k, v in sorted(st.extra.items()))
        lines.append(
            f"{service:<12} {instance:<24} {st.host:<16} {st.uptime_s:>7.0f}s {st.received:>8} {st.published:>8} "
            f"{st.dropped:>6} {st.invalid:>6}  {extra}"
        )
    return "\n".join(lines)


def main(args: argparse.Namespace) -> int:
    keys = keys_from_args(args)
    transport = open_transport_from_args(args)
    with transport:
        while True:
            rows = collect(transport, keys, args.timeout)
            if args.json:
                print(json.dumps([
                    {"service": s, "instance": i, "status": st.model_dump(mode="json") if st else None} for s, i, st in rows
                ], indent=2))
            else:
                if args.watch:
                    print("\033[2J\033[H", end="")
                print(render(rows), flush=True)
            if not args.watch:
                return 0
            try:
                time.sleep(args.watch)
            except KeyboardInterrupt:
                return 0
