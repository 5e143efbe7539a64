"""``perception localize``: localize the boxes of a detections file on depth images (or on the
floor, without them), print JSON."""

from __future__ import annotations

import argparse
import json
import logging
import sys
from dataclasses import replace
from pathlib import Path
from typing import Any, Callable

import numpy as np

from common.runtime.cli_util import CliError
from common.runtime.detections_file import read_detection_lines
from common.geometry.transforms import PinholeCamera, TransformBuffer, TransformError
from common.geometry.transforms import RigidTransform
from services.localizer.core import (
    MISMATCH_TOLERANCE,
    DepthNoiseModel,
    FloorParams,
    Localization,
    LocalizerParams,
    camera_pose_from_homography,
    localize,
    localize_on_floor,
    localize_on_floor_homography,
)
from services.localizer.config import LocalizerConfig
from services.localizer.files import (
    boxes_of_line,
    parse_transform,
    read_camera_info,
    read_depth,
    read_floor_homography,
    read_transforms,
)

log = logging.getLogger(__name__)

DESCRIPTION = """\
Localize the person boxes of a detections file on a depth image and print the 3-D
positions as JSON Lines, for checking a camera setup (intrinsics, depth units,
mounting transforms) without running any service.

Inputs
  --depth DEPTH          a 16-bit PNG/TIFF (millimetres, see --depth-unit; 0 = no
                         depth), or a .npy array (uint16 units or float32 metres);
                         a DIRECTORY means: for each detections line use
                         DIRECTORY/<image stem>.png (or .npy)
  --camera-info CAM      JSON or YAML, CameraInfo-like:
                         {"width": 640, "height": 480,
                          "K": [525, 0, 319.5, 0, 525, 239.5, 0, 0, 1],   (or 3x3)
                          "D": [k1, k2, p1, p2, k3], "distortion_model": "plumb_bob",
                          "frame_id": "camera"}
                         (ROS camera_calibration YAML also works)
  --detections DETS      JSON Lines as written by 'perception detect', one image a line:
                         {"image": "f0001.png", "width": 640, "height": 480,
                          "detections": [{"bbox_xyxy": [x1, y1, x2, y2], "score": 0.9}]}
  --transform P:C:X,Y,Z[:QX,QY,QZ,QW]
                         a static transform parent -> child (maps child points into the
                         parent, ROS TF convention), repeatable; e.g. the camera mount
                         base_link:camera:0.1,0,1.2:-0.5,0.5,-0.5,0.5
  --transforms FILE      JSON/YAML list of {"parent_frame", "child_frame",
                         "translation": [x, y, z], "rotation_xyzw": [qx, qy, qz, qw]}

Output (one line per input line)
  {"image": ..., "depth": ..., "frame_id": TARGET, "camera_frame": ...,
   "detections": [{"index", "bbox_xyxy", "score", "pixel": [u, v], "depth_m",
                   "valid_pixels", "position": [x, y, z] (in TARGET),
                   "position_camera": [x, y, z], "cov": 3x3 (in TARGET),
                   "body_center_z": z (a hint only)}],
   "rejected": {reason: count}, "rejected_indices": {index: reason}}

Without transforms, positions are in the camera frame; with transforms the target
frame defaults to 'map' and must be reachable from the camera frame.

Without --depth (an RGB-only camera) each person is put on the floor from the box's
foot point (bottom centre), at --centre-height above it ("depth": null, "pixel" the
foot point, "depth_m" its depth along the optical axis, "valid_pixels" 0):
  --floor-homography FILE  through an image-to-floor homography, JSON
                           {"H": 3x3, "image_size": [w, h]} (a fixed camera); the
                           positions are in its floor frame, named --target-frame
                           (default map); no transform is needed
  otherwise                through the transforms, which must place the camera above
                           the floor z = --floor-z of --target-frame (default map)"""


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument(
        "--depth", type=Path, default=None, metavar="DEPTH",
        help="depth image, or a directory of them (leave out: people on the floor, see below)"
    )
    parser.add_argument("--camera-info", type=Path, required=True, metavar="CAM", help="CameraInfo JSON/YAML")
    parser.add_argument(
        "--detections", type=Path, required=True, metavar="DETS", help="detections JSON Lines ('-' for stdin)"
    )
    parser.add_argument(
        "--transform",
        action="append",
        default=[],
        metavar="P:C:X,Y,Z[:QX,QY,QZ,QW]",
        help="static transform, repeatable",
    )
    parser.add_argument("--transforms", type=Path, default=None, metavar="FILE", help="JSON/YAML file of transforms")
    parser.add_argument(
        "--target-frame",
        default=None,
        help="frame of the output positions (default map with transforms, else the camera frame)",
    )
    parser.add_argument(
        "--camera-frame", default=None, help="camera frame id (default: the camera info's frame_id, else 'camera')"
    )
    d = LocalizerParams()  # the defaults are the core's
    parser.add_argument(
        "--percentile",
        type=float,
        default=d.percentile,
        help=f"depth percentile inside each box (default {d.percentile:g})",
    )
    parser.add_argument(
        "--body-half-depth",
        type=float,
        default=d.body_half_depth_m,
        metavar="M",
        help=f"the body's centre lies this far behind the surface seen (default {d.body_half_depth_m:g}; 0: the surface)",
    )
    parser.add_argument(
        "--min-depth",
        type=float,
        default=d.min_depth_m,
        metavar="M",
        help=f"nearest valid depth (default {d.min_depth_m:g})",
    )
    parser.add_argument(
        "--max-depth",
        type=float,
        default=d.max_depth_m,
        metavar="M",
        help=f"farthest valid depth (default {d.max_depth_m:g})",
    )
    parser.add_argument(
        "--min-valid-pixels",
        type=int,
        default=d.min_valid_pixels,
        metavar="N",
        help=f"fewer valid pixels rejects a box (default {d.min_valid_pixels})",
    )
    parser.add_argument(
        "--depth-unit",
        type=float,
        default=d.depth_unit_m,
        metavar="M",
        help=f"metres per unit of integer depth (default {d.depth_unit_m:g})",
    )
    parser.add_argument(
        "--pixel-sigma",
        type=float,
        default=d.noise.pixel_sigma_px,
        metavar="PX",
        help=f"box-centre pixel sigma (default {d.noise.pixel_sigma_px:g})",
    )
    f = FloorParams()
    parser.add_argument("--floor-homography", type=Path, default=None, metavar="FILE",
                        help='without --depth: the image-to-floor homography, JSON {"H": 3x3, "image_size": [w, h]}')
    parser.add_argument("--floor-z", type=float, default=f.floor_z_m, metavar="M",
                        help=f"without --depth: height of the floor plane (default {f.floor_z_m:g})")
    parser.add_argument("--centre-height", type=float, default=f.centre_height_m, metavar="M",
                        help=f"without --depth: the position is this far above the feet (default {f.centre_height_m:g})")
    parser.add_argument("--max-floor-range", type=float, default=f.max_floor_range_m, metavar="M",
                        help=f"without --depth: farthest feet kept, from the camera (default {f.max_floor_range_m:g})")
    parser.add_argument("--detector", default="", metavar="NAME",
                        help="without --depth: the detector the boxes came from (hog, yolo-onnx, ...), for its foot "
                             "bias (the localizer's foot_bias; default none)")
    parser.add_argument("--output", "-o", type=Path, default=None, help="write here instead of stdout")


def _depth_for(args: argparse.Namespace, item: dict[str, Any], where: str) -> Path:
    assert args.depth is not None
    if not args.depth.is_dir():
        return args.depth
    stem = Path(str(item.get("image", ""))).stem
    for ext in (".png", ".npy", ".tif", ".tiff"):
        if (args.depth / (stem + ext)).is_file():
            return args.depth / (stem + ext)
    raise CliError(f"{where}: no depth image {stem}.png/.npy/.tif in {args.depth}")


def _record(
    item: dict[str, Any],
    depth_path: Path | None,
    camera_frame: str,
    positions_camera: np.ndarray,
    out: Localization,
    scores: list[float],
    boxes: np.ndarray,
) -> dict[str, Any]:
    """One output line; ``positions_camera`` (M, 3) are ``out``'s positions in ``camera_frame``."""
    dets = []
    for k, i in enumerate(out.indices.tolist()):
        depth_m = float(out.depth_m[k])
        dets.append(
            {
                "index": i,
                "bbox_xyxy": boxes[i].tolist(),
                "score": scores[i],
                "pixel": out.pixels[k].round(3).tolist(),
                "depth_m": round(depth_m, 4) if np.isfinite(depth_m) else None,
                "valid_pixels": int(out.valid_pixels[k]),
                "position": out.positions[k].round(4).tolist(),
                "position_camera": positions_camera[k].round(4).tolist(),
                "cov": out.covs[k].round(8).tolist(),
                "body_center_z": round(float(out.positions[k, 2]), 4),
            }
        )
    return {
        "image": item.get("image"),
        "depth": None if depth_path is None else str(depth_path),
        "frame_id": out.frame,
        "camera_frame": camera_frame,
        "detections": dets,
        "rejected": out.rejected_counts(),
        "rejected_indices": {str(i): r for i, r in out.rejected.items()},
    }


#: boxes (N, 4) -> (those boxes on the floor, the camera's pose in their frame)
_Place = Callable[[np.ndarray], tuple[Localization, RigidTransform]]


def _floor(args: argparse.Namespace, camera: PinholeCamera, camera_frame: str, target: str, to_target: RigidTransform
           ) -> tuple[str, _Place]:
    """Without --depth: ``(frame, place)``, ``place(boxes)`` -> (the boxes on the floor, the camera's pose in frame)."""
    try:
        params = replace(LocalizerConfig().floor_params(args.detector), floor_z_m=args.floor_z,
                         centre_height_m=args.centre_height, max_floor_range_m=args.max_floor_range)
    except ValueError as exc:
        raise CliError(str(exc)) from exc
    if args.floor_homography is None:
        if target == camera_frame:
            raise CliError("without --depth, give --floor-homography, or the transforms that place the camera above "
                           "the floor of --target-frame (--transform PARENT:CHILD:X,Y,Z:QX,QY,QZ,QW)")
        return target, lambda boxes: (localize_on_floor(camera, to_target, boxes, params, frame=target), to_target)
    try:
        hom = read_floor_homography(args.floor_homography).for_image(camera.width, camera.height)
    except ValueError as exc:
        raise CliError(f"--floor-homography: {exc}") from exc
    pose = camera_pose_from_homography(hom, camera.K, params.floor_z_m)
    if not pose.mismatch <= MISMATCH_TOLERANCE:
        log.warning("the camera info's K does not fit the floor homography (mismatch %.2f): the ranges, depths and "
                    "camera-frame positions are rough", pose.mismatch)
    frame = args.target_frame or "map"
    return frame, lambda boxes: (localize_on_floor_homography(hom, boxes, params, camera.width, camera.height, pose,
                                                              frame=frame), pose.camera_to_floor)


def main(args: argparse.Namespace) -> int:
    try:
        params = LocalizerParams(
            percentile=args.percentile,
            min_depth_m=args.min_depth,
            max_depth_m=args.max_depth,
            min_valid_pixels=args.min_valid_pixels,
            depth_unit_m=args.depth_unit,
            body_half_depth_m=args.body_half_depth,
            noise=DepthNoiseModel(pixel_sigma_px=args.pixel_sigma),
        )
    except ValueError as exc:
        raise CliError(str(exc)) from exc
    camera, info_frame = read_camera_info(args.camera_info)
    camera_frame = args.camera_frame or info_frame
    edges = [parse_transform(s) for s in args.transform] + (read_transforms(args.transforms) if args.transforms else [])
    buffer = TransformBuffer()
    on_floor = args.depth is None
    try:
        for parent, child, tf in edges:
            buffer.set_transform(parent, child, 0, tf, static=True)
        target = args.target_frame or ("map" if edges or on_floor else camera_frame)
        to_target = RigidTransform.identity()
        if not (on_floor and args.floor_homography is not None):
            to_target = buffer.lookup(target, camera_frame, None)
    except (TransformError, ValueError) as exc:
        hint = "give it with --transform PARENT:CHILD:X,Y,Z:QX,QY,QZ,QW or --transforms FILE"
        if on_floor:
            hint += "; without --depth the transforms place the camera above the floor, or give --floor-homography"
        raise CliError(f"{exc} ({hint})") from exc
    if on_floor:
        target, place = _floor(args, camera, camera_frame, target, to_target)
    out_stream = args.output.open("w") if args.output else sys.stdout
    try:
        for n, item in read_detection_lines(args.detections):
            where = f"{args.detections}:{n}"
            boxes, scores = boxes_of_line(item, where)
            if on_floor:
                _check_size(camera, None, item, where, None)
                out, cam_to_frame = place(boxes)
                record = _record(item, None, camera_frame, cam_to_frame.inverse().apply(out.positions), out,
                                 scores, boxes)
            else:
                depth_path = _depth_for(args, item, where)
                depth = read_depth(depth_path)
                _check_size(camera, depth, item, where, depth_path)
                cam_loc = localize(depth, camera, boxes, params, frame=camera_frame)
                out = cam_loc.transformed(to_target, target)
                record = _record(item, depth_path, camera_frame, cam_loc.positions, out, scores, boxes)
            out_stream.write(json.dumps(record) + "\n")
    finally:
        if args.output:
            out_stream.close()
    return 0


def _check_size(camera: PinholeCamera, depth: np.ndarray | None, item: dict[str, Any], where: str,
                depth_path: Path | None) -> None:
    if depth is not None and depth.shape != (camera.height, camera.width):
        raise CliError(
            f"depth image {depth_path} is {depth.shape[1]}x{depth.shape[0]}, "
            f"the camera info says {camera.width}x{camera.height}"
        )
    w, h = item.get("width"), item.get("height")
    if (w and int(w) != camera.width) or (h and int(h) != camera.height):
        raise CliError(f"{where}: detections are for a {w}x{h} image, the camera is {camera.width}x{camera.height}")
