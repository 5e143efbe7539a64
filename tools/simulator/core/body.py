"""People as articulated solids: head, neck, torso, shoulders, pelvis, arms, legs and feet as
ellipsoids, posed standing, walking or sitting, dressed in a :class:`Clothing`.

Person frame: origin on the floor under the pelvis, x forward, y left, z up.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from common.geometry.poses import rot_x, rot_y, rot_z

__all__ = ["Clothing", "Ellipsoids", "PersonPose", "body_ellipsoids", "torso_centre"]

Colour = tuple[float, float, float]


@dataclass(frozen=True)
class Clothing:
    """What a person wears: RGB albedos in [0, 1]; ``pattern`` 'plain' or 'stripes' (on the top)."""

    top: Colour
    bottom: Colour
    pattern: str = "plain"
    stripe: Colour = (0.95, 0.95, 0.95)
    long_sleeves: bool = True
    shoes: Colour = (0.12, 0.1, 0.09)
    skin: Colour = (0.8, 0.62, 0.5)
    hair: Colour = (0.2, 0.14, 0.1)
    description: str = ""


@dataclass(frozen=True)
class PersonPose:
    """Where a person is and how: (x, y) on the floor, heading ``yaw``, posture, gait phase (rad),
    gait amplitude in [0, 1] (0 = standing still) and seat height when sitting."""

    x: float
    y: float
    yaw: float
    posture: str = "standing"  # or "sitting"
    phase: float = 0.0
    gait: float = 0.0
    seat_height: float = 0.45


@dataclass
class Ellipsoids:
    """A batch of N coloured ellipsoids in the map frame.

    centres (N, 3); inv (N, 3, 3) maps map-frame offsets into the unit sphere
    (``u = inv @ (p - centre)``); radius (N,) bounding-sphere radii; colour (N, 3) albedo;
    stripe (N, 3) second colour, stripe_period (N,) metres (0 = plain); owner (N,) int person index.
    """

    centres: np.ndarray
    inv: np.ndarray
    radius: np.ndarray
    colour: np.ndarray
    stripe: np.ndarray
    stripe_period: np.ndarray
    owner: np.ndarray
    tips: np.ndarray

    @staticmethod
    def concat(items: list[Ellipsoids]) -> Ellipsoids:
        if not items:
            z3 = np.zeros((0, 3))
            return Ellipsoids(z3, np.zeros((0, 3, 3)), np.zeros(0), z3, z3, np.zeros(0), np.zeros(0, np.int32), z3)
        return Ellipsoids(
            *(
                np.concatenate([getattr(e, f) for e in items])
                for f in ("centres", "inv", "radius", "colour", "stripe", "stripe_period", "owner", "tips")
            )
        )

    def sample_points(self, owner: int) -> np.ndarray:
        """(3 K, 3) points inside person ``owner``'s solids: each centre and 70 % towards both ends."""
        sel = self.owner == owner
        c, tip = self.centres[sel], self.tips[sel]
        return np.concatenate([c, c + 0.7 * tip, c - 0.7 * tip])


def _limb(
    joint: np.ndarray, direction_rot: np.ndarray, length: float, radius: float
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Centre, rotation and radii of a limb hanging from ``joint`` along ``direction_rot @ (0, 0, -1)``."""
    centre = joint + direction_rot @ np.array([0.0, 0.0, -length / 2.0])
    return centre, direction_rot, np.array([radius, radius, length / 2.0 + radius * 0.3])


def _parts(height: float, pose: PersonPose) -> list[tuple[str, np.ndarray, np.ndarray, np.ndarray, str]]:
    """(name, centre (3,), rotation (3, 3), radii (3,), colour slot) in the person frame."""
    h, s = height, height / 1.75
    thigh, shin, ankle = 0.245 * h, 0.215 * h, 0.04 * h
    eye = np.eye(3)
    sitting = pose.posture == "sitting"
    hip_z = max(pose.seat_height + 0.06, shin + ankle) if sitting else 0.5 * h
    dz = hip_z - 0.5 * h  # the upper body moves with the hips
    up = lambda z: np.array([0.0, 0.0, z + dz])  # noqa: E731
    parts = [
        ("head", up(h - 0.115 * s), eye, np.array([0.095, 0.078, 0.115]) * s, "skin"),
        ("hair", up(h - 0.085 * s) + np.array([-0.012, 0, 0]), eye, np.array([0.094, 0.081, 0.09]) * s, "hair"),
        ("neck", up(0.845 * h), eye, np.array([0.05, 0.05, 0.06]) * s, "skin"),
        ("torso", up(0.68 * h), eye, np.array([0.115, 0.175, 0.27]) * s, "top"),
        ("shoulders", up(0.795 * h), eye, np.array([0.105, 0.215, 0.075]) * s, "top"),
        ("pelvis", up(0.525 * h), eye, np.array([0.11, 0.165, 0.1]) * s, "bottom"),
    ]
    swing = 0.45 * pose.gait * np.sin(pose.phase)
    for side, sign in (("l", 1.0), ("r", -1.0)):
        shoulder = up(0.81 * h) + np.array([0.0, sign * 0.2 * s, 0.0])
        arm_swing = -sign * swing * 0.7
        upper_rot = rot_y(-arm_swing) @ rot_x(sign * 0.08)  # slightly away from the body
        c, r, rad = _limb(shoulder, upper_rot, 0.186 * h, 0.048 * s)
        parts.append((f"upper-arm-{side}", c, r, rad, "top"))
        elbow = shoulder + upper_rot @ np.array([0.0, 0.0, -0.186 * h])
        fore_bend = 1.3 if sitting else 0.15 + 0.25 * pose.gait * max(0.0, -sign * np.sin(pose.phase))
        c, r, rad = _limb(elbow, rot_y(-arm_swing - fore_bend), 0.24 * h, 0.04 * s)
        parts.append((f"forearm-{side}", c, r, rad, "sleeve"))
        hip = np.array([0.0, sign * 0.09 * s, hip_z])
        if sitting:
            thigh_rot = rot_y(-np.pi / 2)
            knee = hip + np.array([thigh, 0.0, 0.0])
            shin_rot = rot_y(-0.1)
        else:
            leg_swing = sign * swing
            thigh_rot = rot_y(-leg_swing)
            knee = hip + thigh_rot @ np.array([0.0, 0.0, -thigh])
            shin_rot = rot_y(-leg_swing + 0.5 * pose.gait * max(0.0, np.sin(pose.phase * sign + 1.2)))
        c, r, rad = _limb(hip, thigh_rot, thigh, 0.075 * s)
        parts.append((f"thigh-{side}", c, r, rad, "bottom"))
        c, r, rad = _limb(knee, shin_rot, shin, 0.055 * s)
        parts.append((f"shin-{side}", c, r, rad, "bottom"))
        ankle_p = knee + shin_rot @ np.array([0.0, 0.0, -shin])
        foot_c = np.array([ankle_p[0] + 0.06 * s, ankle_p[1], max(ankle_p[2] - 0.01, 0.04 * s)])
        parts.append((f"foot-{side}", foot_c, eye, np.array([0.12, 0.05, 0.04]) * s, "shoes"))
    return parts


def torso_centre(height: float, pose: PersonPose) -> np.ndarray:
    """(3,) map-frame centre of the torso: the point the ground truth reports."""
    sitting = pose.posture == "sitting"
    shin, ankle = 0.215 * height, 0.04 * height
    hip_z = max(pose.seat_height + 0.06, shin + ankle) if sitting else 0.5 * height
    return np.array([pose.x, pose.y, 0.68 * height + hip_z - 0.5 * height])


def body_ellipsoids(height: float, pose: PersonPose, clothing: Clothing, owner: int) -> Ellipsoids:
    """The person's solids in the map frame (see :class:`Ellipsoids`)."""
    parts = _parts(height, pose)
    yaw_rot = rot_z(pose.yaw)
    origin = np.array([pose.x, pose.y, 0.0])
    n = len(parts)
    centres = np.empty((n, 3))
    inv = np.empty((n, 3, 3))
    radius = np.empty(n)
    colour = np.empty((n, 3))
    stripe = np.zeros((n, 3))
    period = np.zeros(n)
    tips = np.empty((n, 3))
    slots = {
        "skin": clothing.skin,
        "hair": clothing.hair,
        "top": clothing.top,
        "bottom": clothing.bottom,
        "shoes": clothing.shoes,
        "sleeve": clothing.top if clothing.long_sleeves else clothing.skin,
    }
    for i, (name, c, r, radii, slot) in enumerate(parts):
        rot = yaw_rot @ r
        centres[i] = origin + yaw_rot @ c
        inv[i] = np.diag(1.0 / radii) @ rot.T
        radius[i] = float(radii.max())
        tips[i] = rot[:, int(np.argmax(radii))] * radii.max()
        colour[i] = slots[slot]
        if clothing.pattern == "stripes" and slot in ("top", "sleeve") and slots[slot] == clothing.top:
            stripe[i] = clothing.stripe
            period[i] = 0.12 * height / 1.75
    return Ellipsoids(centres, inv, radius, colour, stripe, period, np.full(n, owner, np.int32), tips)
