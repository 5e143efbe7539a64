"""The simulated apartment's static map as a file, as a robot's map saver would write it."""

from __future__ import annotations

from pathlib import Path

from common.geometry.map_file import OccupancyGrid, write_map
from common.geometry.messages import static_map_from_grid
from common.messages.schemas import Header, StaticMap
from tools.simulator.core.apartment import Apartment, default_apartment
from tools.simulator.core.laser_map import MAP_RESOLUTION_M, laser_map
from tools.simulator.messages import MAP

__all__ = ["apartment_static_map", "write_apartment_map"]


def write_apartment_map(path: Path, apartment: Apartment | None = None) -> Path:
    """Write ``apartment``'s (the scenarios' apartment by default) laser map as a ROS map: ``path``
    (YAML) and its PGM image beside it, in the map frame; returns the image's path."""
    occupied, unknown, origin = laser_map(apartment or default_apartment())
    return write_map(path, OccupancyGrid(occupied, unknown, MAP_RESOLUTION_M, origin))


def apartment_static_map(stamp_ns: int, apartment: Apartment | None = None) -> StaticMap:
    """``apartment``'s laser map as a :class:`StaticMap` in the map frame, what the simulated ROS 2
    robot's map server publishes on ``/map`` (100 occupied, 0 free, -1 unknown)."""
    occupied, unknown, origin = laser_map(apartment or default_apartment())
    return static_map_from_grid(OccupancyGrid(occupied, unknown, MAP_RESOLUTION_M, origin),
                                Header(stamp_ns=stamp_ns, frame_id=MAP, source="simulator"))
