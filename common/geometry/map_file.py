"""ROS map files (``map_server``'s and Nav2's: a YAML file naming an image) as occupancy grids.

The YAML keys are ROS's: ``image`` (a path relative to the YAML file; PGM, PNG, BMP), ``resolution``
(m per pixel), ``origin`` ([x, y, yaw] of the image's lower-left pixel in the map frame),
``negate``, ``occupied_thresh`` and ``free_thresh`` (on the occupancy probability
``(255 - value) / 255``, or ``value / 255`` when negated) and ``mode`` (``trinary``, the
default, or ``scale``: the same thresholds; ``raw``: each value is the cell's occupancy in
percent, above 100 unknown). As Nav2's ``map_io`` reads them: a pixel above ``occupied_thresh``
is occupied, one below ``free_thresh`` free, the rest unknown (a raw value is occupied from
``occupied_thresh`` x 100 on).
The image's top row is the map's highest y; the grids here have row 0 at the lowest y
(:mod:`common.geometry.occupancy`). A map saved by ``nav2_map_server``'s map_saver or
``slam_toolbox`` reads as it is.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import lru_cache
from pathlib import Path
from typing import Any

import cv2
import numpy as np
import yaml

from common.geometry.occupancy import ObstacleMap

__all__ = ["MapFileError", "OccupancyGrid", "load_obstacles", "read_map", "write_map"]

#: The pixel values :func:`write_map` uses, map_saver's: occupied, free, unknown.
OCCUPIED_PIXEL, FREE_PIXEL, UNKNOWN_PIXEL = 0, 254, 205


class MapFileError(ValueError):
    """A map file that cannot be read; the message names the file and what to fix."""


@dataclass(frozen=True)
class OccupancyGrid:
    """``occupied`` and ``unknown`` (H, W) bool, row 0 at the lowest y; ``resolution`` m per
    cell; ``origin`` (x, y, yaw) of cell (0, 0)'s outer corner in the map frame."""

    occupied: np.ndarray
    unknown: np.ndarray
    resolution: float
    origin: tuple[float, float, float]

    def obstacles(self, min_extent_m: float = 0.0) -> ObstacleMap:
        """The distances to this map's occupied cells (posts under ``min_extent_m`` left out:
        :meth:`ObstacleMap.from_occupied`)."""
        return ObstacleMap.from_occupied(self.occupied, self.resolution, self.origin, min_extent_m)


def _number(meta: dict[str, Any], key: str, path: Path, default: float | None = None) -> float:
    value = meta.get(key, default)
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        raise MapFileError(f"map {path}: '{key}' must be a number, got {value!r}")
    return float(value)


def read_map(path: str | Path) -> OccupancyGrid:
    """The occupancy grid of the ROS map YAML file ``path``; :class:`MapFileError` naming the problem."""
    path = Path(path)
    if not path.is_file():
        raise MapFileError(f"no map file {path}: give the YAML file a map saver wrote (map.yaml next to "
                           "its map.pgm), e.g. `ros2 run nav2_map_server map_saver_cli -f map`")
    try:
        meta = yaml.safe_load(path.read_text())
    except (OSError, UnicodeDecodeError, yaml.YAMLError) as exc:
        raise MapFileError(f"map {path} is not a readable YAML file: {exc}") from exc
    if not isinstance(meta, dict):
        raise MapFileError(f"map {path} must be a YAML mapping with image, resolution and origin")
    missing = [k for k in ("image", "resolution", "origin") if k not in meta]
    if missing:
        raise MapFileError(f"map {path} lacks {', '.join(missing)}: a ROS map file names its image, "
                           "resolution (m per pixel) and origin [x, y, yaw]")
    resolution = _number(meta, "resolution", path)
    origin = meta["origin"]
    if not (isinstance(origin, (list, tuple)) and len(origin) == 3
            and all(isinstance(v, (int, float)) and not isinstance(v, bool) for v in origin)):
        raise MapFileError(f"map {path}: origin must be [x, y, yaw] in metres and radians, got {origin!r}")
    negate = int(_number(meta, "negate", path, 0))
    occupied_thresh = _number(meta, "occupied_thresh", path, 0.65)
    free_thresh = _number(meta, "free_thresh", path, 0.196)
    mode = meta.get("mode", "trinary")
    if mode not in ("trinary", "scale", "raw"):
        raise MapFileError(f"map {path}: mode must be trinary, scale or raw, got {mode!r}")
    if not (resolution > 0 and 0 <= free_thresh <= occupied_thresh <= 1):
        raise MapFileError(f"map {path}: need resolution > 0 and 0 <= free_thresh <= occupied_thresh <= 1, got "
                           f"{resolution}, {free_thresh}, {occupied_thresh}")
    image_path = path.parent / str(meta["image"])
    image = cv2.imread(str(image_path), cv2.IMREAD_UNCHANGED) if image_path.is_file() else None
    if image is None:
        raise MapFileError(f"map {path}: cannot read its image {image_path} (a PGM, PNG or BMP next to the YAML file)")
    if image.ndim == 3:  # map_server averages the colour channels (an alpha channel is left out)
        image = image[:, :, :3].mean(axis=2)
    value = np.asarray(image, np.float64)[::-1]  # the image's top row is the highest y
    if mode == "raw":
        value = np.rint(value)
        occupied = (value <= 100) & (value >= 100 * occupied_thresh)
        unknown = value > 100
    else:
        p = value / 255.0 if negate else (255.0 - value) / 255.0
        occupied = p > occupied_thresh
        unknown = ~occupied & ~(p < free_thresh)
    return OccupancyGrid(occupied, unknown, resolution, (float(origin[0]), float(origin[1]), float(origin[2])))


def load_obstacles(path: str | Path, min_extent_m: float = 0.0) -> ObstacleMap:
    """``read_map(path).obstacles(min_extent_m)``, made once per version of the YAML file and of
    its image (reading a large image takes a moment, and settings are validated more than once; a
    map saved again under the same name, image only, is read again)."""
    path = Path(path)
    if not path.is_file():
        read_map(path)  # MapFileError naming the fix
    return _obstacles(path.resolve(), _version(path), min_extent_m)


def _version(path: Path) -> tuple[tuple[int, int], ...]:
    """(modification time, size) of the YAML file ``path`` and, when it names one, of its image."""
    stats = [path.stat()]
    try:
        meta = yaml.safe_load(path.read_text())
        stats.append((path.parent / str(meta["image"])).stat())
    except (OSError, UnicodeDecodeError, yaml.YAMLError, KeyError, TypeError):
        pass  # read_map says what is wrong with the file
    return tuple((s.st_mtime_ns, s.st_size) for s in stats)


@lru_cache(maxsize=4)
def _obstacles(path: Path, version: tuple[tuple[int, int], ...], min_extent_m: float) -> ObstacleMap:
    return read_map(path).obstacles(min_extent_m)


def write_map(path: str | Path, grid: OccupancyGrid) -> Path:
    """Write ``grid`` as a ROS map: ``path`` (YAML) and the PGM image beside it; returns the image's path."""
    path = Path(path)
    image_path = path.with_suffix(".pgm")
    pixels = np.full(grid.occupied.shape, FREE_PIXEL, np.uint8)
    pixels[grid.unknown] = UNKNOWN_PIXEL
    pixels[grid.occupied] = OCCUPIED_PIXEL
    path.parent.mkdir(parents=True, exist_ok=True)
    if not cv2.imwrite(str(image_path), pixels[::-1]):
        raise MapFileError(f"cannot write the map image {image_path}")
    meta = {"image": image_path.name, "mode": "trinary", "resolution": grid.resolution,
            "origin": [float(v) for v in grid.origin], "negate": 0, "occupied_thresh": 0.65,
            "free_thresh": 0.196}  # map_server's: 205, unknown, reads back as unknown
    path.write_text(yaml.safe_dump(meta, sort_keys=False))
    return image_path
