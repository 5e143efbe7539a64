"""``perception export-foxglove IN OUT.mcap``: a recording in Foxglove's well-known schemas."""

from __future__ import annotations

import argparse
from pathlib import Path

from common.cli_util import CliError
from common.codec import DecodeError, decode
from common.progress import progress

DESCRIPTION = """\
Convert a recording (MCAP of perception record or simulate --output, or a ROS bag that
perception replay reads) into an MCAP file that the Foxglove app opens with no plugin:

  /camera/image         foxglove.CompressedImage (JPEG) of the colour frames
  /camera/annotations   foxglove.ImageAnnotations: boxes, labelled and coloured by track ID
  /people               foxglove.SceneUpdate in the map frame: body, ID, velocity arrow,
                        covariance ellipse per person
  /tf                   foxglove.FrameTransforms of tf and tf_static
  /perception/...       tracks, detections, localized detections and statuses as JSON

The same translation as perception view --foxglove-port. Needs foxglove-sdk (the 'view'
extra).

example:
  perception export-foxglove run.mcap run-foxglove.mcap"""


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("input", type=Path, metavar="IN", help="recording to read")
    parser.add_argument("output", type=Path, metavar="OUT.mcap", help="Foxglove MCAP file to write")
    parser.add_argument("--force", action="store_true", help="overwrite OUT if it exists")


def main(args: argparse.Namespace) -> int:
    from tools.replay.source_base import SourceError
    from tools.replay.sources import open_source
    from tools.viewer.foxglove_bridge import FoxgloveBridge, FoxgloveUnavailable

    if args.output.exists() and not args.force:
        raise CliError(f"{args.output} exists (--force to overwrite it)")
    if args.output.resolve() == args.input.resolve():
        raise CliError("IN and OUT are the same file")
    try:
        bridge = FoxgloveBridge()
    except FoxgloveUnavailable as exc:
        raise CliError(str(exc)) from exc
    skipped = 0
    try:
        source = open_source(args.input, keep_status=True)
    except SourceError as exc:
        raise CliError(str(exc)) from exc
    writer = bridge.fg.open_mcap(str(args.output), allow_overwrite=True, context=bridge.context)
    try:
        for item in progress(source.items(), desc="export", unit="msg"):
            try:
                msg = item.message if item.message is not None else decode(item.model, item.encoded())
            except DecodeError:
                skipped += 1
                continue
            bridge.on_message(item.key, msg)
    except SourceError as exc:
        raise CliError(f"{exc} (what was read before is in {args.output})") from exc
    finally:
        writer.close()
        source.close()
    for topic, n in sorted(bridge.counts.items()):
        print(f"{topic:<24} {n:>7} messages")
    if skipped:
        print(f"skipped {skipped} undecodable messages")
    print(f"wrote {args.output}")
    return 0
