"""``perception export-foxglove IN OUT.mcap``: a recording in Foxglove's well-known schemas."""

from __future__ import annotations

import argparse
from pathlib import Path
from typing import TYPE_CHECKING

from common.runtime.cli_util import CliError
from common.messages.codec import DecodeError, decode
from common.runtime.progress import progress

if TYPE_CHECKING:
    from tools.foxglove.bridge import FoxgloveMcap

DESCRIPTION = """\
Convert a recording (MCAP of perception record or simulate --output, or a ROS bag that
perception replay reads) into an MCAP file that the Foxglove app opens with no plugin:

  /camera/image         foxglove.CompressedImage (JPEG) of the colour frames
  /camera/annotations   foxglove.ImageAnnotations: boxes, labelled and coloured by track ID
  /people               foxglove.SceneUpdate in the map frame: body, ID, velocity arrow,
                        covariance ellipse per person
  /tf                   foxglove.FrameTransforms of tf and tf_static
  /perception/...       tracks, detections, localized detections and statuses as JSON

The same translation as perception view --foxglove-port and perception record --foxglove
(which writes this file while recording). Needs foxglove-sdk (the 'view' extra).

example:
  perception export-foxglove run.mcap run-foxglove.mcap"""


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("input", type=Path, metavar="IN", help="recording to read")
    parser.add_argument("output", type=Path, metavar="OUT.mcap", help="Foxglove MCAP file to write")
    parser.add_argument("--force", action="store_true", help="overwrite OUT if it exists")


def check_output(path: Path, force: bool) -> None:
    """CliError unless a Foxglove file can be created at ``path`` (an existing one only with ``force``)
    and foxglove-sdk is installed."""
    from tools.foxglove.bridge import FoxgloveUnavailable, require_sdk

    if path.is_dir():
        raise CliError(f"{path} is a folder")
    if path.exists() and not force:
        raise CliError(f"{path} exists (--force to overwrite it)")
    if not path.parent.is_dir():
        raise CliError(f"{path}: folder {path.parent} does not exist")
    try:
        require_sdk()
    except FoxgloveUnavailable as exc:
        raise CliError(str(exc)) from exc


def open_foxglove_mcap(path: Path) -> FoxgloveMcap:
    """A :class:`FoxgloveMcap` at ``path``; CliError without foxglove-sdk or when it cannot be written."""
    from tools.foxglove.bridge import FoxgloveMcap, FoxgloveUnavailable

    try:
        return FoxgloveMcap(path)
    except FoxgloveUnavailable as exc:
        raise CliError(str(exc)) from exc
    except OSError as exc:
        raise CliError(f"{path}: cannot be written ({exc.strerror or exc})") from exc


def main(args: argparse.Namespace) -> int:
    from tools.replay.source_base import SourceError
    from tools.replay.sources import open_source

    check_output(args.output, args.force)
    if args.output.resolve() == args.input.resolve():
        raise CliError("IN and OUT are the same file")
    skipped = 0
    try:
        source = open_source(args.input, keep_status=True)
    except SourceError as exc:
        raise CliError(str(exc)) from exc
    try:
        out = open_foxglove_mcap(args.output)
    except CliError:
        source.close()
        raise
    try:
        for item in progress(source.items(), desc="export", unit="msg"):
            try:
                msg = item.message if item.message is not None else decode(item.model, item.encoded())
            except DecodeError:
                skipped += 1
                continue
            out.write(item.key, msg)
    except SourceError as exc:
        raise CliError(f"{exc} (what was read before is in {args.output})") from exc
    finally:
        out.close()
        source.close()
    for topic, n in sorted(out.counts.items()):
        print(f"{topic:<24} {n:>7} messages")
    if skipped:
        print(f"skipped {skipped} undecodable messages")
    print(f"wrote {args.output}")
    return 0
