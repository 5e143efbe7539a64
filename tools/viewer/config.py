"""The viewer's settings."""

from __future__ import annotations

from pathlib import Path

from pydantic import ConfigDict, PrivateAttr, model_validator

from common.runtime.settings import AdvancedBlock, setting

from common.geometry.map_file import MapFileError, OccupancyGrid, read_map

__all__ = ["ViewerConfig"]


class ViewerConfig(AdvancedBlock):
    """What ``perception view`` serves and how often it refreshes."""

    model_config = ConfigDict(extra="forbid")

    camera: str = setting("head", "camera name in the keys")
    host: str = setting("127.0.0.1", "address the page and the Foxglove server bind to")
    port: int | None = setting(8080, "the page's HTTP port (0: a free one; None: no page)", ge=0, le=65535)
    foxglove_port: int | None = setting(None, "Foxglove WebSocket port (None: no Foxglove server)", ge=0, le=65535)
    map_frame: str = setting("map", "the frame of the map and the tracks", min_length=1)
    base_frame: str = setting("base_link", "the robot's body frame", min_length=1)
    trail_s: float = setting(5.0, "how long a track's trail is", unit="s", gt=0.0, le=120.0)
    state_hz: float = setting(10.0, "most page states per second", unit="Hz", gt=0.0, le=60.0, advanced=True)
    image_hz: float = setting(10.0, "most camera images encoded per second", unit="Hz", gt=0.0, le=60.0, advanced=True)
    jpeg_quality: int = setting(75, "JPEG quality of the camera images sent to the page", ge=10, le=100, advanced=True)
    static_map: Path | None = setting(None, "the robot's map (a ROS map YAML file, in map_frame) to draw; without it "
                                      "the static_map stream's (perception ros2)")
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
