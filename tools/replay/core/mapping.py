"""Which ROS topic feeds which perception stream.

A :class:`TopicPlan` says, for each topic of a bag, its role (``rgb``, ``depth``,
``camera_info``, ``tf``, ``tf_static``, ``odom``, ``scan``) and camera or laser; the rest is
skipped and listed. :func:`plan_topics` builds it from explicit choices, falling back to the
usual RGB-D driver topic names (openni/freenect, RealSense, Astra) and, for 2-D lasers, to every
laser scan topic: ``/scan`` (or ``/base_scan``) is the ``front`` laser, any other is named after
its topic (:func:`laser_name`: ``/rear_scan`` -> ``rear``).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Literal, Mapping, Sequence

__all__ = ["DEFAULT_LASER", "DEFAULT_TOPICS", "FRONT_SCAN_TOPICS", "Role", "TopicPlan", "TopicRoute", "laser_name",
           "parse_remap", "parse_scan_topic", "plan_topics", "remap_key"]

Role = Literal["rgb", "depth", "camera_info", "tf", "tf_static", "odom", "scan"]
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

#: The laser a robot's only (or main) scanner feeds, as the laser node reads by default.
DEFAULT_LASER = "front"
#: The usual names of a robot's main 2-D laser (ROS's ``/scan``; PR2, Fetch and Stage's
#: ``/base_scan``): the first present feeds :data:`DEFAULT_LASER`.
FRONT_SCAN_TOPICS: tuple[str, ...] = ("/scan", "/base_scan")
_CHUNK_CHARS = set("abcdefghijklmnopqrstuvwxyzABCDEFGHIJKLMNOPQRSTUVWXYZ0123456789_-.")


@dataclass(frozen=True)
class TopicRoute:
    role: Role
    camera: str = ""
    #: the laser of a ``scan`` route: its scans go to ``scans/{laser}``
    laser: str = ""


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

    def lasers(self) -> dict[str, str]:
        """laser -> its scan topic."""
        return {route.laser: topic for topic, route in self.routes.items() if route.role == "scan"}


def laser_name(topic: str) -> str:
    """The laser a scan topic is named after, as a ROS user reads it: ``/scan`` and
    ``/base_scan`` -> ``front``; ``/rear_scan``, ``/scan_rear``, ``/rear/scan`` -> ``rear``;
    ``/sick/scan_filtered`` -> ``sick_filtered``. Characters a key chunk cannot hold become ``_``."""
    if "/" + topic.strip("/") in FRONT_SCAN_TOPICS:
        return DEFAULT_LASER
    parts = [p for p in topic.strip("/").split("/") if p and p != "scan"]
    words = "_".join(parts).split("_")
    name = "_".join(w for w in words if w and w != "scan")
    name = "".join(c if c in _CHUNK_CHARS else "_" for c in name).strip("_")
    return name or DEFAULT_LASER


def parse_scan_topic(rule: str) -> tuple[str, str]:
    """``"TOPIC"`` or ``"TOPIC=NAME"`` (``--scan-topic``) -> ``(TOPIC, NAME)``, NAME defaulting
    to :func:`laser_name`; raises ValueError naming the rule."""
    topic, sep, name = rule.partition("=")
    topic, name = topic.strip(), name.strip()
    if not topic.strip("/") or (sep and not name) or any(c not in _CHUNK_CHARS for c in name):
        raise ValueError(f"scan topic {rule!r} must be TOPIC or TOPIC=NAME, NAME a laser name such as 'rear' "
                         "(letters, digits, '_', '-', '.')")
    return topic if topic.startswith("/") else "/" + topic, name or laser_name(topic)


def _present(topic: str, present: set[str]) -> str | None:
    """The bag's spelling of ``topic``: as named, or without/with its leading '/' (ROS 1 bags hold
    relative names such as ``right_scan``)."""
    for t in (topic, topic.lstrip("/"), "/" + topic.lstrip("/")):
        if t in present:
            return t
    return None


def plan_topics(
    available: Sequence[str],
    cameras: Mapping[str, Mapping[str, str]] | None = None,
    lists: Mapping[str, Sequence[str]] | None = None,
    default_camera: str = "head",
    lasers: Mapping[str, str] | None = None,
    laser_topics: Sequence[str] = (),
) -> TopicPlan:
    """Route the ``available`` topics.

    ``cameras``: camera -> {"rgb"|"depth"|"camera_info": topic}, explicit choices; a
    camera role left out takes its default topic (only when a single camera is named
    or none). ``lists``: {"tf"|"tf_static"|"odom": [topics]}, explicit lists replacing
    the defaults. ``lasers``: laser -> scan topic, explicit choices replacing the default,
    which routes every topic of ``laser_topics`` (those that carry laser scans): the first
    of :data:`FRONT_SCAN_TOPICS` present to ``front``, any other to its :func:`laser_name`
    (a name taken already: skipped). Explicit topics missing from the bag are reported in
    ``skipped``.
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
    _plan_lasers(plan, present, lasers, laser_topics)
    for topic in sorted(present - plan.routes.keys() - plan.skipped.keys()):
        alt = next((r for r, names in DEFAULT_TOPICS.items() if topic in names), None)
        plan.skipped[topic] = (f"another {alt} topic is used" if alt in CAMERA_ROLES
                               else "no stream mapped (use --topic-map or the --*-topic flags)")
    return plan


def _plan_lasers(plan: TopicPlan, present: set[str], lasers: Mapping[str, str] | None,
                 laser_topics: Sequence[str]) -> None:
    if lasers is not None:
        for name, topic in lasers.items():
            found = _present(topic, present)
            if found is None:
                plan.skipped[topic] = f"named for laser {name!r} but not in the bag"
            elif found in plan.routes:
                plan.skipped[topic] = f"named for laser {name!r} but already the {plan.routes[found].role} stream"
            else:
                plan.routes[found] = TopicRoute("scan", laser=name)
        for topic in laser_topics:
            if topic in present and topic not in plan.routes:
                plan.skipped[topic] = (f"laser scans not among the lasers named (add --scan-topic "
                                       f"/{topic.lstrip('/')}=NAME)")
        return
    candidates = [t for t in laser_topics if t in present and t not in plan.routes]
    front = next((t for f in FRONT_SCAN_TOPICS for t in candidates if "/" + t.strip("/") == f), None)
    taken: dict[str, str] = {}
    for topic in ([front] if front else []) + sorted(t for t in candidates if t != front):
        name = DEFAULT_LASER if topic == front else laser_name(topic)
        if name in taken:
            plan.skipped[topic] = (f"laser {name!r} is fed by {taken[name]} already "
                                   f"(name it: --scan-topic {topic}=NAME)")
            continue
        taken[name] = topic
        plan.routes[topic] = TopicRoute("scan", laser=name)


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
