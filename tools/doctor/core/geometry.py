"""Geometry: are the people where people can be? A camera whose transform is wrong puts every
person too high, too low, or lower the farther away they are, and nothing else complains.

From the localized people (height above the tracking frame's z = 0, taken as the floor, and the
horizontal distance from the camera), fit height = a + b * distance: a pitch error in the camera's
transform shows as a slope b (atan(b) is about the error), a height error as an offset of a from
a person's centre height (about 0.9 m standing, 0.5-0.7 m seated).
"""

from __future__ import annotations

import math

import numpy as np

from tools.doctor.core.facts import Check, Observation

__all__ = ["geometry_checks"]

SECTION = "Transforms"
#: The centre of a standing person (the localizer's point); seated people are lower.
CENTRE_M = 0.9
#: Heights outside this range are not a person's centre (m above the floor).
PLAUSIBLE_M = (0.35, 1.25)
#: A slope of height against distance beyond this (degrees) is a pitch error.
MAX_PITCH_DEG = 6.0
MIN_PEOPLE = 12


def _mount(obs: Observation, camera_frame: str) -> str:
    """The transform to fix: the first edge above the camera's frame that is not the optical one."""
    parents = obs.parents()
    chain = []
    frame = camera_frame
    while frame in parents and len(chain) < 8:
        e = parents[frame]
        chain.append(f"{e.parent} → {e.child}")
        frame = e.parent
    return " or ".join(chain[:2]) if chain else f"the transforms above {camera_frame!r}"


def _floor_checks(obs: Observation) -> list[Check]:
    """The depth detector's floor against the transforms' (it counts the frames whose depth shows
    no floor where the transforms put it, with both floors' camera height and tilt)."""
    out = []
    camera = next((f.frame_id for frames in obs.frames.values() for f in frames if f.frame_id), "camera")
    for node in obs.running("detector"):
        bad = node.counters.get("floor_disagrees", 0)
        seen = node.counters.get("frames_processed", 0)
        if bad <= 0 or bad < 0.25 * max(seen, 1):
            continue
        g = node.last
        th, tt = g.get("floor_transforms_height_m"), g.get("floor_transforms_tilt_deg")
        dh, dt = g.get("floor_depth_height_m"), g.get("floor_depth_tilt_deg")
        where = _mount(obs, camera)
        figure = f"the depth shows no floor where the transforms put it in {bad:g} of {seen:g} frames"
        if th is not None and tt is not None:
            figure += f": the transforms say the camera is {th:.2f} m up, tilted {tt:.0f}° down"
        if th is not None and tt is not None and dh is not None and dt is not None:
            figure += f"; the depth shows {dh:.2f} m, {dt:.0f}°"
            off = [f"its pitch looks {tt - dt:+.0f}° off"] if abs(tt - dt) > 5 else []
            off += [f"its height {th - dh:+.2f} m off"] if abs(th - dh) > 0.15 else []
            fix = f"the camera's transform {where} is wrong: {' and '.join(off) or 'check it'}; measure the mount"
        else:
            fix = f"the camera's transform {where} (its height or pitch) does not match the floor the camera sees"
        out.append(Check(SECTION, f"floor ({node.service})", "fail", figure, fix))
    return out


def geometry_checks(obs: Observation) -> list[Check]:
    return [*_floor_checks(obs), *_people_checks(obs)]


def _people_checks(obs: Observation) -> list[Check]:
    if len(obs.people) < MIN_PEOPLE:
        return []
    z = np.array([p[0] for p in obs.people])
    d = np.array([p[1] for p in obs.people])
    camera = max({p[2] for p in obs.people}, key=lambda c: sum(p[2] == c for p in obs.people))
    where = _mount(obs, camera)
    name = f"people's height ({camera})"
    median = float(np.median(z))
    up = float(np.median([p[5] for p in obs.people]))
    if up < -0.5:
        return [Check(SECTION, name, "fail",
                      f"the transforms put the image's up {math.degrees(math.acos(max(-1.0, min(1.0, up)))):.0f}° from "
                      f"the world's up, yet {len(z)} upright people were detected in it",
                      f"the camera's transform {where} is rolled 180° (or the camera is mounted upside down and its "
                      "images are not flipped): fix the roll, or flip the images in the driver")]
    slope = 0.0
    if float(np.ptp(d)) > 1.0:
        slope, _ = np.polyfit(d, z, 1)
    pitch = math.degrees(math.atan(float(slope)))
    if abs(pitch) > MAX_PITCH_DEG and float(np.ptp(d)) > 1.0:
        return [Check(SECTION, name, "fail",
                      f"{'lower' if pitch < 0 else 'higher'} the farther they are: {slope:+.2f} m per m of distance "
                      f"(median {median:.2f} m above the floor, {len(z)} people)",
                      f"the camera's pitch in {where} looks {abs(pitch):.0f}° off "
                      f"({'pitched down' if pitch < 0 else 'pitched up'} too little in the transform): measure the mount")]
    cam_h = float(np.median([p[3] for p in obs.people]))
    mirrored = 2 * cam_h - median  # where the people were, if the camera is rolled 180 degrees in the transform
    if median > cam_h + 0.2 and PLAUSIBLE_M[0] <= mirrored <= PLAUSIBLE_M[1]:
        return [Check(SECTION, name, "fail",
                      f"people are above the camera: {median:.2f} m against its {cam_h:.2f} m (median of {len(z)}); "
                      f"mirrored about the camera they would stand at {mirrored:.2f} m",
                      f"the camera looks mounted upside down, or its transform {where} is rolled 180°: "
                      "fix the roll in the transform (or turn the camera)")]
    if median < 0:
        return [Check(SECTION, name, "fail", f"people are {-median:.2f} m below the floor (median of {len(z)})",
                      f"the camera's transform {where} is wrong: its height, or a camera mounted upside down")]
    max_range = float(np.median([p[4] for p in obs.people]))
    far = int(np.sum(d > max_range * 1.05))
    if far > 0.2 * len(d):
        return [Check(SECTION, name, "fail", f"{far} of {len(d)} people are farther than the camera's range "
                                             f"({max_range:.1f} m) on the floor",
                      f"the camera's pose in {where} is wrong (its pitch or height), or the range is set too short")]
    if not PLAUSIBLE_M[0] <= median <= PLAUSIBLE_M[1]:
        off = median - CENTRE_M
        return [Check(SECTION, name, "fail",
                      f"people's centres are {median:.2f} m above the floor (a standing person's is near {CENTRE_M} m; "
                      f"median of {len(z)})",
                      f"the camera's height in {where} looks {off:+.2f} m off: measure the mount")]
    return [Check(SECTION, name, "ok", f"median {median:.2f} m above the floor, {slope:+.2f} m per m of distance "
                                       f"({len(z)} people)")]
