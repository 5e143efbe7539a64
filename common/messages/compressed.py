"""The size of a JPEG or PNG image from its header, without decoding it: what a compressed
``Image`` message needs (its shape) when the pixels are passed on as they came."""

from __future__ import annotations

import struct

__all__ = ["PNG_MAGIC", "is_jpeg", "jpeg_size", "png_size"]

PNG_MAGIC = b"\x89PNG\r\n\x1a\n"


def jpeg_size(data: bytes) -> tuple[int, int, int]:
    """(height, width, components) from a JPEG's start-of-frame marker."""
    i = 2
    n = len(data)
    while i + 4 <= n:
        if data[i] != 0xFF:
            raise ValueError("a JPEG marker was expected")
        marker = data[i + 1]
        if marker == 0xFF:  # fill byte
            i += 1
            continue
        if marker in (0xD8, 0x01) or 0xD0 <= marker <= 0xD7:
            i += 2
            continue
        (length,) = struct.unpack_from(">H", data, i + 2)
        if 0xC0 <= marker <= 0xCF and marker not in (0xC4, 0xC8, 0xCC):
            if i + 10 > n:
                break
            h, w = struct.unpack_from(">HH", data, i + 5)
            return h, w, data[i + 9]
        i += 2 + length
    raise ValueError("no start-of-frame marker")


def png_size(data: bytes) -> tuple[int, int, int, int]:
    """(height, width, bit depth, colour type) from a PNG's IHDR chunk."""
    if len(data) < 29 or data[12:16] != b"IHDR":
        raise ValueError("no IHDR chunk")
    w, h, bits, colour = struct.unpack_from(">IIBB", data, 16)
    return h, w, bits, colour


def is_jpeg(data: bytes) -> bool:
    return data[:2] == b"\xff\xd8"
