"""A stand-in detector backend with known output, for the detector service's tests."""

from __future__ import annotations

import threading

import numpy as np

__all__ = ["FixedDetector"]


class FixedDetector:
    """Two boxes per frame; optionally blocks in ``detect`` until released (a slow model)."""

    name = "fixed"
    needs_depth = False
    postures = ("standing", "sitting")  # the posture of each of the two boxes
    depths = (2.5, 4.0)  # each box's person's own depth (m), as the depth detector measures it
    statures = (1.78, float("nan"))  # the standing one's stature (m); the seated one has none

    def __init__(self, block_first: bool = False) -> None:
        self.entered = threading.Event()
        self.release = threading.Event()
        if not block_first:
            self.release.set()
        self.calls = 0

    def detect(self, rgb: np.ndarray, depth: np.ndarray | None = None,
               camera: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
        self.calls += 1
        self.entered.set()
        assert self.release.wait(30.0), "test never released the detector"
        boxes = np.array([[10, 20, 50, 120], [200, 40, 260, 200]], np.float32)
        return boxes, np.array([0.9, 0.6], np.float32)
