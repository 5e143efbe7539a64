"""Camera views for the tracker's tests (:class:`~services.tracker.core.view.FieldOfView`)."""

from __future__ import annotations

import numpy as np

from services.tracker.core.view import FieldOfView


def camera_looking_along_x() -> FieldOfView:
    """A 640x480 camera at the origin looking along +x (camera z = x, camera x = -y, camera y = -z)."""
    m = np.eye(4)
    m[:3, :3] = np.array([[0.0, 0.0, 1.0], [-1.0, 0.0, 0.0], [0.0, -1.0, 0.0]])
    return FieldOfView(m, np.array([[500.0, 0, 320], [0, 500.0, 240], [0, 0, 1]]), 640, 480, 8.0)


def turned_round(fov: FieldOfView) -> FieldOfView:
    """``fov``'s camera turned round (looking the other way): what it saw is behind it."""
    flip = np.array([[-1.0, 0, 0, 0], [0, 1, 0, 0], [0, 0, -1.0, 0], [0, 0, 0, 1]])
    return FieldOfView(fov.camera_to_frame @ flip, fov.K, 640, 480, 8.0)
