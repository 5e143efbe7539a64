"""The topic map of a ROS bag replay: which topics feed which perception streams.

A YAML file (``--topic-map``), for example::

    cameras:
      head:                       # camera name: frames go to .../frames/head
        rgb: /camera/rgb/image_color
        depth: /camera/depth_registered/image_raw
        camera_info: /camera/rgb/camera_info
    tf: [/tf]
    tf_static: [/tf_static]
    odom: [/odom]                 # nav_msgs/Odometry -> transform odom -> base_link on tf
    lasers:                       # laser name: sensor_msgs/LaserScan go to .../scans/{name}
      front: /scan
      rear: /rear_scan
    pair_tolerance_ms: 20

The ``--rgb-topic``/``--depth-topic``/... flags override the file for the camera named
by ``--camera``; ``--scan-topic TOPIC[=NAME]`` names lasers over the file's. Anything left
out takes the defaults of :data:`tools.replay.core.mapping.DEFAULT_TOPICS` (lasers: every
laser scan topic, ``/scan`` as ``front``, see :func:`tools.replay.core.mapping.plan_topics`).
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

from pydantic import ConfigDict, field_validator

from common.runtime.settings import AdvancedBlock, setting

from common.runtime.config import ConfigError, load_config
from common.messages.keys import validate_chunk

__all__ = ["CameraTopics", "TopicMapConfig", "load_topic_map"]


def _topic(v: str | None) -> str | None:
    if v is not None and not v.startswith("/"):
        raise ValueError(f"topic {v!r} must start with '/'")
    return v


class CameraTopics(AdvancedBlock):
    model_config = ConfigDict(extra="forbid")

    rgb: str | None = setting(None, "sensor_msgs/Image or CompressedImage colour topic")
    depth: str | None = setting(None, "sensor_msgs/Image depth topic (16UC1 mm or 32FC1 m)")
    camera_info: str | None = setting(None, "sensor_msgs/CameraInfo of the colour camera")

    @field_validator("rgb", "depth", "camera_info")
    @classmethod
    def _check(cls, v: str | None) -> str | None:
        return _topic(v)


class TopicMapConfig(AdvancedBlock):
    model_config = ConfigDict(extra="forbid")

    cameras: dict[str, CameraTopics] = setting(description="per camera name (frames/{name}): its rgb, depth and "
                                               "camera_info topics", default_factory=dict)
    tf: list[str] | None = setting(None, "tf2_msgs/TFMessage topics replayed on tf; none: the default topics")
    tf_static: list[str] | None = setting(None, "topics replayed on tf_static; none: the default topics")
    odom: list[str] | None = setting(None, "nav_msgs/Odometry topics replayed on tf as odom -> base_link; none: the "
                                     "default topics")
    lasers: dict[str, str] | None = setting(None, "per laser name (scans/{name}): its sensor_msgs/LaserScan topic; "
                                            "none: every LaserScan topic, /scan (or /base_scan) as front, the others "
                                            "by their names (/rear_scan: rear); {}: no scans")
    pair_tolerance_ms: float = setting(20.0, "largest stamp difference of paired colour and depth images",
                                       unit="ms", gt=0.0, le=1000.0)

    @field_validator("cameras")
    @classmethod
    def _camera_names(cls, v: dict[str, CameraTopics]) -> dict[str, CameraTopics]:
        for name in v:
            validate_chunk(name, "camera name")
        return v

    @field_validator("lasers")
    @classmethod
    def _lasers(cls, v: dict[str, str] | None) -> dict[str, str] | None:
        seen: dict[str, str] = {}
        for name, topic in (v or {}).items():
            validate_chunk(name, "laser name")
            _topic(topic)
            if topic.strip("/") in seen:
                raise ValueError(f"topic {topic!r} is named for lasers {seen[topic.strip('/')]!r} and {name!r}")
            seen[topic.strip("/")] = name
        return v

    @field_validator("tf", "tf_static", "odom")
    @classmethod
    def _topics(cls, v: list[str] | None) -> list[str] | None:
        for t in v or []:
            _topic(t)
        return v

    def camera_dict(self) -> dict[str, dict[str, str]]:
        return {name: {k: t for k, t in cam.model_dump().items() if t} for name, cam in self.cameras.items()}

    def list_dict(self) -> dict[str, list[str]]:
        return {k: v for k, v in (("tf", self.tf), ("tf_static", self.tf_static), ("odom", self.odom)) if v is not None}


def load_topic_map(path: Path | None, camera: str, flags: dict[str, Any]) -> TopicMapConfig:
    """File, then flags (``rgb``/``depth``/``camera_info`` for ``camera``, ``tf``... lists,
    ``scan``: (topic, laser) pairs added to the file's lasers, replacing any of the same name
    or topic)."""
    cfg = load_config(TopicMapConfig, path)
    cam_flags = {k: flags.get(k) for k in ("rgb", "depth", "camera_info") if flags.get(k)}
    data = cfg.model_dump()
    if cam_flags:
        data["cameras"].setdefault(camera, {}).update(cam_flags)
    for k in ("tf", "tf_static", "odom"):
        if flags.get(k):
            data[k] = flags[k]
    if flags.get("scan"):
        given: dict[str, str] = {}
        for topic, name in flags["scan"]:
            if name in given:
                raise ConfigError(f"--scan-topic: laser {name!r} is named for {given[name]} and {topic}")
            given[name] = topic
        topics = {t.strip("/") for t in given.values()}
        kept = {n: t for n, t in (data["lasers"] or {}).items() if n not in given and t.strip("/") not in topics}
        data["lasers"] = {**kept, **given}
    if flags.get("pair_tolerance_ms") is not None:
        data["pair_tolerance_ms"] = flags["pair_tolerance_ms"]
    return load_config(TopicMapConfig, None, overrides=data)
