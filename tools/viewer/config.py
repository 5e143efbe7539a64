"""The viewer's settings."""

from __future__ import annotations

from pathlib import Path

from pydantic import BaseModel, ConfigDict, Field, PrivateAttr, model_validator

from common.geometry.map_file import MapFileError, OccupancyGrid, read_map

__all__ = ["ViewerConfig"]


class ViewerConfig(BaseModel):
    """What ``perception view`` serves and how often it refreshes."""

    model_config = ConfigDict(extra="forbid")

    camera: str = Field(default="head", description="camera name in the keys")
    host: str = Field(default="127.0.0.1", description="address the page and the Foxglove server bind to")
    port: int | None = Field(default=8080, ge=0, le=65535, description="the page's HTTP port (0: a free one; None: no page)")
    foxglove_port: int | None = Field(default=None, ge=0, le=65535,
                                      description="Foxglove WebSocket port (None: no Foxglove server)")
    map_frame: str = Field(default="map", min_length=1, description="the frame of the map and the tracks")
    base_frame: str = Field(default="base_link", min_length=1, description="the robot's body frame")
    trail_s: float = Field(default=5.0, gt=0.0, le=120.0, description="how long a track's trail is (s)")
    state_hz: float = Field(default=10.0, gt=0.0, le=60.0, description="most page states per second")
    image_hz: float = Field(default=10.0, gt=0.0, le=60.0, description="most camera images encoded per second")
    jpeg_quality: int = Field(default=75, ge=10, le=100)
    static_map: Path | None = Field(default=None, description="the robot's map (a ROS map YAML file, in map_frame) to "
                                                             "draw; without it the static_map stream's (perception ros2)")
    _grid: OccupancyGrid | None = PrivateAttr(default=None)

    @model_validator(mode="after")
    def _something_to_serve(self) -> ViewerConfig:
        if self.port is None and self.foxglove_port is None:
            raise ValueError("nothing to serve: give --port or --foxglove-port")
        if self.static_map is not None:
            try:
                self._grid = read_map(self.static_map)
            except MapFileError as exc:
                raise ValueError(str(exc)) from None
        return self

    @property
    def grid(self) -> OccupancyGrid | None:
        """The map file's grid (None: no file)."""
        return self._grid
