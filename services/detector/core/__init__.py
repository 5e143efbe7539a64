"""The detector's pure core: every backend behind ``detect(rgb, depth=None, camera=None)``.

No Zenoh, no pydantic messages, no I/O beyond reading model files at construction.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Protocol

import numpy as np

from services.detector.core.boxes import DetectorError

__all__ = ["Detector", "DetectorError"]


class Detector(Protocol):
    """A person detector.

    ``detect`` takes ``rgb`` (H, W, 3) uint8 RGB, optionally ``depth`` (H, W) float32
    metres registered to ``rgb`` (NaN = invalid) and ``camera`` (3, 3) float64
    intrinsics K, and returns ``(boxes (N, 4) float32 xyxy pixels, scores (N,)
    float32 in [0, 1])``, best score first. ``postures``: the posture each of the last
    detections showed ("standing", "sitting"), empty for a backend that cannot tell.
    ``depths``: each of the last detections' own depth (m) measured from the person's points,
    empty for a backend that has none (the localizer then reads the depth in the box).
    ``statures``: each of the last detections' stature (m, the top of a standing person above
    the floor; NaN where not seen), empty for a backend that cannot measure it.
    """

    name: str
    needs_depth: bool
    postures: Sequence[str]
    depths: Sequence[float]
    statures: Sequence[float]

    def detect(self, rgb: np.ndarray, depth: np.ndarray | None = None,
               camera: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]: ...
