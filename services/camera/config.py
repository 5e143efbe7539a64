"""CameraConfig: the camera node's settings."""

from __future__ import annotations

from pathlib import Path
from typing import Literal

from pydantic import BaseModel, ConfigDict, Field, field_validator, model_validator

from common.messages.keys import validate_chunk

__all__ = ["CameraConfig"]


class CameraConfig(BaseModel):
    """Everything ``perception camera`` can be told."""

    model_config = ConfigDict(extra="forbid")

    backend: Literal["opencv", "realsense"] = Field(
        default="opencv", description="opencv: a V4L2 device, a video file, an RTSP/HTTP URL or a folder of images (RGB "
                                      "only); realsense: a RealSense camera (colour + aligned depth) or its recording")
    source: str = Field(default="0", description="opencv: a device index (0) or path (/dev/video0), a video file, a "
                                                 "folder of images (sorted by name) or a URL; realsense: a recording "
                                                 "(.bag, .db3), or '' for a live camera")
    serial: str = Field(default="", description="realsense: the camera's serial number ('': the first one)")
    camera: str = Field(default="head", description="this project's camera name: frames/{camera}")
    frame_id: str = Field(default="", description="the optical frame's name in the transforms ('': {camera}_optical)")
    width: int = Field(default=640, ge=0, le=8192, description="the size asked of a device (0: its default)")
    height: int = Field(default=480, ge=0, le=8192)
    fps: float = Field(default=30.0, gt=0.0, le=1000.0,
                       description="the rate asked of a device; a folder of images plays at this rate")
    camera_info: Path | None = Field(default=None, description="calibration: ROS camera_calibration YAML, or OpenCV "
                                                                "FileStorage YAML/XML")
    hfov_deg: float = Field(default=69.0, gt=1.0, lt=179.0,
                            description="without a calibration: the horizontal field of view (rough intrinsics, "
                                        "a warning says so)")
    pace: Literal["real-time", "max"] = Field(
        default="real-time", description="a file: at its frame rate times rate, or each frame once the detector "
                                         "has answered the previous one (max)")
    rate: float = Field(default=1.0, gt=0.0, le=100.0, description="a file's speed relative to real time")
    max_wait_s: float = Field(default=2.0, gt=0.0, description="max: the longest wait for the detector per frame")
    detections: str = Field(default="", description="max: the detections stream to wait for ('': the camera's)")
    loop: bool = Field(default=False, description="a file starts again at its end (else the node exits)")
    start_ns: int | None = Field(default=None, ge=0, description="a file's first stamp (default: the wall clock at "
                                                                  "start); frame k is start + (k - 1) / fps")
    retry_initial_s: float = Field(default=0.5, gt=0.0, description="a lost live stream: the first wait before reopening")
    retry_max_s: float = Field(default=10.0, gt=0.0, description="... doubling up to this")
    passthrough: bool = Field(default=True, description="opencv: a folder's JPEG files and an MJPG video's frames go "
                                                         "out as the JPEGs they are, undecoded (the receivers decode "
                                                         "them); false: decoded and sent raw")
    jpeg_quality: int = Field(default=0, ge=0, le=100,
                              description="publish colour as JPEG of this quality (0: raw rgb8, the default)")

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
