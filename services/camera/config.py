"""CameraConfig: the camera node's settings."""

from __future__ import annotations

from pathlib import Path
from typing import Literal

from pydantic import ConfigDict, field_validator, model_validator

from common.runtime.settings import AdvancedBlock, setting

from common.messages.keys import validate_chunk

__all__ = ["CameraConfig"]


class CameraConfig(AdvancedBlock):
    """Everything ``perception camera`` can be told."""

    model_config = ConfigDict(extra="forbid")

    backend: Literal["opencv", "realsense"] = setting("opencv", "opencv: a V4L2 device, a video file, an RTSP/HTTP "
                                                      "URL or a folder of images (RGB only); realsense: a RealSense "
                                                      "camera (colour + aligned depth) or its recording")
    source: str = setting("0", "opencv: a device index (0) or path (/dev/video0), a video file, a folder of images "
                          "(sorted by name) or a URL; realsense: a recording (.bag, .db3), or '' for a live camera")
    serial: str = setting("", "realsense: the camera's serial number ('': the first one)")
    camera: str = setting("head", "this project's camera name: frames/{camera}")
    frame_id: str = setting("", "the optical frame's name in the transforms ('': {camera}_optical)")
    width: int = setting(640, "the image width asked of a device (0: its default)", unit="px", ge=0, le=8192)
    height: int = setting(480, "... and its height (0: its default)", unit="px", ge=0, le=8192)
    fps: float = setting(30.0, "the rate asked of a device; a folder of images plays at this rate", unit="Hz", gt=0.0, le=1000.0)
    camera_info: Path | None = setting(None, "calibration: ROS camera_calibration YAML, or OpenCV FileStorage "
                                       "YAML/XML")
    hfov_deg: float = setting(69.0, "without a calibration: the horizontal field of view (rough intrinsics, a warning "
                              "says so)", unit="deg", gt=1.0, lt=179.0)
    pace: Literal["real-time", "max"] = setting("real-time", "a file: at its frame rate times rate, or each frame "
                                                "once the detector has answered the previous one (max)")
    rate: float = setting(1.0, "a file's speed relative to real time", gt=0.0, le=100.0)
    max_wait_s: float = setting(2.0, "max: the longest wait for the detector per frame", unit="s", gt=0.0, advanced=True)
    detections: str = setting("", "max: the detections stream to wait for ('': the camera's)")
    loop: bool = setting(False, "a file starts again at its end (else the node exits)")
    start_ns: int | None = setting(None, "a file's first stamp (default: the wall clock at start); frame k is start + "
                                   "(k - 1) / fps", unit="ns", ge=0)
    retry_initial_s: float = setting(0.5, "a lost live stream: the first wait before reopening", unit="s", gt=0.0, advanced=True)
    retry_max_s: float = setting(10.0, "... doubling up to this", unit="s", gt=0.0, advanced=True)
    passthrough: bool = setting(True, "opencv: a folder's JPEG files and an MJPG video's frames go out as the JPEGs "
                                "they are, undecoded (the receivers decode them); false: decoded and sent raw")
    jpeg_quality: int = setting(0, "publish colour as JPEG of this quality (0: raw rgb8, the default)", ge=0, le=100)

    @field_validator("camera_info", mode="before")
    @classmethod
    def _no_file(cls, v: object) -> object:
        return None if v in ("", None) else v  # an unset ${CAMERA_INFO:-} in a launch file

    @model_validator(mode="after")
    def _names(self) -> CameraConfig:
        validate_chunk(self.camera, "camera")
        if self.backend == "opencv" and not self.source:
            raise ValueError("source: give a device index (0), a video file, a folder of images or a URL")
        return self

    @property
    def optical_frame(self) -> str:
        return self.frame_id or f"{self.camera}_optical"
