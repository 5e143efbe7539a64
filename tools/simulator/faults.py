"""Setup mistakes the simulator can make on purpose, to see what ``perception doctor`` says.

Each fault is one classic way a robot's camera driver or transform tree is set up wrong.
:func:`apply_faults` rewrites one simulated frame's messages accordingly. The faults that
break a message's own rules (a depth image of another size, a zero ``K``) build it without
validation, exactly as a misconfigured driver would send it: receivers refuse it as an
invalid payload.
"""

from __future__ import annotations

import numpy as np

from common.messages.keys import Keys
from common.messages.schemas import CameraInfo, Image, Message, RGBDFrame, Transform, TransformBatch

__all__ = ["FAULTS", "MOUNT_ERROR_M", "OLD_STAMPS_S", "apply_faults"]

#: mount-high: how much higher the head's mount is said to be than it is.
MOUNT_ERROR_M = 0.5
#: mount-pitched: how far the camera's mount is said to be pitched off.
PITCH_ERROR_DEG = 30.0

#: How far ``old-stamps`` puts the stamps in the past (s).
OLD_STAMPS_S = 5.0

#: Fault name -> what it does.
FAULTS: dict[str, str] = {
    "depth-float-mm": "depth as 32FC1 (float) holding millimetres instead of metres",
    "depth-half-size": "depth at half the colour image's width and height (not registered)",
    "zero-k": "camera info with an all-zero K",
    "no-odom-edge": "no odom -> base_link transform",
    "static-once": "static transforms published with the first frame only",
    "old-stamps": f"every stamp {OLD_STAMPS_S:g} s in the past (an unsynchronised clock)",
    "mount-high": f"the head's mount on tf_static {MOUNT_ERROR_M:g} m higher than it is",
    "mount-pitched": f"the camera's mount on tf_static pitched {PITCH_ERROR_DEG:g} degrees off",
    "mount-upside-down": "the camera's mount on tf_static rolled 180 degrees (a camera mounted upside down)",
}


def _frame(frame: RGBDFrame, faults: frozenset[str]) -> RGBDFrame:
    rgb, depth, info = frame.rgb, frame.depth, frame.camera_info
    if depth is not None and "depth-float-mm" in faults:
        mm = depth.to_array().astype(np.float32)
        depth = Image.from_array(mm, "32FC1", depth.header)
    if depth is not None and "depth-half-size" in faults:
        half = np.ascontiguousarray(depth.to_array()[::2, ::2])
        depth = Image.model_construct(header=depth.header, encoding=depth.encoding, dtype=depth.dtype,
                                      shape=half.shape, data=half.tobytes())
    if "zero-k" in faults:
        info = CameraInfo.model_construct(header=info.header, width=info.width, height=info.height,
                                          K=np.zeros((3, 3)), D=info.D, distortion_model=info.distortion_model)
    if depth is frame.depth and info is frame.camera_info:
        return frame
    return RGBDFrame.model_construct(header=frame.header, rgb=rgb, depth=depth, camera_info=info)


def _misrotated(t: Transform, faults: frozenset[str]) -> Transform:
    """The camera's mount (head_link -> camera) with a wrong pitch (about the head's y axis) or a
    roll of 180 degrees about the optical axis."""
    from scipy.spatial.transform import Rotation

    if t.parent_frame != "head_link":
        return t
    rot = Rotation.from_quat(t.rotation_xyzw)
    if "mount-pitched" in faults:
        rot = Rotation.from_euler("y", PITCH_ERROR_DEG, degrees=True) * rot
    if "mount-upside-down" in faults:
        rot = rot * Rotation.from_euler("z", 180.0, degrees=True)
    return t.model_copy(update={"rotation_xyzw": rot.as_quat()})


def apply_faults(pairs: list[tuple[str, Message]], faults: frozenset[str], keys: Keys,
                 seq: int) -> list[tuple[str, Message]]:
    """Frame ``seq``'s (key, message) pairs with ``faults`` applied (``old-stamps`` is applied
    to the stream's start time instead, see :class:`tools.simulator.source.SimulatedStream`)."""
    if not faults:
        return pairs
    out: list[tuple[str, Message]] = []
    for key, msg in pairs:
        if key == keys.tf_static() and "static-once" in faults and seq > 0:
            continue
        if key == keys.tf_static() and "mount-high" in faults and isinstance(msg, TransformBatch):
            raised = [t.model_copy(update={"translation": t.translation + [0.0, 0.0, MOUNT_ERROR_M]})
                      if (t.parent_frame, t.child_frame) == ("base_link", "head_link") else t for t in msg.transforms]
            msg = msg.model_copy(update={"transforms": raised})
        if key == keys.tf_static() and faults & {"mount-pitched", "mount-upside-down"} and isinstance(msg, TransformBatch):
            msg = msg.model_copy(update={"transforms": [_misrotated(t, faults) for t in msg.transforms]})
        if key == keys.tf() and "no-odom-edge" in faults and isinstance(msg, TransformBatch):
            kept = [t for t in msg.transforms if (t.parent_frame, t.child_frame) != ("odom", "base_link")]
            msg = msg.model_copy(update={"transforms": kept})
        if isinstance(msg, RGBDFrame):
            msg = _frame(msg, faults)
        out.append((key, msg))
    return out
