"""``perception record --output run.mcap``: record perception streams from Zenoh into MCAP."""

from __future__ import annotations

import argparse
import contextlib
import logging
import time
from pathlib import Path
from typing import TYPE_CHECKING, Any

from common.runtime.cli_util import CliError, add_key_arguments, keys_from_args
from common.messages.keys import Delivery
from common.runtime.service import Counters, ServiceRuntime, Shutdown, package_version
from common.transport.base import Received, Subscription, Transport, wait_any
from common.transport.zenoh_config import add_zenoh_arguments
from tools.replay.recorder import McapRecorder

if TYPE_CHECKING:
    from tools.foxglove.bridge import FoxgloveMcap

log = logging.getLogger(__name__)

DESCRIPTION = """Record perception messages from Zenoh into an MCAP file, until Ctrl-C (or --duration).

Every payload is decoded first: messages that are not valid perception messages are
counted as invalid and not recorded. The file holds one channel per key (topic = the
key, message encoding msgpack), the JSON schema of every message type, and the
schema versions; log time = receive time, publish time = header.stamp_ns.
On SIGINT/SIGTERM what was received is written and the file is closed properly.

--foxglove FOX.mcap also writes, from the same messages, a second MCAP file in Foxglove's
well-known schemas that the Foxglove app opens with no plugin (what perception
export-foxglove makes from a recording): /camera/image (JPEG), /camera/annotations,
/people (3-D scene in the map frame), /tf, and tracks, detections, localized detections
and statuses as JSON. The --output file stays the one perception replay reads. Needs
foxglove-sdk (the 'view' extra); each colour frame is JPEG-encoded while recording.

examples:
  perception record --output run.mcap
  perception record --output run.mcap --foxglove run-foxglove.mcap
  perception record --keys 'pp/robot/perception/v1/tracks' --keys 'pp/robot/perception/v1/tf' -o tracks.mcap"""

#: Recording must not lose messages: a deep FIFO (overflow is counted and reported).
RECORD_DELIVERY = Delivery(latest=False, queue=1024, congestion="block")


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--output", "-o", type=Path, required=True, metavar="FILE.mcap", help="MCAP file to write")
    parser.add_argument("--keys", "-k", action="append", default=None, metavar="EXPR",
                        help="key expression to record, repeatable (default: everything of the robot, KEYS.all())")
    parser.add_argument("--compression", choices=("zstd", "lz4", "none"), default="zstd",
                        help="MCAP chunk compression (default zstd; lz4 is cheaper on CPU)")
    parser.add_argument("--duration", type=float, default=None, metavar="S", help="stop after S seconds (default: at Ctrl-C)")
    parser.add_argument("--foxglove", type=Path, default=None, metavar="FOX.mcap",
                        help="also write the messages in Foxglove's well-known schemas into FOX.mcap, for the "
                             "Foxglove app (needs foxglove-sdk, the 'view' extra)")
    parser.add_argument("--force", action="store_true", help="overwrite FILE (and FOX.mcap) if it exists")
    add_key_arguments(parser)
    add_zenoh_arguments(parser)


def drain(subs: list[Subscription[Any]]) -> list[Received[Any]]:
    """Everything pending on ``subs``, in receive order."""
    got: list[Received[Any]] = []
    for sub in subs:
        while (r := sub.try_recv()) is not None:
            got.append(r)
    got.sort(key=lambda r: r.recv_ns)
    return got


def record(transport: Transport, recorder: McapRecorder, exprs: list[str], runtime: ServiceRuntime,
           shutdown: Shutdown, duration_s: float | None, foxglove: FoxgloveMcap | None = None) -> list[Subscription[Any]]:
    """Record until ``shutdown`` or ``duration_s``; returns the subscriptions (for their stats).

    ``foxglove``, if given, is written every recorded message too.
    """
    subs: list[Subscription[Any]] = [transport.subscribe(e, None, RECORD_DELIVERY) for e in exprs]
    runtime.watch(*subs)
    own_status = runtime.keys.status(runtime.name, runtime.instance)
    deadline = None if duration_s is None else time.monotonic() + duration_s

    def write_pending() -> None:
        for r in drain(subs):
            if r.key != own_status:
                recorder.write(r.key, r.msg, r.recv_ns)
                if foxglove is not None:
                    foxglove.write(r.key, r.msg)
        runtime.counters.gauge("recorded", sum(recorder.counts.values()))

    while not shutdown.is_set() and (deadline is None or time.monotonic() < deadline):
        wait_any(subs, transport.notify, 0.1)
        write_pending()
    write_pending()  # what arrived before the stop
    return subs


def _check_paths(args: argparse.Namespace) -> None:
    if args.output.exists() and not args.force:
        raise CliError(f"{args.output} exists; pass --force to overwrite it")
    if not args.output.parent.is_dir():
        raise CliError(f"{args.output}: folder {args.output.parent} does not exist")
    if args.foxglove is not None:
        from tools.replay.export_foxglove_cli import check_output

        if args.foxglove.resolve() == args.output.resolve():
            raise CliError("--foxglove and --output are the same file")
        check_output(args.foxglove, args.force)


def _open_files(args: argparse.Namespace, exprs: list[str]) -> tuple[McapRecorder, FoxgloveMcap | None]:
    """The recorder and, with --foxglove, the Foxglove file; CliError (nothing left open) when one cannot be written."""
    foxglove = None
    if args.foxglove is not None:
        from tools.replay.export_foxglove_cli import open_foxglove_mcap

        new = not args.foxglove.exists()
        foxglove = open_foxglove_mcap(args.foxglove)
    try:
        recorder = McapRecorder(args.output, compression=args.compression, key_exprs=exprs,
                                writer_version=package_version())
    except OSError as exc:
        if foxglove is not None:
            foxglove.close()
            if new:  # no empty file left behind to need --force next time
                args.foxglove.unlink(missing_ok=True)
        raise CliError(f"{args.output}: cannot be written ({exc.strerror or exc})") from exc
    return recorder, foxglove


def main(args: argparse.Namespace) -> int:
    from common.transport.zenoh import open_transport_from_args

    keys = keys_from_args(args)
    exprs = args.keys or [keys.all()]
    _check_paths(args)
    transport = open_transport_from_args(args)
    try:
        recorder, foxglove = _open_files(args, exprs)
    except CliError:
        transport.close()
        raise
    counters = Counters()
    closes_foxglove = foxglove if foxglove is not None else contextlib.nullcontext()
    with Shutdown() as shutdown, transport, recorder, closes_foxglove, \
            ServiceRuntime("record", transport, keys, counters=counters) as rt:
        log.info("recording %s into %s%s", ", ".join(exprs), args.output,
                 f" and, in Foxglove's schemas, {args.foxglove}" if foxglove is not None else "")
        subs = record(transport, recorder, exprs, rt, shutdown, args.duration, foxglove)
    total = sum(recorder.counts.values())
    print(f"recorded {total} messages ({sum(recorder.bytes.values()) / 1e6:.1f} MB) into {args.output}")
    for key in sorted(recorder.counts):
        print(f"  {key} [{recorder.schema_of[key]}]: {recorder.counts[key]}")
    dropped = sum(s.stats.dropped for s in subs)
    invalid = sum(s.stats.invalid for s in subs)
    if dropped or invalid:
        print(f"  not recorded: {dropped} dropped (writer too slow), {invalid} invalid payloads")
    if foxglove is not None:
        print(f"wrote {sum(foxglove.counts.values())} messages in Foxglove's schemas into {args.foxglove}")
        for topic, n in sorted(foxglove.counts.items()):
            print(f"  {topic}: {n}")
    return 0
