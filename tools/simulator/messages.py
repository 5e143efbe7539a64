"""Simulated frames -> messages: RGBDFrame, transforms and PeopleGroundTruth."""

from __future__ import annotations

import numpy as np

from common.geometry.transforms import PinholeCamera
from common.messages.schemas import (
    CameraInfo,
    Header,
    Image,
    LaserScan,
    PeopleGroundTruth,
    PersonGroundTruth,
    RGBDFrame,
    Transform,
    TransformBatch,
)
from common.geometry.poses import quaternion_from_matrix
from tools.simulator.core.render import RenderResult
from tools.simulator.core.simulation import BaseLaser, FixedView, FrameData, ScanData

__all__ = [
    "CAMERA_FRAME",
    "FRAME_NAMES",
    "fixed_frame_message",
    "frame_message",
    "groundtruth_message",
    "scan_message",
    "static_transforms",
    "tf_message",
]

MAP, ODOM, BASE, HEAD, CAMERA_FRAME = "map", "odom", "base_link", "head_link", "camera"
#: The frames of the robot without its fixed cameras; a fixed camera's frames must differ.
FRAME_NAMES = (MAP, ODOM, BASE, HEAD, CAMERA_FRAME)


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


def _rgbd(render: RenderResult, pinhole: PinholeCamera, header: Header) -> RGBDFrame:
    info = CameraInfo(
        header=header, width=pinhole.width, height=pinhole.height, K=pinhole.K.copy(), D=np.zeros(5),
        distortion_model="plumb_bob",
    )
    return RGBDFrame(
        header=header,
        rgb=Image.from_array(render.rgb, "rgb8", header),
        depth=Image.from_array(render.depth_mm, "16UC1", header),
        camera_info=info,
    )


def frame_message(fd: FrameData, pinhole: PinholeCamera, stamp_ns: int, camera: str) -> RGBDFrame:
    """The head camera's RGB-D frame; RGB, depth and camera info share one header (stamp, seq, source)."""
    return _rgbd(fd.render, pinhole, Header(stamp_ns=stamp_ns, frame_id=CAMERA_FRAME, seq=fd.seq, source=camera))


def fixed_frame_message(view: FixedView, seq: int, pinhole: PinholeCamera, stamp_ns: int) -> RGBDFrame:
    """A fixed camera's RGB-D frame: source = its name, frame id = its optical frame."""
    cam = view.camera
    return _rgbd(view.render, pinhole, Header(stamp_ns=stamp_ns, frame_id=cam.optical_frame, seq=seq, source=cam.name))


def tf_message(fd: FrameData, stamp_ns: int, camera: str, head_moves: bool) -> TransformBatch:
    """map -> odom (drift correction), odom -> base_link, and base_link -> head_link when the head moves."""
    items = [transform(MAP, ODOM, fd.map_odom, stamp_ns), transform(ODOM, BASE, fd.odom_base, stamp_ns)]
    if head_moves:
        items.append(transform(BASE, HEAD, fd.base_head, stamp_ns))
    return TransformBatch(header=Header(stamp_ns=stamp_ns, frame_id=MAP, seq=fd.seq, source=camera), transforms=items)


def static_transforms(fd: FrameData, stamp_ns: int, camera: str, head_moves: bool,
                      laser: BaseLaser | None = None) -> TransformBatch:
    """head_link -> camera, base_link -> head_link when the head does not move, for each
    fixed camera base_link -> {name}_link -> {name}_optical, and base_link -> the laser's frame."""
    items = [] if head_moves else [transform(BASE, HEAD, fd.base_head, stamp_ns, static=True)]
    items.append(transform(HEAD, CAMERA_FRAME, fd.head_camera, stamp_ns, static=True))
    for view in fd.views.values():
        cam = view.camera
        items.append(transform(BASE, cam.mount_frame, cam.base_mount, stamp_ns, static=True))
        items.append(transform(cam.mount_frame, cam.optical_frame, cam.mount_optical, stamp_ns, static=True))
    if laser is not None:
        items.append(transform(BASE, laser.frame, laser.mount, stamp_ns, static=True))
    return TransformBatch(header=Header(stamp_ns=stamp_ns, frame_id=BASE, seq=fd.seq, source=camera), transforms=items)


def groundtruth_message(fd: FrameData, stamp_ns: int, camera: str, min_visible: float) -> PeopleGroundTruth:
    """Every person's torso centre in the map, with the visibility rule's verdict. With fixed
    cameras, a person counts when any camera sees enough of them, and the fractions are the
    largest of the cameras'."""
    views = list(fd.views.values())
    people = [
        PersonGroundTruth(
            id=p.id,
            position=p.position,
            velocity=p.velocity,
            visible_fraction=min(1.0, max([p.visible_fraction, *(float(v.visible[k]) for v in views)])),
            in_view_fraction=min(1.0, max([p.in_view_fraction, *(float(v.in_view[k]) for v in views)])),
            counted=p.counted or any(bool(v.counted[k]) for v in views),
            posture=p.posture,  # type: ignore[arg-type]
            height_m=p.height_m,
            clothing=p.clothing.description,
            outfit=p.outfit,
            facing_rad=p.facing_rad,
            laser_seen=p.laser_seen,
        )
        for k, p in enumerate(fd.people)
    ]
    return PeopleGroundTruth(
        header=Header(stamp_ns=stamp_ns, frame_id=MAP, seq=fd.seq, source=camera),
        people=people,
        min_visible=min_visible,
    )


def scan_message(scan: ScanData, seq: int, stamp_ns: int) -> LaserScan:
    """The base laser's sweep as its driver publishes it: frame id the laser's, 0 for no return
    (a Hokuyo's), the first beam at ``stamp_ns``."""
    spec, a = scan.laser.spec, scan.laser.spec.angles()
    return LaserScan(header=Header(stamp_ns=stamp_ns, frame_id=scan.laser.frame, seq=seq, source=scan.laser.name),
                     angle_min=float(a[0]), angle_max=float(a[-1]), angle_increment=float(a[1] - a[0]),
                     time_increment=0.0,  # simulated: every beam at the frame's instant
                     scan_time=1.0 / spec.rate_hz, range_min=spec.range_min, range_max=spec.range_max,
                     ranges=scan.ranges)
