"""``perception calibrate-localizer``: the floor paths' foot-point noise of a detector, measured."""

from __future__ import annotations

import argparse
import json
import math
import re
from pathlib import Path

import numpy as np

from common.runtime.cli_util import CliError, check_input_file
from common.runtime.detections_file import read_detection_lines
from services.localizer.config import LocalizerConfig
from services.localizer.core.foot_noise import FootNoise, fit_foot_noise, match_boxes
from services.localizer.files import boxes_of_line

DESCRIPTION = """\
Measure how far a detector's foot points stray, for a camera without depth.

The localizer puts a person where the bottom centre of the box meets the floor, and tells the
tracker how uncertain that is: a pixel plus a share of the box's height, across (u) and down
(v) (foot_sigma_u_px, foot_sigma_share_u, ...). The shares depend on the detector. This
command pairs your detector's boxes with ground-truth boxes of the same frames (IoU >= 0.5,
one to one), fits sigma^2 = sigma_px^2 + (share * h)^2 to the foot points' errors, and prints
the settings, the check per box height and the bias: the mean error, which the localizer takes
off the foot point of that detector's boxes (foot_bias; a detector whose boxes reach below the
feet would put people a little too close).

Inputs:
  --detections  JSON lines of 'perception detect' (the frame is the last number in each
                image's file name: frame_0042.jpg, 000042.png), or a MOTChallenge det.txt
                (frame,id,left,top,width,height,score,...)
  --ground-truth  a MOTChallenge gt.txt (frame,id,left,top,width,height,flag,...); rows whose
                flag (column 7) is 0 are don't-care and left out

Example (PETS09, whose ground truth is in 768x576 pixels and the frames 480x360):
  perception detect frames/*.jpg > dets.jsonl
  perception calibrate-localizer --detections dets.jsonl --ground-truth gt.txt --gt-scale 0.625"""

_NUMBER = re.compile(r"\d+")


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--detections", required=True, metavar="DETS",
                        help="the detector's boxes: JSON lines of 'perception detect', or a MOTChallenge det.txt")
    parser.add_argument("--ground-truth", required=True, metavar="GT.txt",
                        help="MOTChallenge ground truth of the same frames")
    parser.add_argument("--gt-scale", type=float, default=1.0, metavar="S",
                        help="multiply the ground truth's boxes by S, when it was drawn on images of another size "
                             "(default 1)")
    parser.add_argument("--min-iou", type=float, default=0.5, metavar="IOU",
                        help="a detection and a ground-truth box pair up at this IoU or more (default 0.5)")
    parser.add_argument("--detector", default="hog", metavar="NAME",
                        help="the detector the boxes came from, as its detections name it (hog, yolo-onnx, darknet, "
                             "...): the settings' foot_bias entry (default hog)")
    parser.add_argument("--json", action="store_true", help="print the result as JSON")


def _mot_boxes(path: str, what: str, flag_column: bool) -> tuple[np.ndarray, np.ndarray]:
    """(frames (N,), xyxy boxes (N, 4)) of a MOTChallenge file; with ``flag_column`` the rows
    whose 7th column is 0 are left out. CliError naming the file and line of a bad row."""
    need = 7 if flag_column else 6
    form = f"frame,id,left,top,width,height{',flag' if flag_column else ''},..."
    try:
        text = Path(path).read_text(encoding="utf-8")
    except UnicodeDecodeError:
        raise CliError(f"{path}: not text; expected a MOTChallenge {what} ({form})") from None
    rows = []
    for n, line in enumerate(text.splitlines(), 1):
        if not line.strip():
            continue
        cells = line.replace(" ", "").split(",")
        try:
            values = [float(c) for c in cells]
        except ValueError:
            raise CliError(f"{path}:{n}: not a MOTChallenge {what} row ({form}: numbers), "
                           f"got {line.strip()[:60]!r}") from None
        if len(values) < need or not all(math.isfinite(v) for v in values[:need]):
            raise CliError(f"{path}:{n}: a MOTChallenge {what} row has {need} or more finite numbers ({form}), "
                           f"got {line.strip()[:60]!r}")
        rows.append(values[:need])
    if not rows:
        raise CliError(f"{path} is empty; expected a MOTChallenge {what} ({form})")
    arr = np.asarray(rows, np.float64)
    if flag_column:
        arr = arr[arr[:, 6] != 0]
    x, y, w, h = arr[:, 2], arr[:, 3], arr[:, 4], arr[:, 5]
    return arr[:, 0].astype(np.int64), np.column_stack([x, y, x + w, y + h])


def _jsonl_boxes(path: str) -> tuple[np.ndarray, np.ndarray]:
    frames, boxes = [], []
    for n, line in read_detection_lines(path, require_image=True):
        numbers = _NUMBER.findall(Path(str(line["image"])).stem)
        if not numbers:
            raise CliError(f"{path}:{n}: no frame number in the image's name {line['image']!r} "
                           "(name the images after their frame, e.g. frame_0042.jpg)")
        got, _ = boxes_of_line(line, f"{path}:{n}")
        frames += [int(numbers[-1])] * len(got)
        boxes.append(got)
    return np.asarray(frames, np.int64), np.concatenate(boxes) if boxes else np.zeros((0, 4))


def read_detections(path: str) -> tuple[np.ndarray, np.ndarray]:
    """(frames, xyxy boxes) of a detections file: JSON lines or a MOTChallenge det.txt."""
    check_input_file(path, "the detector's boxes: JSON lines of 'perception detect', or a MOTChallenge det.txt")
    if Path(path).suffix.lower() in (".jsonl", ".json", ".ndjson"):
        return _jsonl_boxes(path)
    return _mot_boxes(path, "det.txt", flag_column=False)


def _report(noise: FootNoise, pairs: int, dets: int, gts: int, detector: str) -> dict[str, object]:
    return {"detections": dets, "ground_truth": gts, "pairs": pairs, "used": noise.matched, "dropped": noise.dropped,
            "settings": {"foot_sigma_u_px": round(noise.sigma_u_px, 2), "foot_sigma_v_px": round(noise.sigma_v_px, 2),
                         "foot_sigma_share_u": round(noise.share_u, 4), "foot_sigma_share_v": round(noise.share_v, 4)},
            "bias_share": {"u": round(noise.bias_u, 4), "v": round(noise.bias_v, 4)},
            "foot_bias": {detector: {"u": round(noise.bias_u, 3), "v": round(noise.bias_v, 3)}},
            "bins": [{"height_px": [round(b.lo, 1), round(b.hi, 1)], "n": b.n,
                      "rms_px": [round(b.rms_u_px, 2), round(b.rms_v_px, 2)],
                      "fit_px": [round(b.fit_u_px, 2), round(b.fit_v_px, 2)]} for b in noise.bins]}


def main(args: argparse.Namespace) -> int:
    if not (math.isfinite(args.gt_scale) and args.gt_scale > 0):
        raise CliError(f"--gt-scale must be a positive number, got {args.gt_scale}")
    if not 0.0 < args.min_iou <= 1.0:
        raise CliError(f"--min-iou must be in (0, 1], got {args.min_iou}")
    det_frames, det_boxes = read_detections(args.detections)
    check_input_file(args.ground_truth, "a MOTChallenge gt.txt")
    gt_frames, gt_boxes = _mot_boxes(args.ground_truth, "gt.txt", flag_column=True)
    gt_boxes = gt_boxes * args.gt_scale
    common = np.intersect1d(det_frames, gt_frames)
    if not len(common):
        raise CliError(f"no frame of {args.detections} ({len(np.unique(det_frames))} frames) is in {args.ground_truth} "
                       f"({len(np.unique(gt_frames))} frames): the frame numbers must agree (for JSON lines, the last "
                       "number in each image's name)")
    d, g = match_boxes(det_frames, det_boxes, gt_frames, gt_boxes, args.min_iou)
    try:
        noise = fit_foot_noise(det_boxes[d], gt_boxes[g])
    except ValueError as exc:
        raise CliError(f"{exc} (over {len(common)} common frames at IoU >= {args.min_iou}; are the ground truth's "
                       "boxes in the detections' pixels? see --gt-scale)") from None
    report = _report(noise, len(d), len(det_boxes), len(gt_boxes), args.detector)
    if args.json:
        print(json.dumps(report, indent=2))
        return 0
    config = LocalizerConfig()
    now = config.floor_params(args.detector)
    print(f"{len(det_boxes)} detections, {len(gt_boxes)} ground-truth boxes, {len(common)} common frames: "
          f"{len(d)} pairs at IoU >= {args.min_iou}, {noise.dropped} of them left out as mismatches")
    print(f"{'box height (px)':>16} {'pairs':>6} {'error across':>13} {'fit':>6} {'error down':>11} {'fit':>6}")
    for b in noise.bins:
        print(f"{b.lo:7.1f} - {b.hi:6.1f} {b.n:6d} {b.rms_u_px:10.2f} px {b.fit_u_px:6.2f} {b.rms_v_px:8.2f} px "
              f"{b.fit_v_px:6.2f}")
    print(f"bias (mean error, as a share of the height, + is right / down): across {noise.bias_u:+.4f}, "
          f"down {noise.bias_v:+.4f}")
    print(f"the defaults now: {now.foot_sigma_u_px} / {now.foot_sigma_v_px} px, shares {now.foot_sigma_share_u} / "
          f"{now.foot_sigma_share_v}; foot bias of {args.detector!r}: "
          + (f"u {now.foot_bias_u}, v {now.foot_bias_v}" if args.detector in config.foot_bias else "none"))
    s, bias = report["settings"], report["foot_bias"]
    assert isinstance(s, dict) and isinstance(bias, dict)
    print("\nlocalizer:\n" + "".join(f"  {k}: {v}\n" for k, v in s.items())
          + f"  foot_bias:\n    {args.detector}: {{u: {bias[args.detector]['u']}, v: {bias[args.detector]['v']}}}")
    return 0
