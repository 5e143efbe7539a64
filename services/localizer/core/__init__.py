"""The localizer's pure core: numpy, scipy and cv2 only (no messages, no transport, no I/O)."""

from services.localizer.core.localize import (
    REJECT_EMPTY_BOX,
    REJECT_INVALID_BOX,
    REJECT_OUTSIDE_IMAGE,
    REJECT_TOO_FEW_PIXELS,
    Localization,
    LocalizerParams,
    box_depths,
    localize,
)
from services.localizer.core.noise import DepthNoiseModel, point_covariances

__all__ = [
    "REJECT_EMPTY_BOX",
    "REJECT_INVALID_BOX",
    "REJECT_OUTSIDE_IMAGE",
    "REJECT_TOO_FEW_PIXELS",
    "DepthNoiseModel",
    "Localization",
    "LocalizerParams",
    "box_depths",
    "localize",
    "point_covariances",
]
