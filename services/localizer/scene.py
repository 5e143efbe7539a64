"""A robot scene for the localizer's tests, benchmark and demos: messages plus the true map positions."""

from __future__ import annotations

import numpy as np
from scipy.spatial.transform import Rotation

from common.geometry import PinholeCamera, RigidTransform
from common.geometry_messages import transform_msg
from common.samples import camera_info
from common.schemas import (
    Detection,
    Detections,
    Header,
    Image,
    RGBDFrame,
    TransformBatch,
)
from services.localizer.synthetic import Person, person_box, render_depth

S = 1_000_000_000
T0 = 1_700_000_000 * S
#: base_link -> camera (optical frame: z forward, x right, y down), 1.2 m up, tilted 10 degrees down
BASE_CAMERA = RigidTransform(
    Rotation.from_euler("y", 10, degrees=True) * Rotation.from_quat([-0.5, 0.5, -0.5, 0.5]), np.array([0.1, 0.0, 1.2])
)
MAP_ODOM = RigidTransform(Rotation.from_euler("z", 20, degrees=True), np.array([1.0, -0.5, 0.0]))


def odom_base(stamp_ns: int) -> RigidTransform:
    """The robot drives along x at 0.5 m/s while turning at 0.2 rad/s."""
    t = (stamp_ns - T0) / S
    return RigidTransform(Rotation.from_euler("z", 0.2 * t), np.array([0.5 * t, 0.0, 0.0]))


def camera() -> PinholeCamera:
    info = camera_info(640, 480)
    return PinholeCamera(np.asarray(info.K), 640, 480)


def frame(
    seq: int,
    people: list[Person],
    stamp_ns: int | None = None,
    with_depth: bool = True,
    mm: bool = True,
    frame_id: str = "camera",
) -> RGBDFrame:
    stamp = T0 + seq * S // 30 if stamp_ns is None else stamp_ns
    header = Header(stamp_ns=stamp, frame_id=frame_id, seq=seq, source="head")
    depth_m = render_depth(camera(), people)
    depth = (
        Image.from_array(np.round(depth_m * 1000).astype(np.uint16), "16UC1", header)
        if mm
        else Image.from_array(depth_m, "32FC1", header)
    )
    info = camera_info(640, 480, stamp, frame_id)
    return RGBDFrame(
        header=header,
        rgb=Image.from_array(np.zeros((480, 640, 3), np.uint8), "rgb8", header),
        depth=depth if with_depth else None,
        camera_info=info,
    )


def detections(
    f: RGBDFrame, people: list[Person], extra_boxes: tuple[tuple[float, float, float, float], ...] = ()
) -> Detections:
    boxes: list[tuple[float, float, float, float]] = [_box(person_box(camera(), p)) for p in people]
    boxes += list(extra_boxes)
    return Detections(
        header=f.header,
        image_width=640,
        image_height=480,
        detector="test",
        detections=[Detection(index=i, bbox_xyxy=b, score=0.9) for i, b in enumerate(boxes)],
    )


def _box(b: np.ndarray) -> tuple[float, float, float, float]:
    return (float(b[0]), float(b[1]), float(b[2]), float(b[3]))


def tf_static() -> TransformBatch:
    return TransformBatch(
        header=Header(stamp_ns=T0, source="robot_description"),
        transforms=[transform_msg("base_link", "camera", T0, BASE_CAMERA, static=True)],
    )


def tf(stamp_ns: int) -> TransformBatch:
    return TransformBatch(
        header=Header(stamp_ns=stamp_ns, source="localization"),
        transforms=[
            transform_msg("map", "odom", stamp_ns, MAP_ODOM),
            transform_msg("odom", "base_link", stamp_ns, odom_base(stamp_ns)),
        ],
    )


def map_position(p: Person, stamp_ns: int) -> np.ndarray:
    """Where the body centre of ``p`` truly is in the map at ``stamp_ns``."""
    return (MAP_ODOM @ odom_base(stamp_ns) @ BASE_CAMERA).apply(np.array(p.center))
