"""The tracker service and the robot's map: from the static_map stream (the ros2 node's /map) or
from a map file, no track is born on its walls; a map in another frame is counted, not used."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from common.geometry.map_file import OccupancyGrid, write_map
from common.messages.keys import MAPS
from common.messages.schemas import Header, StaticMap
from common.transport.memory import MemoryBus
from services.tracker.config import TrackerConfig
from tests.helpers.tracker_rig import KEYS, T0, Rig, config

RES = 0.05
#: A wall along x = 2.0-2.1 m, y 0-2 m, on a 4 x 3 m grid from (0, 0).
OCCUPIED = np.zeros((60, 80), bool)
OCCUPIED[0:40, 40:42] = True
JAMB, PERSON = (1, (1.98, 1.0, 1.0)), (0, (1.0, 1.0, 1.0))


def grid_message(frame_id: str = "map", stamp: int = T0) -> StaticMap:
    cells = np.where(OCCUPIED, 100, 0).astype(np.int8)
    return StaticMap(header=Header(stamp_ns=stamp, frame_id=frame_id, source="ros2"), resolution=RES, width=80,
                     height=60, origin=(0.0, 0.0, 0.0), data=cells.tobytes())


def confirmed_x(rig: Rig, n: int) -> set[float]:
    xs: set[float] = set()
    for msg in rig.walk(T0, n, [PERSON, JAMB]):
        xs |= {round(float(t.position[0]), 1) for t in msg.tracks}
    return xs


def test_the_map_on_the_stream_keeps_tracks_off_its_walls(tmp_path: Path, memory_bus: MemoryBus) -> None:
    rig = Rig(config(tmp_path), memory_bus)
    maps = memory_bus.transport().publisher(KEYS.static_map(), StaticMap, MAPS)
    for _ in range(3):  # the ros2 node sends it again every few seconds: taken once
        maps.put(grid_message())
    assert confirmed_x(rig, 12) == {1.0}
    assert rig.extra["static_maps"] == 1 and rig.extra["births_on_obstacles"] >= 12
    assert "static_map stream" in rig.service.describe()


def test_without_a_map_the_jamb_becomes_a_track(tmp_path: Path, memory_bus: MemoryBus) -> None:
    assert confirmed_x(Rig(config(tmp_path), memory_bus), 12) == {1.0, 2.0}


def test_a_map_in_another_frame_is_counted_and_not_used(tmp_path: Path, memory_bus: MemoryBus) -> None:
    rig = Rig(config(tmp_path), memory_bus)
    memory_bus.transport().publisher(KEYS.static_map(), StaticMap, MAPS).put(grid_message("odom"))
    assert confirmed_x(rig, 12) == {1.0, 2.0}
    assert rig.extra["static_map_wrong_frame"] == 1 and "static_maps" not in rig.extra


def test_a_map_file_wins_over_the_stream(tmp_path: Path, memory_bus: MemoryBus) -> None:
    path = tmp_path / "map.yaml"
    write_map(path, OccupancyGrid(OCCUPIED, np.zeros_like(OCCUPIED), RES, (0.0, 0.0, 0.0)))
    cfg = TrackerConfig.model_validate({**config(tmp_path).model_dump(), "robust": {"static_map": {"path": str(path)}}})
    rig = Rig(cfg, memory_bus)
    assert rig.service.map_sub is None and f"static map {path}" in rig.service.describe()
    assert confirmed_x(rig, 12) == {1.0}
    assert "static_maps" not in rig.extra


def test_the_thesis_profile_has_no_birth_map(tmp_path: Path, memory_bus: MemoryBus) -> None:
    rig = Rig(config(tmp_path, profile="thesis"), memory_bus)
    memory_bus.transport().publisher(KEYS.static_map(), StaticMap, MAPS).put(grid_message())
    assert confirmed_x(rig, 12) == {1.0, 2.0}  # Pinto's thesis exactly: the map changes nothing
