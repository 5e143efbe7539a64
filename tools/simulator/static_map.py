"""The simulated apartment's static map as a file, as a robot's map saver would write it."""

from __future__ import annotations

from pathlib import Path

from common.geometry.map_file import OccupancyGrid, write_map
from tools.simulator.core.apartment import Apartment, default_apartment
from tools.simulator.core.laser_map import MAP_RESOLUTION_M, laser_map

__all__ = ["write_apartment_map"]


def write_apartment_map(path: Path, apartment: Apartment | None = None) -> Path:
    """Write ``apartment``'s (the scenarios' apartment by default) laser map as a ROS map: ``path``
    (YAML) and its PGM image beside it, in the map frame; returns the image's path."""
    occupied, unknown, origin = laser_map(apartment or default_apartment())
    return write_map(path, OccupancyGrid(occupied, unknown, MAP_RESOLUTION_M, origin))
