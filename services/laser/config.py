"""LaserConfig: the laser node's settings."""

from __future__ import annotations

from pathlib import Path

from pydantic import ConfigDict, field_validator

from common.geometry.map_file import load_obstacles
from common.geometry.occupancy import ObstacleMap
from common.messages.keys import validate_chunk
from common.runtime.settings import AdvancedBlock, setting
from services.laser.core.legs import LegParams

__all__ = ["LaserConfig"]

#: The core's defaults: written once, in the core.
_D = LegParams()


class LaserConfig(AdvancedBlock):
    """Everything ``perception laser`` can be told (file section ``laser``)."""

    model_config = ConfigDict(extra="forbid")

    laser: str = setting("front", "scanner name in the keys: reads scans/{laser}, publishes localized/{laser}")
    target_frame: str = setting("map", "frame the people are published in", min_length=1)
    laser_frame: str = setting("", "the scanner's frame id when its scans carry none")
    model: Path | None = setting(None, "a leg classifier written by 'perception train-legs'; None: the one shipped "
                                 "in the package (trained on Leigh et al.'s labelled scans)")
    min_probability: float = setting(0.2, "a person's least probability (that a leg of theirs is a leg) to be "
                                     "published", ge=0.0, lt=1.0)
    max_range_m: float = setting(_D.max_range_m, "legs farther than this from the scanner are left out", unit="m",
                                 gt=0.0, le=100.0)
    static_map: Path | None = setting(None, "the robot's static map, a ROS map_server / Nav2 map_saver YAML file in "
                                      "target_frame (--static-map); None: the static_map stream's (perception ros2 "
                                      "passes /map on)")
    map_clearance_m: float = setting(0.1, "people this close to an obstacle of the static map (a wall, furniture "
                                     "drawn on the map) are left out; 0: keep them", unit="m", ge=0.0, le=2.0)
    person_z_m: float = setting(0.9, "the height the people are published at, above floor_z_m: a 2-D scan does "
                                "not measure it (the body centre, as the localizer's floor paths)", unit="m",
                                ge=0.0, le=3.0)
    person_z_sigma_m: float = setting(0.15, "standard deviation of that height", unit="m", gt=0.0, le=2.0,
                                      advanced=True)
    floor_z_m: float = setting(0.0, "height of the floor in target_frame", unit="m", ge=-100.0, le=100.0,
                               advanced=True)
    leg_min_probability: float = setting(_D.min_probability, "a segment's least leg probability to count as a leg",
                                         ge=0.0, lt=1.0, advanced=True)
    pair_m: float = setting(_D.pair_m, "two legs closer than this are one person", unit="m", gt=0.0, le=3.0,
                            advanced=True)
    pair_sigma_m: float = setting(_D.pair_sigma_m, "a pair's position sigma (plus the legs' own spread)", unit="m",
                                  gt=0.0, le=2.0, advanced=True)
    lone_sigma_m: float = setting(_D.lone_sigma_m, "a lone leg's position sigma (the other leg is hidden)",
                                  unit="m", gt=0.0, le=2.0, advanced=True)
    join_m: float = setting(_D.join_m, "two beams' points closer than this are one segment (Leigh et al.)",
                            unit="m", gt=0.0, le=1.0, advanced=True)
    min_points: int = setting(_D.min_points, "segments of fewer beams are dropped", ge=1, le=100, advanced=True)
    max_width_m: float = setting(_D.max_width_m, "wider segments are never legs", unit="m", gt=0.0, le=5.0,
                                 advanced=True)
    tf_history_s: float = setting(10.0, "history kept per transform edge", unit="s", gt=0.0, le=3600.0, advanced=True)
    tf_tolerance_s: float = setting(0.05, "a lookup this far outside an edge's history uses its end",
                                    unit="s", ge=0.0, le=10.0, advanced=True)
    transform_wait_s: float = setting(0.25, "how long a scan waits for its transform before being dropped",
                                      unit="s", ge=0.0, le=10.0, advanced=True)
    max_pending: int = setting(32, "scans waiting for their transform at most (the oldest is dropped)", ge=1,
                               le=10000, advanced=True)

    @field_validator("laser")
    @classmethod
    def _chunk(cls, v: str) -> str:
        return validate_chunk(v, "laser")

    def obstacles(self) -> ObstacleMap | None:
        """The static map's obstacles from ``static_map`` (None: none given; MapFileError names the fix)."""
        return None if self.static_map is None else load_obstacles(self.static_map)

    def params(self) -> LegParams:
        return LegParams(join_m=self.join_m, min_points=self.min_points, max_width_m=self.max_width_m,
                         max_range_m=self.max_range_m, min_probability=self.leg_min_probability, pair_m=self.pair_m,
                         pair_sigma_m=self.pair_sigma_m, lone_sigma_m=self.lone_sigma_m)
