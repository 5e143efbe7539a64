"""``perception track``: the tracker core over a detections CSV file."""

from __future__ import annotations

import argparse
import json
import logging
import time
from pathlib import Path

import numpy as np

from common.runtime.cli_util import CliError, check_input_file
from common.runtime.config import ConfigError, read_config_file
from common.runtime.node import load_node_config
from services.tracker import flags
from services.tracker.config import DEFAULT_EMBEDDING_MODEL, PROFILES, AppearanceConfig, TrackerConfig
from services.tracker.core.types import FrameResult
from services.tracker.core.view import FloorView
from services.tracker.offline import Detections, FormatError, Row, read_detections, thresholds_for, track, write_tracks

log = logging.getLogger(__name__)

DESCRIPTION = f"""\
Run the tracker offline on a detections file and write the Confirmed tracks.

Input CSV, with a header row: frame,stamp,x,y,z,score[,e0,e1,...]
  positions in the map frame in metres (z up), stamp in seconds, rows sorted by frame,
  one row per detection. Every frame from the first to the last is processed; frames
  without rows have no detections, and their stamps are interpolated.
  Without e-columns the tracker runs position-only; with them it uses the thresholds
  of --embedding-model (default {DEFAULT_EMBEDDING_MODEL!r}) from the config.
Output CSV: frame,stamp,id,x,y,z, one row per Confirmed track per frame.

A fixed camera's view (--floor-view, its floor homography): a coasting person whose feet
leave the image is no longer reported, and the ID memory tells a person who walked out of
the image from one lost inside it (hidden, missed). In an open place, where those who walk
out seldom come straight back, give --preset pets-site (robust.recovery.left_weight 0.3): a
stranger walking in is then less readily given the ID of someone who walked out."""


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--detections", type=Path, required=True, metavar="DETS.csv", help="input detections")
    parser.add_argument("--output", type=Path, required=True, metavar="TRACKS.csv", help="where to write the tracks")
    parser.add_argument("--service-config", type=Path, default=None, metavar="FILE",
                        help="YAML/JSON settings; its 'tracker' section if it has one, else the whole file")
    flags.add_preset_argument(parser)
    # The old spelling: --config is the Zenoh config in every other command, so it only explains.
    parser.add_argument("--config", dest="old_config", type=Path, default=None, help=argparse.SUPPRESS)
    parser.add_argument("--embedding-model", default=DEFAULT_EMBEDDING_MODEL, metavar="NAME",
                        help=f"model that made the e-columns; picks its thresholds (default {DEFAULT_EMBEDDING_MODEL})")
    parser.add_argument("--time-step", choices=("time", "frame"), default=None,
                        help="thesis profile: 'time': dt from stamps (default); 'frame': dt = 1 per frame, as the thesis")
    parser.add_argument("--profile", choices=PROFILES, default=None,
                        help="'robust' (default): cue fusion, staged association, life cycle in seconds; "
                             "'thesis': Pinto's thesis exactly")
    parser.add_argument("--birth-score", type=float, default=None, metavar="S",
                        help="robust: detections scoring below S update tracks but never start one (default: the settings')")
    parser.add_argument("--floor-view", type=Path, default=None, metavar="FILE",
                        help="a fixed camera's floor homography (the localizer's --floor-homography file, with its "
                             "image_size): what the camera sees, so a coasting person who walked out of the image is "
                             "not reported, and the ID memory knows who walked out (robust: recovery.left_weight)")
    parser.add_argument("--static-map", type=Path, default=None, metavar="MAP.yaml",
                        help="robust: the robot's static map (a ROS map_server / Nav2 map_saver YAML file, in the "
                             "detections' frame): no track is born on its walls and furniture")
    parser.add_argument("--status", action="store_true",
                        help="add a status column: confirmed, or coasting (robust: reported through a short miss)")
    parser.add_argument("--id-log", type=Path, default=None, metavar="IDS.jsonl",
                        help="with e-columns: write why each newly confirmed person got their ID, one JSON line "
                             "per decision that weighed remembered people (the frame, the ID, recovered or new or "
                             "undone; robust: each candidate's log-odds and support, where and when they left; "
                             "thesis: Algorithm 2's descriptor distances against t_recover, rule 'nearest')")


def floor_view(path: Path) -> FloorView:
    """The :class:`FloorView` of a floor homography file, the localizer's ``--floor-homography``
    format (``{"H": 3x3, "image_size": [width, height]}``, JSON or YAML); CliError naming what
    is wrong."""
    check_input_file(path, 'expected a floor homography file: {"H": 3x3, "image_size": [width, height]}')
    try:
        data = read_config_file(path)
    except ConfigError as exc:
        raise CliError(f"floor homography: {exc}") from exc
    if "H" not in data:
        raise CliError(f'floor homography {path} has no "H" (a 3x3 matrix: foot pixel (u, v, 1) -> floor (x, y, w))')
    size = data.get("image_size")
    if not isinstance(size, (list, tuple)) or len(size) != 2:
        raise CliError(f"floor homography {path} has no image_size: the view needs the image's [width, height]; "
                       'add "image_size": [width, height] of the pixels H was fitted in')
    try:
        return FloorView(np.asarray(data["H"], np.float64).reshape(3, 3), int(size[0]), int(size[1]))
    except (TypeError, ValueError) as exc:
        raise CliError(f"floor homography {path}: {exc}") from exc


def _detections(path: Path) -> Detections:
    check_input_file(path, "expected a detections CSV file: frame,stamp,x,y,z,score[,e0,e1,...]")
    try:
        return read_detections(path)
    except FormatError as exc:
        raise CliError(str(exc)) from exc


def _thresholds(config: TrackerConfig, dets: Detections, model: str) -> AppearanceConfig | None:
    """:func:`thresholds_for`, saying what to do when there are none (CliError)."""
    if dets.descriptors is None:
        log.info("no embedding columns: tracking position-only")
    try:
        return thresholds_for(dets, config, model)
    except ValueError as exc:
        raise CliError(f"{exc}; add t_lower, t_upper and t_recover under appearance.{model} in --service-config "
                       "FILE, or pick another --embedding-model") from None


def _write(args: argparse.Namespace, rows: list[Row], decisions: list[dict[str, object]], described: bool) -> None:
    """The track rows to ``args.output`` and the ID decisions to ``args.id_log`` (CliError: cannot write)."""
    try:
        write_tracks(args.output, rows, status=args.status)
        if args.id_log is not None:
            args.id_log.write_text("".join(json.dumps(d) + "\n" for d in decisions))
    except OSError as exc:
        raise CliError(f"cannot write {exc.filename or args.output}: {exc.strerror or exc}") from exc
    if args.id_log is not None:
        log.info("%d ID decisions -> %s%s", len(decisions), args.id_log,
                 "" if described else " (none: IDs are decided from descriptors, and there are none)")


def main(args: argparse.Namespace) -> int:
    if args.old_config is not None:
        raise CliError(f"--config is the Zenoh config file in every command; "
                       f"give the tracker settings as --service-config {args.old_config}")
    config = load_node_config(TrackerConfig, "tracker", args.service_config, {
        "profile": args.profile, "thesis": {"time_step": args.time_step},
        "robust": {"scores": {"birth_score": args.birth_score}, "static_map": {"path": args.static_map}}},
        base=flags.preset(args))
    dets = _detections(args.detections)
    thresholds = _thresholds(config, dets, args.embedding_model)
    view = floor_view(args.floor_view) if args.floor_view is not None else None
    decisions: list[dict[str, object]] = []

    def keep_decisions(frame: int, result: FrameResult) -> None:
        decisions.extend({"frame": frame, **d.as_dict()} for d in result.id_decisions)

    start = time.perf_counter()
    rows = track(dets, config.build_tracker(thresholds), show_progress=True, view=view,
                 on_result=keep_decisions if args.id_log is not None else None)
    elapsed = time.perf_counter() - start
    _write(args, rows, decisions, dets.descriptors is not None)
    n_frames = int(dets.frames[-1] - dets.frames[0] + 1) if len(dets.frames) else 0
    log.info("%d frames, %d detections -> %d track rows in %.2f s (%.0f frames/s)", n_frames, len(dets.frames),
             len(rows), elapsed, n_frames / elapsed if elapsed > 0 else float("inf"))
    return 0
