"""The laser node driven through the in-memory transport: scans and transforms in, people out."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from common.messages.keys import MAPS, RELIABLE, SCANS, Keys
from common.messages.schemas import (
    Header,
    LaserScan,
    LocalizedDetections,
    StaticMap,
    Transform,
    TransformBatch,
)
from common.runtime.service import Counters
from common.transport.memory import MemoryBus
from services.laser.config import LaserConfig
from services.laser.service import DETECTOR, LaserService
from tools.simulator.core.laser_scan import LaserSpec, cast, sense

KEYS = Keys()
T0 = 1_700_000_000_000_000_000
SPEC = LaserSpec(sigma_m=0.005, dropout=0.0)
#: the scanner in the map: at (1, 2), 0.2 m up, facing +y
MOUNT = (np.array([1.0, 2.0, 0.2]), np.array([0.0, 0.0, np.sin(np.pi / 4), np.cos(np.pi / 4)]))


class Rig:
    def __init__(self, bus: MemoryBus, **config: object) -> None:
        self.counters = Counters()
        self.service = LaserService(bus.transport(), KEYS, LaserConfig(**config), self.counters)
        client = bus.transport()
        self.scans = client.publisher(KEYS.scans("front"), LaserScan, SCANS)
        self.tf_static = client.publisher(KEYS.tf_static(), TransformBatch, RELIABLE)
        self.map = client.publisher(KEYS.static_map(), StaticMap, MAPS)
        self.out = client.subscribe(KEYS.localized("front"), LocalizedDetections, RELIABLE)

    def mount(self) -> None:
        t, q = MOUNT
        self.tf_static.put(TransformBatch(header=Header(stamp_ns=T0), transforms=[Transform(
            parent_frame="map", child_frame="base_laser", stamp_ns=T0, translation=t, rotation_xyzw=q, static=True)]))


def scan(seq: int, legs_local: list[tuple[float, float]], walls: list[tuple[float, float, float, float]] = (),
         frame: str = "base_laser") -> LaserScan:
    circles = np.array([(x, y, 0.06) for x, y in legs_local]).reshape(-1, 3)
    exact = cast(np.zeros(2), 0.0, SPEC.angles(), np.asarray(walls, float).reshape(-1, 4), circles, SPEC.range_max)
    ranges = sense(exact, SPEC, np.random.default_rng(seq))
    a = SPEC.angles()
    return LaserScan(header=Header(stamp_ns=T0 + seq * 66_000_000, frame_id=frame, seq=seq, source="front"),
                     angle_min=float(a[0]), angle_max=float(a[-1]), angle_increment=float(a[1] - a[0]),
                     time_increment=1e-5, scan_time=1 / 15, range_min=SPEC.range_min, range_max=SPEC.range_max,
                     ranges=ranges)


def to_map(x: float, y: float) -> np.ndarray:
    """A point of the scanner's frame in the map (the scanner faces +y)."""
    return np.array([1.0 - y, 2.0 + x])


def test_people_come_out_in_the_map(memory_bus: MemoryBus) -> None:
    rig = Rig(memory_bus)
    rig.mount()
    # a person 2 m ahead (legs 0.25 m apart) and a wall 4 m ahead
    rig.scans.put(scan(1, [(2.0, -0.125), (2.0, 0.125)], [(4.0, -3.0, 4.2, 3.0)]))
    [msg] = rig.service.poll(0.0)
    assert rig.out.recv(timeout=1.0).msg == msg  # type: ignore[union-attr]
    assert msg.header == Header(stamp_ns=T0 + 66_000_000, frame_id="map", seq=1, source="front")
    assert msg.detector == DETECTOR and msg.camera_frame == "base_laser" and msg.view is None
    [person] = msg.detections
    assert np.linalg.norm(person.position[:2] - to_map(1.95, 0.0)) < 0.08
    assert person.position[2] == pytest.approx(0.9)
    assert person.bbox_xyxy == (0.0, 0.0, 0.0, 0.0) and person.score >= 0.5
    assert person.depth_m == pytest.approx(1.95, abs=0.08) and person.valid_pixels > 10
    assert np.all(np.linalg.eigvalsh(person.cov) > 0)
    assert rig.counters.extra["beams_too_near"] > 0  # the beams that hit nothing read 0


def test_nobody_in_an_empty_corridor(memory_bus: MemoryBus) -> None:
    rig = Rig(memory_bus)
    rig.mount()
    rig.scans.put(scan(2, [], [(3.0, -3.0, 3.2, 3.0), (-3.0, 1.5, 3.0, 1.7), (-3.0, -1.7, 3.0, -1.5)]))
    [msg] = rig.service.poll(0.0)
    assert msg.detections == []


def test_people_on_the_map_s_obstacles_are_left_out(memory_bus: MemoryBus) -> None:
    rig = Rig(memory_bus)
    rig.mount()
    # a map whose cells around the person are occupied (a wrong map, or a coat stand drawn on it)
    res, w, h = 0.05, 100, 100
    cells = np.zeros((h, w), np.int8)
    x, y = to_map(1.95, 0.0)
    cells[int(y / res) - 2:int(y / res) + 3, int(x / res) - 2:int(x / res) + 3] = 100
    rig.map.put(StaticMap(header=Header(stamp_ns=T0, frame_id="map"), resolution=res, width=w, height=h,
                          origin=(0.0, 0.0, 0.0), data=cells.tobytes()))
    rig.scans.put(scan(3, [(2.0, -0.125), (2.0, 0.125)]))
    [msg] = rig.service.poll(0.0)
    assert msg.detections == [] and msg.rejected["legs_on_map"] == 2


def test_a_map_file_s_furniture_is_left_out_and_a_bad_file_is_named(memory_bus: MemoryBus, tmp_path: Path) -> None:
    from common.geometry.map_file import MapFileError, OccupancyGrid, write_map

    occupied = np.zeros((100, 100), bool)
    x, y = to_map(1.95, 0.0)  # a chair's legs where the legs are, drawn on the robot's map
    occupied[int(y / 0.05) - 2:int(y / 0.05) + 3, int(x / 0.05) - 2:int(x / 0.05) + 3] = True
    path = tmp_path / "map.yaml"
    write_map(path, OccupancyGrid(occupied, np.zeros_like(occupied), 0.05, (0.0, 0.0, 0.0)))
    rig = Rig(memory_bus, static_map=path)
    rig.mount()
    rig.scans.put(scan(3, [(2.0, -0.125), (2.0, 0.125)]))
    [msg] = rig.service.poll(0.0)
    assert msg.detections == [] and msg.rejected["legs_on_map"] == 2
    assert rig.service.sub_map is None  # the file's map, not the stream's
    (tmp_path / "bad.yaml").write_text("image: nowhere.pgm\nresolution: 0.05\norigin: [0, 0, 0]\n")
    with pytest.raises(MapFileError, match="nowhere.pgm"):
        LaserConfig(static_map=tmp_path / "bad.yaml").obstacles()


def test_bad_scans_are_counted_and_the_node_keeps_going(memory_bus: MemoryBus) -> None:
    rig = Rig(memory_bus)
    rig.mount()
    good = scan(4, [(2.0, -0.125), (2.0, 0.125)])
    for bad in (dict(angle_increment=0.0), dict(angle_increment=-0.01),
                dict(ranges=good.ranges[:100]), dict(intensities=np.ones(5, np.float32))):
        rig.scans.put(LaserScan.model_construct(**{**dict(good), **bad}))
    nan = good.ranges.copy()
    nan[::7] = np.nan
    nan[1::7] = np.inf
    rig.scans.put(good.model_copy(update={"ranges": nan}))
    out = rig.service.poll(0.0)
    assert rig.service.sub_scans.stats.invalid == 4
    assert len(out) == 1 and len(out[0].detections) == 1  # the scan with NaN and inf beams still finds them
    assert rig.counters.extra["beams_nonfinite"] == 2 * len(nan[::7])


def test_a_scan_waits_for_its_transform_then_is_dropped(memory_bus: MemoryBus) -> None:
    rig = Rig(memory_bus, transform_wait_s=0.2)
    rig.scans.put(scan(5, [(2.0, 0.0)]))
    assert rig.service.poll(0.0) == [] and len(rig.service.waiting) == 1
    assert rig.service.deadline(0.05) == pytest.approx(0.15)
    assert rig.service.poll(0.3) == []
    assert rig.counters.extra.get("dropped_no_transform") == 1
    rig.scans.put(scan(6, [(2.0, 0.0)], frame=""))
    rig.service.poll(0.4)
    assert rig.counters.extra.get("dropped_no_laser_frame") == 1


def test_a_late_transform_is_waited_for(memory_bus: MemoryBus) -> None:
    rig = Rig(memory_bus)
    rig.scans.put(scan(7, [(2.0, -0.125), (2.0, 0.125)]))
    assert rig.service.poll(0.0) == []
    rig.mount()
    [msg] = rig.service.poll(0.1)
    assert len(msg.detections) == 1
