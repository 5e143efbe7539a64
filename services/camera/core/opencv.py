"""The ``opencv`` backend: a V4L2 device (index or path), a video file, an RTSP/HTTP URL, or a
folder of images (sorted by name). RGB only."""

from __future__ import annotations

import time
from pathlib import Path

import cv2
import numpy as np

from common.messages.compressed import is_jpeg, jpeg_size
from services.camera.core.sources import Capture, Intrinsics, SourceError, StreamLost

__all__ = ["IMAGE_SUFFIXES", "OpenCvSource", "describe_source"]

IMAGE_SUFFIXES = (".jpg", ".jpeg", ".png", ".bmp", ".tif", ".tiff", ".webp", ".ppm", ".pgm")
_URL = ("rtsp://", "rtsps://", "http://", "https://", "udp://", "tcp://", "rtmp://")


def _fourcc(cap: cv2.VideoCapture) -> str:
    code = int(cap.get(cv2.CAP_PROP_FOURCC))
    return code.to_bytes(4, "little").decode("ascii", errors="replace")


def _jpeg_capture(data: bytes, index: int, stamp: int | None) -> Capture | None:
    """A colour JPEG as a capture passed on undecoded, or None when it is not one (a grey JPEG,
    a corrupt header): then the caller decodes it."""
    if not is_jpeg(data):
        return None
    try:
        h, w, comps = jpeg_size(data)
    except (ValueError, IndexError):
        return None
    if comps != 3 or h <= 0 or w <= 0:
        return None
    return Capture(None, None, stamp, index, jpeg=data, size=(h, w))


def describe_source(spec: str) -> str:
    """What ``spec`` names: ``device``, ``url``, ``folder``, ``file`` or ``missing``."""
    if spec.isdigit() or spec.startswith("/dev/video"):
        return "device"
    if spec.startswith(_URL):
        return "url"
    path = Path(spec).expanduser()
    if path.is_dir():
        return "folder"
    if path.is_file():
        return "file"
    return "missing"


class OpenCvSource:
    """Frames from OpenCV's ``VideoCapture``, or from the image files of a folder.

    ``fps``: a folder's frame rate (it has none of its own), and the rate asked of a device; a
    video file reports its own. ``width``/``height``: the size asked of a device (0: its default).
    ``passthrough``: a folder's JPEG files and an MJPG video's frames go out as the JPEGs they are,
    undecoded (the receivers decode them); other frames are decoded.
    """

    is_file: bool
    intrinsics: Intrinsics | None = None

    def __init__(self, spec: str, *, fps: float = 30.0, width: int = 0, height: int = 0,
                 open_timeout_s: float = 10.0, passthrough: bool = True) -> None:
        # OpenCV's worker threads spin between frames: on a 640x480 stream they cost more than the
        # work they share (16 % of a core against 4 % at 30 Hz); one thread does a frame in ~1 ms
        cv2.setNumThreads(1)
        self.spec = spec
        self.passthrough = passthrough
        self._raw = False  # an MJPG video read as its JPEG packets
        self.kind = describe_source(spec)
        self._index = 0
        self._files: list[Path] = []
        self._cap: cv2.VideoCapture | None = None
        if self.kind == "missing":
            raise SourceError(f"{spec}: no such file, folder or device; give a device index (0), a device path "
                              "(/dev/video0), a video file, a folder of images or an rtsp:// or http:// URL")
        if self.kind == "folder":
            folder = Path(spec).expanduser()
            self._files = sorted(p for p in folder.iterdir() if p.suffix.lower() in IMAGE_SUFFIXES)
            if not self._files:
                raise SourceError(f"{spec}: the folder holds no image ({', '.join(IMAGE_SUFFIXES)})")
            self.is_file = True
            self.fps: float | None = fps
            self.name = f"folder {spec} ({len(self._files)} images)"
            return
        self.is_file = self.kind == "file"
        target: int | str = int(spec) if spec.isdigit() else str(Path(spec).expanduser()) if self.is_file else spec
        params = [cv2.CAP_PROP_OPEN_TIMEOUT_MSEC, int(open_timeout_s * 1000)] if self.kind == "url" else []
        cap = cv2.VideoCapture(target, cv2.CAP_ANY, params) if params else cv2.VideoCapture(target)
        if not cap.isOpened():
            cap.release()
            raise SourceError(self._open_error())
        if self.kind == "device":
            if width and height:
                cap.set(cv2.CAP_PROP_FRAME_WIDTH, width)
                cap.set(cv2.CAP_PROP_FRAME_HEIGHT, height)
            if fps:
                cap.set(cv2.CAP_PROP_FPS, fps)
        own = cap.get(cv2.CAP_PROP_FPS)
        self.fps = float(own) if own and 0 < own < 1000 else (fps or None)
        self._cap = cap
        self.name = {"device": f"device {spec}", "url": f"stream {spec}", "file": f"video {spec}"}[self.kind]
        if self.is_file and passthrough and _fourcc(cap) == "MJPG" and cap.set(cv2.CAP_PROP_FORMAT, -1):
            self._raw = True  # each packet is a JPEG: passed on undecoded
        if self.is_file:
            # a file that is not a video opens on some backends and then yields nothing
            ok, first = cap.read()
            if not ok or first is None:
                cap.release()
                raise SourceError(f"{spec}: not a video OpenCV can read (no frame decoded); convert it, e.g. "
                                  "ffmpeg -i IN -c:v libx264 OUT.mp4, or give a folder of images")
            self._first: np.ndarray | None = first
        else:
            self._first = None

    def _open_error(self) -> str:
        if self.kind == "device":
            return (f"camera {self.spec} does not open: is it connected (v4l2-ctl --list-devices), used by another "
                    "program, and is this user in the 'video' group?")
        if self.kind == "url":
            return f"stream {self.spec} does not open: is the server up and the URL right (try it with ffplay)?"
        return f"{self.spec}: not a video OpenCV can open (an unknown container or codec)"

    def read(self) -> Capture | None:
        if self._files:
            if self._index >= len(self._files):
                return None
            path = self._files[self._index]
            if self.passthrough and path.suffix.lower() in (".jpg", ".jpeg"):
                if (jpeg := _jpeg_capture(path.read_bytes(), self._index + 1, None)) is not None:
                    self._index += 1
                    return jpeg
            bgr = cv2.imread(str(path), cv2.IMREAD_COLOR)
            if bgr is None:
                raise SourceError(f"{path}: not an image OpenCV can read")
            self._index += 1
            return Capture(bgr, None, None, self._index, order="bgr8")
        assert self._cap is not None
        if self._first is not None:
            ok, bgr, self._first = True, self._first, None
        else:
            ok, bgr = self._cap.read()
        stamp = None if self.is_file else time.time_ns()
        if not ok or bgr is None:
            if self.is_file:
                return None
            raise StreamLost(f"{self.name} stopped delivering frames")
        self._index += 1
        if self._raw:
            jpeg = _jpeg_capture(bgr.tobytes(), self._index, stamp)
            if jpeg is None:
                raise SourceError(f"{self.name}: frame {self._index} is not a JPEG; play it with passthrough off")
            return jpeg
        if bgr.ndim == 2:
            bgr = cv2.cvtColor(bgr, cv2.COLOR_GRAY2BGR)
        return Capture(bgr, None, stamp, self._index, order="bgr8")

    def close(self) -> None:
        if self._cap is not None:
            self._cap.release()
            self._cap = None
