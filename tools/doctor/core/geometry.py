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

from tools.doctor.core.facts import Check, EdgeFacts, Observation

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
    parents: dict[str, EdgeFacts] = {e.child: e for e in obs.edges}
    chain = []
    frame = camera_frame
    while frame in parents and len(chain) < 8:
        e = parents[frame]
        chain.append(f"{e.parent} → {e.child}")
        frame = e.parent
    return " or ".join(chain[:2]) if chain else f"the transforms above {camera_frame!r}"


def geometry_checks(obs: Observation) -> list[Check]:
    if len(obs.people) < MIN_PEOPLE:
        return []
    z = np.array([p[0] for p in obs.people])
    d = np.array([p[1] for p in obs.people])
    camera = max({p[2] for p in obs.people}, key=lambda c: sum(p[2] == c for p in obs.people))
    where = _mount(obs, camera)
    name = f"people's height ({camera})"
    median = float(np.median(z))
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
    if median < 0:
        return [Check(SECTION, name, "fail", f"people are {-median:.2f} m below the floor (median of {len(z)})",
                      f"the camera's transform {where} is wrong: its height, or a camera mounted upside down")]
    if not PLAUSIBLE_M[0] <= median <= PLAUSIBLE_M[1]:
        off = median - CENTRE_M
        return [Check(SECTION, name, "fail",
                      f"people's centres are {median:.2f} m above the floor (a standing person's is near {CENTRE_M} m; "
                      f"median of {len(z)})",
                      f"the camera's height in {where} looks {off:+.2f} m off: measure the mount")]
    return [Check(SECTION, name, "ok", f"median {median:.2f} m above the floor, {slope:+.2f} m per m of distance "
                                       f"({len(z)} people)")]
