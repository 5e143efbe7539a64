"""Which ROS topic feeds which perception stream.

A :class:`TopicPlan` says, for each topic of a bag, its role (``rgb``, ``depth``,
``camera_info``, ``tf``, ``tf_static``, ``odom``) and camera; the rest is skipped and
listed. :func:`plan_topics` builds it from explicit choices, falling back to the usual
RGB-D driver topic names (openni/freenect, RealSense, Astra).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Literal, Mapping, Sequence

__all__ = ["DEFAULT_TOPICS", "Role", "TopicPlan", "TopicRoute", "parse_remap", "plan_topics", "remap_key"]

Role = Literal["rgb", "depth", "camera_info", "tf", "tf_static", "odom"]
CAMERA_ROLES: tuple[Role, ...] = ("rgb", "depth", "camera_info")

#: Default topic names per role, most preferred first. For the camera roles only the
#: first one present in a bag is used (a bag often holds both raw and rectified images).
DEFAULT_TOPICS: dict[Role, tuple[str, ...]] = {
    "rgb": (
        "/camera/rgb/image_rect_color", "/camera/rgb/image_color", "/camera/rgb/image_raw",
        "/camera/color/image_raw", "/camera/color/image_rect_color",
        "/camera/rgb/image_rect_color/compressed", "/camera/rgb/image_color/compressed",
        "/camera/rgb/image_raw/compressed", "/camera/color/image_raw/compressed",
    ),
    "depth": (
        "/camera/depth_registered/image_raw", "/camera/depth_registered/image",
        "/camera/aligned_depth_to_color/image_raw", "/camera/depth_registered/sw_registered/image_rect_raw",
        "/camera/depth/image_raw", "/camera/depth/image", "/camera/depth/image_rect_raw",
    ),
    "camera_info": ("/camera/rgb/camera_info", "/camera/color/camera_info"),
    "tf": ("/tf",),
    "tf_static": ("/tf_static",),
    "odom": ("/odom", "/odometry/filtered"),
}


@dataclass(frozen=True)
class TopicRoute:
    role: Role
    camera: str = ""


@dataclass
class TopicPlan:
    """``routes``: topic -> route; ``skipped``: topic -> why it is not replayed."""

    routes: dict[str, TopicRoute] = field(default_factory=dict)
    skipped: dict[str, str] = field(default_factory=dict)

    def cameras(self) -> dict[str, dict[Role, str]]:
        """camera -> role -> topic."""
        out: dict[str, dict[Role, str]] = {}
        for topic, route in self.routes.items():
            if route.camera:
                out.setdefault(route.camera, {})[route.role] = topic
        return out


def plan_topics(
    available: Sequence[str],
    cameras: Mapping[str, Mapping[str, str]] | None = None,
    lists: Mapping[str, Sequence[str]] | None = None,
    default_camera: str = "head",
) -> TopicPlan:
    """Route the ``available`` topics.

    ``cameras``: camera -> {"rgb"|"depth"|"camera_info": topic}, explicit choices; a
    camera role left out takes its default topic (only when a single camera is named
    or none). ``lists``: {"tf"|"tf_static"|"odom": [topics]}, explicit lists replacing
    the defaults. Explicit topics missing from the bag are reported in ``skipped``.
    """
    present = set(available)
    plan = TopicPlan()
    chosen_cams = {name: dict(roles) for name, roles in (cameras or {}).items()} or {default_camera: {}}
    fill_defaults = len(chosen_cams) == 1
    for cam, roles in chosen_cams.items():
        for role in CAMERA_ROLES:
            topic = roles.get(role)
            if topic is None and fill_defaults:
                topic = next((t for t in DEFAULT_TOPICS[role] if t in present), None)
            if topic is None:
                continue
            if topic not in present:
                plan.skipped[topic] = f"named for camera {cam!r} {role} but not in the bag"
                continue
            plan.routes[topic] = TopicRoute(role, cam)
    for role in ("tf", "tf_static", "odom"):
        given = (lists or {}).get(role)
        for topic in (given if given is not None else DEFAULT_TOPICS[role]):  # type: ignore[index]
            if topic in present:
                plan.routes[topic] = TopicRoute(role)  # type: ignore[arg-type]
            elif given is not None:
                plan.skipped[topic] = f"named as {role} but not in the bag"
    for topic in sorted(present - plan.routes.keys()):
        alt = next((r for r, names in DEFAULT_TOPICS.items() if topic in names), None)
        plan.skipped[topic] = (f"another {alt} topic is used" if alt in CAMERA_ROLES
                               else "no stream mapped (use --topic-map or the --*-topic flags)")
    return plan


def parse_remap(rule: str) -> tuple[str, str]:
    """``"OLD=NEW"`` -> ``(OLD, NEW)``; raises ValueError naming the rule."""
    old, sep, new = rule.partition("=")
    old, new = old.strip().strip("/"), new.strip().strip("/")
    if not sep or not old or not new or any(c in old + new for c in "*$?#"):
        raise ValueError(f"remap rule {rule!r} must be OLD=NEW with two key expressions without wildcards")
    return old, new


def remap_key(key: str, rules: Sequence[tuple[str, str]]) -> str:
    """Apply the first rule whose OLD is ``key`` or a leading part of it (whole chunks)."""
    for old, new in rules:
        if key == old:
            return new
        if key.startswith(old + "/"):
            return new + key[len(old):]
    return key
