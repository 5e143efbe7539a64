"""Poses as plain 4x4 homogeneous matrices built from elementary rotations.

Convention (ROS TF, as in :mod:`common.geometry.transforms`): ``T_a_b`` maps points expressed in
frame ``b`` into frame ``a`` (``p_a = T_a_b @ p_b``), so ``T_a_c = T_a_b @ T_b_c``.

These complement :class:`common.geometry.transforms.RigidTransform` where results must be
reproducible bit for bit: that class holds a scipy ``Rotation`` (a quaternion), and a
pose that goes through it comes back different in the last bits for most poses (its
inverse and its quaternion too). The simulator builds its robot, head and camera poses
with these, so its frames, ground truth and messages are identical for a seed.
"""

from __future__ import annotations

import numpy as np

__all__ = [
    "OPTICAL_FROM_BODY",
    "make_pose",
    "pose_inverse",
    "quaternion_from_matrix",
    "rot_x",
    "rot_y",
    "rot_z",
    "planar_pose",
]


def rot_x(a: float) -> np.ndarray:
    """(3, 3) rotation by ``a`` radians about x."""
    c, s = np.cos(a), np.sin(a)
    return np.array([[1.0, 0.0, 0.0], [0.0, c, -s], [0.0, s, c]])


def rot_y(a: float) -> np.ndarray:
    """(3, 3) rotation by ``a`` radians about y."""
    c, s = np.cos(a), np.sin(a)
    return np.array([[c, 0.0, s], [0.0, 1.0, 0.0], [-s, 0.0, c]])


def rot_z(a: float) -> np.ndarray:
    """(3, 3) rotation by ``a`` radians about z."""
    c, s = np.cos(a), np.sin(a)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


#: Rotation from a camera's optical frame (z forward, x right, y down) into the body
#: frame it is mounted on (x forward, y left, z up): ``p_body = OPTICAL_FROM_BODY @ p_optical``.
OPTICAL_FROM_BODY = np.array([[0.0, 0.0, 1.0], [-1.0, 0.0, 0.0], [0.0, -1.0, 0.0]])


def make_pose(rotation: np.ndarray, translation: np.ndarray | tuple[float, float, float]) -> np.ndarray:
    """(4, 4) homogeneous transform from a (3, 3) rotation and a (3,) translation."""
    pose = np.eye(4)
    pose[:3, :3] = rotation
    pose[:3, 3] = translation
    return pose


def planar_pose(x: float, y: float, yaw: float, z: float = 0.0) -> np.ndarray:
    """(4, 4) pose of a frame at (x, y, z) rotated by ``yaw`` about z."""
    return make_pose(rot_z(yaw), (x, y, z))


def pose_inverse(pose: np.ndarray) -> np.ndarray:
    """Inverse of a (4, 4) rigid transform."""
    inv = np.eye(4)
    r = pose[:3, :3]
    inv[:3, :3] = r.T
    inv[:3, 3] = -r.T @ pose[:3, 3]
    return inv


def quaternion_from_matrix(r: np.ndarray) -> np.ndarray:
    """Unit quaternion (x, y, z, w), w >= 0, of a (3, 3) rotation matrix."""
    m = np.asarray(r, dtype=np.float64)
    t = np.trace(m)
    if t > 0.0:
        s = 2.0 * np.sqrt(t + 1.0)
        q = np.array([(m[2, 1] - m[1, 2]) / s, (m[0, 2] - m[2, 0]) / s, (m[1, 0] - m[0, 1]) / s, 0.25 * s])
    else:
        i = int(np.argmax(np.diag(m)))
        j, k = (i + 1) % 3, (i + 2) % 3
        s = 2.0 * np.sqrt(1.0 + m[i, i] - m[j, j] - m[k, k])
        q = np.empty(4)
        q[i] = 0.25 * s
        q[j] = (m[j, i] + m[i, j]) / s
        q[k] = (m[k, i] + m[i, k]) / s
        q[3] = (m[k, j] - m[j, k]) / s
    q /= np.linalg.norm(q)
    return -q if q[3] < 0 else q
