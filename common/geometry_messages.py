"""Build :mod:`common.geometry` objects from messages, and messages from them.

Kept apart from :mod:`common.geometry` so that the geometry stays free of pydantic.
"""

from __future__ import annotations

import numpy as np

from common.geometry import PinholeCamera, RigidTransform, TransformBuffer
from common.schemas import CameraInfo, Transform, TransformBatch

__all__ = ["add_batch", "add_transform", "camera_from_info", "rigid_from_msg", "transform_msg"]


def camera_from_info(info: CameraInfo) -> PinholeCamera:
    """The pinhole model of a :class:`CameraInfo` (K, D and distortion model)."""
    return PinholeCamera(
        K=np.asarray(info.K),
        width=info.width,
        height=info.height,
        D=np.asarray(info.D),
        distortion_model=info.distortion_model,
    )


def rigid_from_msg(msg: Transform) -> RigidTransform:
    """The rigid transform of a :class:`Transform` (maps child points into the parent)."""
    return RigidTransform.from_quat(msg.translation, msg.rotation_xyzw)


def transform_msg(parent: str, child: str, stamp_ns: int, tf: RigidTransform, static: bool = False) -> Transform:
    """A :class:`Transform` message of ``tf`` for the edge ``parent -> child``."""
    return Transform(
        parent_frame=parent,
        child_frame=child,
        stamp_ns=stamp_ns,
        translation=tf.translation.copy(),
        rotation_xyzw=tf.quat_xyzw,
        static=static,
    )


def add_transform(buffer: TransformBuffer, msg: Transform, static: bool = False) -> None:
    """Put one message in ``buffer``; static if ``static`` or ``msg.static``."""
    buffer.set_transform(
        msg.parent_frame, msg.child_frame, msg.stamp_ns, rigid_from_msg(msg), static=static or msg.static
    )


def add_batch(buffer: TransformBuffer, batch: TransformBatch, static: bool = False) -> int:
    """Put every transform of ``batch`` in ``buffer``; returns how many were added.

    Raises :class:`common.geometry.FrameTreeError` at the first transform that breaks
    the tree (the ones before it are kept).
    """
    for msg in batch.transforms:
        add_transform(buffer, msg, static)
    return len(batch.transforms)
