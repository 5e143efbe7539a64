"""The colour image of a frame as JPEG, for the operator's page and Foxglove."""

from __future__ import annotations

from common.messages.schemas import RGBDFrame

__all__ = ["jpeg_of"]


def jpeg_of(frame: RGBDFrame, quality: int) -> bytes:
    """The frame's colour image as JPEG (passed through when it already is one)."""
    if frame.rgb.encoding == "jpeg":
        return frame.rgb.data
    import cv2

    rgb = frame.rgb.to_array()
    bgr = cv2.cvtColor(rgb, cv2.COLOR_RGB2BGR) if rgb.ndim == 3 else rgb
    ok, buf = cv2.imencode(".jpg", bgr, [cv2.IMWRITE_JPEG_QUALITY, quality])
    if not ok:
        raise ValueError(f"cannot encode a {rgb.dtype.name} {rgb.shape} image as JPEG")
    return buf.tobytes()
