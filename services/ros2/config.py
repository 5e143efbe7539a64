"""Ros2Config: the ROS 2 node's settings. The default topic names are the RealSense ROS 2
driver's (``realsense2_camera``, namespace and name ``camera``); any other driver's are settings."""

from __future__ import annotations

import os
from typing import Any, Literal

from pydantic import ConfigDict, field_validator, model_validator

from common.messages.keys import validate_chunk
from common.runtime.settings import AdvancedBlock, setting

from services.ros2.core.types import DISTROS

__all__ = ["Ros2Config"]


def _domain_from_env() -> int:
    text = os.environ.get("ROS_DOMAIN_ID", "").strip()
    if not text:
        return 0
    if not text.isdigit() or int(text) > 232:
        raise ValueError(f"ROS_DOMAIN_ID={text!r} is not a ROS 2 domain (0-232)")
    return int(text)


def _topic(v: str) -> str:
    if not v:
        return v
    if not v.startswith("/") or "//" in v or v.endswith("/") or any(c in v for c in " *$?#%"):
        raise ValueError(f"{v!r} is not an absolute ROS 2 topic name like /camera/color/image_raw")
    if any(t[:1].isdigit() for t in v.strip("/").split("/")):
        raise ValueError(f"{v!r}: a ROS 2 name token cannot start with a digit")
    return v


#: The laser a bare scan topic feeds: the one ``perception laser`` reads by default.
DEFAULT_LASER = "front"


def _scans(v: Any) -> list[str]:
    """``scans`` as ``TOPIC:NAME`` items: from a list of ``TOPIC[:NAME]`` (a bare topic is laser
    front), a mapping ``{TOPIC: NAME}`` or one comma-separated text; every topic and name once."""
    if isinstance(v, dict):
        items = [f"{k}:{n}" for k, n in v.items()]
    elif isinstance(v, str):
        items = [t.strip() for t in v.split(",") if t.strip()]
    elif isinstance(v, (list, tuple)):
        items = [str(t).strip() for t in v]
    else:
        raise ValueError(f"{v!r}: give a list of TOPIC[:NAME] (e.g. [/scan:front, /rear/scan:rear]) or a mapping "
                         "{TOPIC: NAME}")
    out: list[str] = []
    topics: dict[str, str] = {}
    names: dict[str, str] = {}
    for item in items:
        topic, _, name = item.partition(":")
        name = name.strip() or DEFAULT_LASER
        topic = topic.strip()
        if not topic:
            raise ValueError(f"{item!r}: no topic (write TOPIC[:NAME], e.g. /scan:front)")
        _topic(topic)
        try:
            if ":" in name:
                raise ValueError(f"laser name {name!r} has a ':'")
            validate_chunk(name, "laser name")
        except ValueError as exc:
            raise ValueError(f"{item!r}: {exc}") from None
        if topic in topics:
            raise ValueError(f"{topic} is listed twice ({topics[topic]}, {item}): read each topic once")
        if name in names:
            raise ValueError(f"{names[name]} and {item} both feed scans/{name}: name each laser "
                             f"(e.g. {topic}:rear); a bare topic is laser {DEFAULT_LASER}")
        topics[topic], names[name] = item, item
        out.append(f"{topic}:{name}")
    return out


class Ros2Config(AdvancedBlock):
    """Everything ``perception ros2`` can be told."""

    model_config = ConfigDict(extra="forbid")

    # --- the ROS 2 side
    domain_id: int = setting(description="ROS_DOMAIN_ID of the robot", default_text="$ROS_DOMAIN_ID, else 0",
                             default_factory=_domain_from_env, ge=0, le=232)
    distro: Literal["jazzy", "kilted", "rolling"] = setting("jazzy", "the robot's ROS 2 distribution: the message "
                                                            "definitions and their hashes (Humble's rmw_zenoh writes "
                                                            "no hash and is not supported)")
    node_name: str = setting("people_perception", "the node's name in the ROS 2 graph (ros2 node list)",
                             pattern=r"^[A-Za-z_][A-Za-z0-9_]*$")
    namespace: str = setting("/", "the node's namespace in the ROS 2 graph")

    # --- in: a ROS 2 camera becomes frames/{camera}
    camera_in: bool = setting(True, "read the ROS 2 camera topics and publish frames/{camera}")
    camera: str = setting("head", "this project's camera name (frames/{camera})", min_length=1)
    colour_topic: str = setting("/camera/camera/color/image_raw", "colour images: sensor_msgs/Image (rgb8, bgr8, "
                                "mono8), or CompressedImage")
    colour_compressed: bool = setting(False, "the colour topic carries sensor_msgs/CompressedImage (jpeg or png), "
                                      "e.g. .../image_raw/compressed")
    depth_topic: str = setting("/camera/camera/aligned_depth_to_color/image_raw", "depth registered to the colour image: "
                               "16UC1 (mm) or 32FC1 (m); '' for an RGB-only camera")
    depth_compressed: bool = setting(False, "the depth topic carries CompressedImage (16-bit png, compressedDepth)")
    camera_info_topic: str = setting("/camera/camera/color/camera_info", "the colour camera's sensor_msgs/CameraInfo")
    slop_s: float = setting(0.05, "colour and depth pair when their stamps are this close (approximate time)",
                            unit="s", gt=0.0, le=1.0, advanced=True)
    pair_wait_s: float = setting(0.5, "a colour image waits this long for its depth image", unit="s", gt=0.0, le=10.0, advanced=True)
    require_depth: bool = setting(True, "drop a colour image with no depth image near it (else publish it alone)")
    image_queue: int = setting(4, "ROS images kept per topic while the node is busy", ge=1, le=64, advanced=True)

    # --- in: /tf and /tf_static become tf and tf_static
    tf_in: bool = setting(True, "read /tf and /tf_static (transient local: a late joiner gets the static transforms "
                          "from rmw_zenoh's publisher cache)")
    tf_topic: str = setting("/tf", "the ROS 2 transforms, tf2_msgs/TFMessage")
    tf_static_topic: str = setting("/tf_static", "the ROS 2 static transforms (transient local)")
    map_topic: str = setting("/map", "the robot's map, nav_msgs/OccupancyGrid (transient local: Nav2's map_server, "
                             "slam_toolbox) -> static_map, for the tracker; '' for none")
    map_period_s: float = setting(5.0, "the map received is re-sent on static_map this often, for late joiners",
                                  unit="s", gt=0.0, le=600.0, advanced=True)

    # --- in: 2-D laser scans become scans/{laser}
    scans: list[str] = setting(
        default_factory=lambda: [f"/scan:{DEFAULT_LASER}"],
        description="2-D laser scans, sensor_msgs/LaserScan: each TOPIC:NAME -> scans/NAME, for perception laser "
                    "(a bare TOPIC is laser front; a mapping {TOPIC: NAME} is read too); [] for none")

    # --- out: the people as ROS 2 topics
    people_out: bool = setting(True, "publish the tracker's people as ROS4HRI topics, /tf frames and RViz markers")
    humans_namespace: str = setting("/humans", "ROS4HRI's root (REP 155)")
    markers_topic: str = setting("/humans/markers", "RViz markers of the people, visualization_msgs/MarkerArray")
    body_prefix: str = setting("p", "a body's ID is this plus the track ID (ROS names cannot start with a digit)",
                               pattern=r"^[A-Za-z][A-Za-z0-9_]*$")
    body_frames: bool = setting(True, "a body_<id> frame per person on /tf")
    static_period_s: float = setting(1.0, "the static transforms received are re-sent on tf_static this often, for "
                                     "this project's late joiners", unit="s", gt=0.0, le=60.0, advanced=True)
    include_coasting: bool = setting(False, "also publish tracks coasting through a short occlusion (else confirmed "
                                     "only)")
    marker_lifetime_s: float = setting(2.0, "markers vanish after this if the node stops (0: never)",
                                       unit="s", ge=0.0, le=60.0, advanced=True)
    queue: int = setting(256, "tracks kept while the node is busy", ge=1, advanced=True)
    log_every_s: float = setting(1.0, "a recurring input problem is logged at most this often", unit="s", gt=0.0, advanced=True)

    @field_validator("colour_topic", "depth_topic", "camera_info_topic", "tf_topic", "tf_static_topic", "map_topic",
                     "markers_topic", "humans_namespace")
    @classmethod
    def _topics(cls, v: str) -> str:
        return _topic(v)

    @field_validator("scans", mode="before")
    @classmethod
    def _scan_topics(cls, v: Any) -> list[str]:
        return _scans(v)

    def scan_topics(self) -> list[tuple[str, str]]:
        """(ROS topic, laser name) of each scan topic read."""
        return [(topic, name) for topic, _, name in (item.partition(":") for item in self.scans)]

    @field_validator("namespace")
    @classmethod
    def _namespace(cls, v: str) -> str:
        return "/" if v in ("", "/") else _topic(v)

    @field_validator("distro")
    @classmethod
    def _distro(cls, v: str) -> str:
        if v not in DISTROS:
            raise ValueError(f"distro {v!r} is not one of {', '.join(DISTROS)}")
        return v

    @model_validator(mode="after")
    def _something_to_do(self) -> Ros2Config:
        if not (self.camera_in or self.tf_in or self.people_out or self.scans):
            raise ValueError("nothing to do: camera_in, tf_in and people_out are all off and scans is empty")
        if self.camera_in and not (self.colour_topic and self.camera_info_topic):
            raise ValueError("camera_in needs colour_topic and camera_info_topic (or turn camera_in off)")
        if self.camera_in and self.require_depth and not self.depth_topic:
            raise ValueError("require_depth needs depth_topic; for an RGB-only camera set require_depth: false")
        return self
