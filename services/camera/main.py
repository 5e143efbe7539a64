"""``perception camera``: run the camera node."""

from __future__ import annotations

import argparse

from common.runtime.node import run_node
from services.camera import flags
from services.camera.config import CameraConfig
from services.camera.service import CameraService

DESCRIPTION = """\
Publish a camera's images on frames/{camera}, stamped by their capture time, with the camera's
intrinsics: a V4L2 device, a video file, an RTSP/HTTP stream or a folder of images (opencv
backend, RGB only: the localizer then places people on the floor), or a RealSense camera or
recording (colour and depth aligned to it, intrinsics from the device). Intrinsics come from
--camera-info FILE.yaml (ROS camera_calibration or OpenCV), else roughly from --hfov. A file plays
in real time (--rate) or as fast as the detector keeps up (--max); its frame k has seq k and the
stamp start + (k - 1) / fps. A lost live stream is reported in the status and reopened with
backoff. Settings come from defaults <- --service-config FILE (section 'camera') <-
PERCEPTION_CAMERA__FIELD environment variables <- flags."""

add_arguments = flags.add_arguments


def main(args: argparse.Namespace) -> int:
    return run_node(args, "camera", CameraConfig, flags.overrides(args), CameraService, prepare=flags.prepare)
