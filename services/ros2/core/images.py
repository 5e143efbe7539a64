"""ROS 2 images and camera info as plain pixels: ``sensor_msgs/msg/Image``,
``sensor_msgs/msg/CompressedImage`` and ``sensor_msgs/msg/CameraInfo``.

Raw encodings the pipeline reads are passed through without a copy of the pixels when rows
carry no padding (``step == width * bytes per pixel``). A compressed image keeps its JPEG or
PNG bytes: only its header is read for the size, so nothing is decoded here. Every problem is a
:class:`ImageError` whose ``reason`` is a short counter name and whose text says what was wrong.
"""

from __future__ import annotations

import struct
from dataclasses import dataclass
from typing import Any

import numpy as np

from common.messages.compressed import PNG_MAGIC, jpeg_size, png_size

__all__ = ["ENCODINGS", "ImageError", "Intrinsics", "Pixels", "compressed_pixels", "intrinsics", "raw_pixels"]

#: ROS encoding -> (dtype, channels) for the encodings the pipeline reads.
ENCODINGS: dict[str, tuple[str, int]] = {
    "rgb8": ("uint8", 3),
    "bgr8": ("uint8", 3),
    "mono8": ("uint8", 1),
    "8UC1": ("uint8", 1),
    "16UC1": ("uint16", 1),  # depth in millimetres (the RealSense driver's aligned depth)
    "mono16": ("uint16", 1),
    "32FC1": ("float32", 1),  # depth in metres
}
#: What an encoding is called in this project's Image message.
_AS = {"8UC1": "mono8", "mono16": "16UC1"}
_CAMERA_MODELS = {"plumb_bob": 5, "rational_polynomial": 8, "equidistant": 4}


class ImageError(ValueError):
    """An image this node cannot read; ``reason`` is the counter it is counted under."""

    def __init__(self, reason: str, text: str) -> None:
        super().__init__(text)
        self.reason = reason


@dataclass(frozen=True)
class Pixels:
    """An image as this project's Image message holds it: encoding, dtype, shape and bytes."""

    encoding: str
    dtype: str
    shape: tuple[int, ...]
    data: bytes | memoryview

    @property
    def is_depth(self) -> bool:
        return self.encoding in ("16UC1", "32FC1") or (self.encoding == "png" and self.dtype == "uint16")


def raw_pixels(msg: Any, *, depth: bool) -> Pixels:
    """A ``sensor_msgs/msg/Image`` as pixels; ``depth`` says which kind the topic must carry."""
    enc = str(msg.encoding)
    if enc not in ENCODINGS:
        raise ImageError("unknown_encoding", f"encoding {enc!r} is not one of {', '.join(ENCODINGS)}")
    dtype, channels = ENCODINGS[enc]
    enc = _AS.get(enc, enc)
    is_depth = enc in ("16UC1", "32FC1")
    if depth and not is_depth:
        raise ImageError("not_depth", f"encoding {enc!r} on the depth topic: depth must be 16UC1 (mm) or 32FC1 (m)")
    if not depth and is_depth:
        raise ImageError("not_colour", f"encoding {enc!r} on the colour topic: colour must be rgb8, bgr8 or mono8")
    h, w, step = int(msg.height), int(msg.width), int(msg.step)
    if h <= 0 or w <= 0:
        raise ImageError("empty", f"image is {w}x{h}")
    item = np.dtype(dtype).itemsize
    row = w * channels * item
    data = msg.data
    if step < row:
        raise ImageError("bad_step", f"step {step} is less than width {w} x {channels * item} bytes per pixel ({row})")
    if len(data) != step * h:
        raise ImageError("bad_size", f"data holds {len(data)} bytes, step {step} x height {h} needs {step * h}")
    big = bool(msg.is_bigendian) and item > 1
    if step != row or big:
        arr = np.frombuffer(data, np.uint8).reshape(h, step)[:, :row]
        pixels = np.ascontiguousarray(arr).view(np.dtype(dtype).newbyteorder(">") if big else dtype)
        raw: bytes | memoryview = pixels.astype(dtype).tobytes()
    else:
        raw = memoryview(data) if isinstance(data, np.ndarray) else bytes(data)
    shape = (h, w, channels) if channels > 1 else (h, w)
    return Pixels(enc, dtype, shape, raw)


def compressed_pixels(msg: Any, *, depth: bool) -> Pixels:
    """A ``sensor_msgs/msg/CompressedImage`` (JPEG or PNG; image_transport's ``compressed`` and,
    for 16-bit depth, ``compressedDepth``) as compressed pixels, told apart by their magic bytes."""
    data = bytes(msg.data)
    fmt = str(msg.format)
    if "compresseddepth" in fmt.lower().replace(" ", ""):
        # compressedDepth: a 12-byte header (format, two float parameters) before the PNG
        if "32FC1" in fmt:
            raise ImageError("unknown_encoding", f"format {fmt!r}: 32FC1 compressedDepth (quantized inverse depth) is not "
                                                 "read; publish 16UC1 or raw depth")
        data = data[12:]
    try:
        if data[:2] == b"\xff\xd8":
            h, w, comps = jpeg_size(data)
            if depth:
                raise ImageError("not_depth", f"a JPEG on the depth topic (format {fmt!r}): depth must be 16-bit PNG")
            return Pixels("jpeg", "uint8", (h, w, 3) if comps == 3 else (h, w), data)
        if data[:8] == PNG_MAGIC:
            h, w, bits, colour = png_size(data)
            if depth:
                if bits != 16 or colour != 0:
                    raise ImageError("not_depth", f"a {bits}-bit PNG of colour type {colour} on the depth topic: "
                                                  "depth must be a 16-bit grey PNG (mm)")
                return Pixels("png", "uint16", (h, w), data)
            if bits != 8 or colour not in (0, 2, 6):
                raise ImageError("unknown_encoding", f"a {bits}-bit PNG of colour type {colour} is not a colour image")
            return Pixels("png", "uint8", (h, w) if colour == 0 else (h, w, 3), data)
    except (ValueError, struct.error) as exc:
        if isinstance(exc, ImageError):
            raise
        raise ImageError("corrupt", f"format {fmt!r}: {exc}") from exc
    raise ImageError("unknown_encoding", f"format {fmt!r}: the data is neither JPEG nor PNG")


@dataclass(frozen=True)
class Intrinsics:
    width: int
    height: int
    K: np.ndarray
    D: np.ndarray
    distortion_model: str


def intrinsics(msg: Any) -> Intrinsics:
    """A ``sensor_msgs/msg/CameraInfo``'s size, K and distortion; :class:`ImageError` if unusable."""
    k = np.asarray(msg.k, dtype=np.float64).reshape(3, 3)
    if not np.all(np.isfinite(k)) or k[0, 0] <= 0 or k[1, 1] <= 0:
        raise ImageError("bad_camera_info", "camera info: K has no positive focal lengths (is the camera calibrated?)")
    model = str(msg.distortion_model) or "none"
    d = np.asarray(msg.d, dtype=np.float64)
    if model not in _CAMERA_MODELS and model != "none":
        raise ImageError("bad_camera_info", f"camera info: distortion model {model!r} is not plumb_bob, "
                                            "rational_polynomial or equidistant")
    if model == "none" or not np.any(d):
        model, d = "none", np.zeros(0)
    elif len(d) != _CAMERA_MODELS[model]:
        if model == "plumb_bob" and len(d) < 5:
            d = np.concatenate([d, np.zeros(5 - len(d))])
        else:
            raise ImageError("bad_camera_info", f"camera info: {model} takes {_CAMERA_MODELS[model]} coefficients, "
                                                f"got {len(d)}")
    if int(msg.width) <= 0 or int(msg.height) <= 0:
        raise ImageError("bad_camera_info", f"camera info: size {msg.width}x{msg.height}")
    return Intrinsics(int(msg.width), int(msg.height), k, d, model)
