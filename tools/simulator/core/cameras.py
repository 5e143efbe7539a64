"""Cameras fixed on the robot's base, besides the head camera: where they are mounted.

Each one adds two static frames under ``base_link``: ``{name}_link``, the mount (x along
the optical axis, y left, z up, as ``base_link``), and ``{name}_optical``, the optical
frame (z forward, x right, y down) at the same point. The default is the back camera:
on the rear of the base, 0.95 m above the floor, level, looking backwards (yaw 180 deg).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from common.geometry.poses import OPTICAL_FROM_BODY, make_pose, rot_y, rot_z

__all__ = ["BACK_CAMERA_OFFSET", "FixedCamera", "back_camera"]

#: base_link -> the back camera's mount (m): at the rear edge of the 0.35 m base, 0.95 m up.
BACK_CAMERA_OFFSET = (-0.30, 0.0, 0.95)
#: The mount -> the optical frame: the axes turned, no offset.
_MOUNT_OPTICAL = make_pose(OPTICAL_FROM_BODY, (0.0, 0.0, 0.0))


@dataclass(frozen=True)
class FixedCamera:
    """A camera fixed on the base. ``base_mount`` (4, 4) is T_base_link_mount."""

    name: str
    base_mount: np.ndarray

    @property
    def mount_frame(self) -> str:
        return f"{self.name}_link"

    @property
    def optical_frame(self) -> str:
        """The frame id of its images and camera info."""
        return f"{self.name}_optical"

    @property
    def mount_optical(self) -> np.ndarray:
        """(4, 4) T_mount_optical."""
        return _MOUNT_OPTICAL

    @property
    def base_optical(self) -> np.ndarray:
        """(4, 4) T_base_link_optical."""
        return self.base_mount @ _MOUNT_OPTICAL


def back_camera(
    name: str = "back",
    offset: tuple[float, float, float] = BACK_CAMERA_OFFSET,
    yaw: float = np.pi,
    pitch: float = 0.0,
) -> FixedCamera:
    """A camera at ``offset`` (m, in ``base_link``) turned by ``yaw`` about z (pi: backwards),
    then pitched down by ``pitch`` (rad, positive looks down, as the head's tilt)."""
    return FixedCamera(name, make_pose(rot_z(yaw) @ rot_y(pitch), offset))
