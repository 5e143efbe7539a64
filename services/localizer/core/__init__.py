"""The localizer's pure core: numpy, scipy and cv2 only (no messages, no transport, no I/O)."""

from services.localizer.core.floor import (
    REJECT_ABOVE_HORIZON,
    REJECT_BEYOND_RANGE,
    REJECT_CAMERA_BELOW_FLOOR,
    REJECT_FOOT_OUTSIDE_IMAGE,
    FloorParams,
    foot_points,
    localize_on_floor,
)
from services.localizer.core.homography import (
    MISMATCH_TOLERANCE,
    FloorHomography,
    HomographyPose,
    camera_pose_from_homography,
    homography_from_camera,
    homography_in_frame,
    localize_on_floor_homography,
)
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
    "MISMATCH_TOLERANCE",
    "REJECT_ABOVE_HORIZON",
    "REJECT_BEYOND_RANGE",
    "REJECT_CAMERA_BELOW_FLOOR",
    "REJECT_EMPTY_BOX",
    "REJECT_FOOT_OUTSIDE_IMAGE",
    "REJECT_INVALID_BOX",
    "REJECT_OUTSIDE_IMAGE",
    "REJECT_TOO_FEW_PIXELS",
    "DepthNoiseModel",
    "FloorHomography",
    "FloorParams",
    "HomographyPose",
    "Localization",
    "LocalizerParams",
    "box_depths",
    "camera_pose_from_homography",
    "foot_points",
    "homography_from_camera",
    "homography_in_frame",
    "localize",
    "localize_on_floor",
    "localize_on_floor_homography",
    "point_covariances",
]
