"""Camera: is the camera info plausible, is depth registered to the colour image, in which
unit is it really, and how much of it is valid."""

from __future__ import annotations

import numpy as np

from tools.doctor.core.facts import Check, FrameFacts, Observation

__all__ = ["camera_checks", "depth_values"]

SECTION = "Camera"
#: A 16UC1 median below this many "millimetres" is metres stored as integers.
MM_MIN = 20.0
#: A 32FC1 median above this many "metres" is millimetres stored as floats.
M_MAX = 30.0
#: Plausible median depth of a room, metres.
ROOM_M = (0.3, 15.0)
#: Valid depth share below FAIL fails, below WARN warns.
VALID_FAIL, VALID_WARN = 0.2, 0.5


def _size(hw: tuple[int, int] | None) -> str:
    return f"{hw[1]}x{hw[0]}" if hw else "?"


def depth_values(frames: list[FrameFacts]) -> tuple[np.ndarray, int]:
    """(valid raw depth values (N,) float64, how many were sampled) over ``frames``."""
    samples = [f.depth_sample for f in frames if f.depth_sample is not None and f.depth_sample.size]
    if not samples:
        return np.zeros(0), 0
    values = np.concatenate(samples)
    return values[np.isfinite(values) & (values > 0)], values.size


def _info(f: FrameFacts, cam: str) -> Check:
    name = f"camera info ({cam})"
    if f.K is None:
        return Check(SECTION, name, "fail", "no camera info in the frames", "send the camera info with every frame")
    K = np.asarray(f.K, dtype=np.float64)
    if K.shape != (3, 3) or not np.all(np.isfinite(K)):
        return Check(SECTION, name, "fail", f"K is not a finite 3x3 matrix: {K.tolist()}",
                     "send K = [fx 0 cx; 0 fy cy; 0 0 1] from the camera's calibration")
    if not np.any(K):
        return Check(SECTION, name, "fail", "K is all zeros (an uncalibrated camera info)",
                     "send the camera's calibration in the camera info: K = [fx 0 cx; 0 fy cy; 0 0 1] "
                     "(the driver's calibration file)")
    fx, fy, cx, cy = K[0, 0], K[1, 1], K[0, 2], K[1, 2]
    if fx <= 0 or fy <= 0 or not np.allclose(K[2], [0.0, 0.0, 1.0]):
        return Check(SECTION, name, "fail", f"K is not a pinhole matrix (fx {fx:g}, fy {fy:g}, last row {K[2].tolist()})",
                     "send K = [fx 0 cx; 0 fy cy; 0 0 1] with positive focal lengths")
    if f.info_hw is not None and f.rgb_hw is not None and f.info_hw != f.rgb_hw:
        return Check(SECTION, name, "fail", f"camera info is {_size(f.info_hw)}, the image {_size(f.rgb_hw)}",
                     "send the camera info of the resolution you stream (or scale K with the image)")
    figure = f"{_size(f.rgb_hw)}, fx {fx:.1f} fy {fy:.1f}, cx {cx:.1f} cy {cy:.1f}"
    if f.rgb_hw is not None and not (0 <= cx <= f.rgb_hw[1] and 0 <= cy <= f.rgb_hw[0]):
        return Check(SECTION, name, "warn", figure + ": the principal point lies outside the image",
                     "check the calibration: cx, cy are usually near the image centre")
    return Check(SECTION, name, "ok", figure)


def _registration(f: FrameFacts, cam: str) -> Check:
    name = f"depth registered ({cam})"
    if f.depth_hw is None:
        return Check(SECTION, name, "fail", "the frames carry no depth image",
                     "enable the camera's depth stream, registered to the colour image (the localizer needs it)")
    if f.depth_hw != f.rgb_hw:
        return Check(SECTION, name, "fail", f"depth {_size(f.depth_hw)}, colour {_size(f.rgb_hw)}: not registered",
                     "register depth to the colour camera (the driver's depth_registration / align_depth option) "
                     "and send that depth image")
    return Check(SECTION, name, "ok", f"depth {_size(f.depth_hw)} = colour")


def _unit(frames: list[FrameFacts], cam: str) -> Check:
    name = f"depth unit ({cam})"
    enc = frames[-1].depth_encoding
    valid, _ = depth_values(frames)
    if not valid.size:
        return Check(SECTION, name, "warn", f"{enc or 'no depth'}: no valid pixel to judge by", "see the valid depth line")
    med = float(np.median(valid))
    if enc == "32FC1":
        if med > M_MAX:
            return Check(SECTION, name, "fail", f"32FC1 (float metres) whose median is {med:.0f}: millimetres stored as "
                         "floats", "divide the depth by 1000 (32FC1 is metres), or send uint16 millimetres as 16UC1")
        metres, unit = med, "(float metres)"
    else:
        if med < MM_MIN:
            return Check(SECTION, name, "fail", f"{enc} (uint16 millimetres) whose median is {med:g}: metres stored as "
                         "integers", "multiply by 1000 before converting to uint16, or send float metres as 32FC1")
        metres, unit = med / 1000.0, "(uint16 millimetres)"
    figure = f"{enc} {unit}, median {metres:.2f} m"
    if not ROOM_M[0] <= metres <= ROOM_M[1]:
        return Check(SECTION, name, "warn", figure + ": unusual for a room",
                     "check the depth scale (the localizer's depth_unit_m for 16UC1)")
    return Check(SECTION, name, "ok", figure)


def _valid(frames: list[FrameFacts], cam: str) -> Check:
    name = f"valid depth ({cam})"
    valid, total = depth_values(frames)
    if total == 0:
        return Check(SECTION, name, "fail", "no depth pixels", "enable the camera's depth stream")
    share = valid.size / total
    figure = f"{share:.0%} of the depth pixels"
    if share < VALID_WARN:
        return Check(SECTION, name, "fail" if share < VALID_FAIL else "warn", figure,
                     "most depth is missing: a scene out of the sensor's range, a covered or misaligned depth "
                     "sensor, or an exposure problem")
    return Check(SECTION, name, "ok", figure)


def camera_checks(obs: Observation) -> list[Check]:
    """Four lines per camera, judged on the frames sampled (the latest for shapes)."""
    out = []
    for cam in obs.cameras():
        frames = obs.frames.get(cam, [])
        if not frames:
            out.append(Check(SECTION, f"camera ({cam})", "fail", f"no frame on frames/{cam} in {obs.duration_s:.1f} s",
                             f"start the camera driver publishing frames/{cam}"))
            continue
        latest = frames[-1]
        if latest.rgb_hw is None:
            out.append(Check(SECTION, f"camera ({cam})", "fail", f"frames cannot be read: {latest.error}",
                             "send RGBDFrame messages of this project's schema (perception replay converts ROS bags)"))
            continue
        if latest.depth_hw is None and cam in obs.floor_cameras:
            out += [_info(latest, cam), Check(SECTION, f"depth registered ({cam})", "ok",
                                              "no depth, none needed: placed on the floor by its homography")]
            continue
        out += [_info(latest, cam), _registration(latest, cam)]
        if latest.depth_hw is not None:
            out += [_unit(frames, cam), _valid(frames, cam)]
    return out
