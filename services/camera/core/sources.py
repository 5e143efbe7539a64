"""Where the camera node's images come from: one interface, one class per backend.

A :class:`Source` opens at construction (a device that does not open, a file that is not a
video: :class:`SourceError`, said once at start-up), then ``read()`` returns the next
:class:`Capture`, ``None`` at the end of a file, or raises :class:`StreamLost` when a live
stream goes away (a USB cable pulled, an RTSP server gone); the node then reopens it with backoff.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Protocol

import numpy as np

__all__ = ["Capture", "Intrinsics", "Source", "SourceError", "StreamLost"]


class SourceError(RuntimeError):
    """The source cannot be opened or read; the message names it and the fix."""


class StreamLost(RuntimeError):
    """A live source stopped delivering during a run; the node retries with backoff."""


@dataclass(frozen=True)
class Intrinsics:
    """Pinhole intrinsics of the colour image."""

    width: int
    height: int
    K: np.ndarray
    D: np.ndarray
    distortion_model: str = "plumb_bob"
    #: True when the intrinsics are a guess from a field of view, not a calibration.
    rough: bool = False


@dataclass(frozen=True)
class Capture:
    """One captured image: colour (H, W, 3) uint8 (RGB, or BGR when ``order`` says so), depth aligned to it when the source has depth
    (uint16 millimetres, 0 = invalid, or float32 metres, NaN = invalid), the capture time (ns
    since the epoch, None for a file: the node stamps it by its frame number) and the frame
    number in the source (1 for the first frame of a file)."""

    rgb: np.ndarray | None
    depth: np.ndarray | None
    stamp_ns: int | None
    index: int
    #: "bgr8" when ``rgb`` holds OpenCV's blue-green-red order, passed on as it is (a conversion
    #: costs more than the rest of the frame's work; the receivers read either order).
    order: str = "rgb8"
    #: A JPEG frame passed on undecoded (an MJPG file's or a folder's own), with its (height,
    #: width): then ``rgb`` is None and the receivers decode it.
    jpeg: bytes | None = None
    size: tuple[int, int] | None = None


class Source(Protocol):
    #: The source's own frame rate (a file's, a device's setting), None when unknown.
    fps: float | None
    #: A file plays once and can be paced; a live stream cannot.
    is_file: bool
    #: Intrinsics the device knows (a RealSense), else None (calibration file or field of view).
    intrinsics: Intrinsics | None
    #: What it is, for logs and the status.
    name: str

    def read(self) -> Capture | None: ...

    def close(self) -> None: ...


def is_image_folder(path: Path) -> bool:
    return path.is_dir()
