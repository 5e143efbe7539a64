"""Simulated frames -> messages: RGBDFrame, transforms and PeopleGroundTruth."""

from __future__ import annotations

import numpy as np

from common.geometry import PinholeCamera
from common.schemas import (
    CameraInfo,
    Header,
    Image,
    PeopleGroundTruth,
    PersonGroundTruth,
    RGBDFrame,
    Transform,
    TransformBatch,
)
from common.poses import quaternion_from_matrix
from tools.simulator.core.simulation import FrameData

__all__ = ["CAMERA_FRAME", "frame_message", "groundtruth_message", "static_transforms", "tf_message"]

MAP, ODOM, BASE, HEAD, CAMERA_FRAME = "map", "odom", "base_link", "head_link", "camera"


def transform(parent: str, child: str, pose: np.ndarray, stamp_ns: int, static: bool = False) -> Transform:
    """A :class:`Transform` from a (4, 4) T_parent_child."""
    return Transform(
        parent_frame=parent,
        child_frame=child,
        stamp_ns=stamp_ns,
        translation=pose[:3, 3].copy(),
        rotation_xyzw=quaternion_from_matrix(pose[:3, :3]),
        static=static,
    )


def frame_message(fd: FrameData, pinhole: PinholeCamera, stamp_ns: int, camera: str) -> RGBDFrame:
    """The RGB-D frame; RGB, depth and camera info share one header (stamp, seq, source)."""
    header = Header(stamp_ns=stamp_ns, frame_id=CAMERA_FRAME, seq=fd.seq, source=camera)
    info = CameraInfo(
        header=header, width=pinhole.width, height=pinhole.height, K=pinhole.K.copy(), D=np.zeros(5),
        distortion_model="plumb_bob",
    )
    return RGBDFrame(
        header=header,
        rgb=Image.from_array(fd.render.rgb, "rgb8", header),
        depth=Image.from_array(fd.render.depth_mm, "16UC1", header),
        camera_info=info,
    )


def tf_message(fd: FrameData, stamp_ns: int, camera: str, head_moves: bool) -> TransformBatch:
    """map -> odom (drift correction), odom -> base_link, and base_link -> head_link when the head moves."""
    items = [transform(MAP, ODOM, fd.map_odom, stamp_ns), transform(ODOM, BASE, fd.odom_base, stamp_ns)]
    if head_moves:
        items.append(transform(BASE, HEAD, fd.base_head, stamp_ns))
    return TransformBatch(header=Header(stamp_ns=stamp_ns, frame_id=MAP, seq=fd.seq, source=camera), transforms=items)


def static_transforms(fd: FrameData, stamp_ns: int, camera: str, head_moves: bool) -> TransformBatch:
    """head_link -> camera, and base_link -> head_link when the head does not move."""
    items = [] if head_moves else [transform(BASE, HEAD, fd.base_head, stamp_ns, static=True)]
    items.append(transform(HEAD, CAMERA_FRAME, fd.head_camera, stamp_ns, static=True))
    return TransformBatch(header=Header(stamp_ns=stamp_ns, frame_id=BASE, seq=fd.seq, source=camera), transforms=items)


def groundtruth_message(fd: FrameData, stamp_ns: int, camera: str, min_visible: float) -> PeopleGroundTruth:
    """Every person's torso centre in the map, with the visibility rule's verdict."""
    people = [
        PersonGroundTruth(
            id=p.id,
            position=p.position,
            velocity=p.velocity,
            visible_fraction=min(1.0, p.visible_fraction),
            in_view_fraction=min(1.0, p.in_view_fraction),
            counted=p.counted,
            posture=p.posture,  # type: ignore[arg-type]
            height_m=p.height_m,
            clothing=p.clothing.description,
            outfit=p.outfit,
            facing_rad=p.facing_rad,
        )
        for p in fd.people
    ]
    return PeopleGroundTruth(
        header=Header(stamp_ns=stamp_ns, frame_id=MAP, seq=fd.seq, source=camera),
        people=people,
        min_visible=min_visible,
    )
