"""Configuration of the simulator (``perception simulate``)."""

from __future__ import annotations

from pydantic import BaseModel, ConfigDict, Field, field_validator, model_validator

from common.messages.keys import validate_chunk
from tools.simulator.core.cameras import back_camera
from tools.simulator.core.scenarios import SCENARIOS
from tools.simulator.core.simulation import MIN_VISIBLE
from tools.simulator.faults import FAULTS
from tools.simulator.messages import FRAME_NAMES

__all__ = ["SimulatorConfig"]


class SimulatorConfig(BaseModel):
    """What to simulate and how fast. ``duration_s`` None = the scenario's length, 0 = until stopped."""

    model_config = ConfigDict(extra="forbid")

    scenario: str = "still"
    seed: int = Field(default=0, ge=0)
    fps: float = Field(default=15.0, gt=0.0, le=120.0, description="camera frames per simulated second")
    width: int = Field(default=640, ge=16, le=4096)
    height: int = Field(default=480, ge=16, le=4096)
    camera: str = Field(default="head", min_length=1, description="camera name in the frames key and header.source")
    back_camera: str | None = Field(
        default=None,
        description="name of a second camera, fixed on the base looking backwards (0.95 m up, yaw 180 deg, the head "
                    "camera's intrinsics), published on frames/{name} with frame id {name}_optical; None = none",
    )
    rate: float = Field(default=1.0, gt=0.0, le=100.0, description="speed relative to real time")
    max_speed: bool = Field(default=False, description="as fast as the detector keeps up instead of --rate")
    max_wait_s: float = Field(default=1.0, gt=0.0, description="--max: longest wait for the detector per frame")
    duration_s: float | None = Field(default=None, ge=0.0)
    alike: bool = Field(default=False, description="dress the first two people the same")
    min_visible: float = Field(default=MIN_VISIBLE, ge=0.0, le=1.0, description="GT rule: visible share of the body")
    depth_noise: bool = True
    start_ns: int | None = Field(default=None, ge=0, description="stamp of frame 0 (default: the wall clock at start)")
    static_period_s: float = Field(default=1.0, gt=0.0, description="how often tf_static is re-sent for late joiners")
    head_control: bool = Field(default=False, description="the head obeys HeadCommand on head/command (the attention "
                                                          "node's) instead of the scenario's head motion")
    ros2: bool = Field(default=False, description="publish the head camera and the transforms as a ROS 2 robot does "
                                                  "(rmw_zenoh, the RealSense driver's topics), for perception ros2")
    ros2_domain_id: int = Field(default=0, ge=0, le=232, description="the ROS 2 domain of --ros2")
    faults: list[str] = Field(default_factory=list, description="setup mistakes to make on purpose (tools/simulator/faults.py)")

    @field_validator("faults")
    @classmethod
    def _known_faults(cls, v: list[str]) -> list[str]:
        unknown = [f for f in v if f not in FAULTS]
        if unknown:
            raise ValueError(f"unknown fault {unknown[0]!r}; choose from {', '.join(FAULTS)}")
        return v

    @field_validator("back_camera")
    @classmethod
    def _back_name(cls, v: str | None) -> str | None:
        if v is None:
            return v
        validate_chunk(v, "back_camera")
        cam = back_camera(v)
        taken = [f for f in (cam.mount_frame, cam.optical_frame) if f in FRAME_NAMES]
        if taken:
            raise ValueError(f"back_camera {v!r} would name its frame {taken[0]!r}, which the robot already has; "
                             "choose another name")
        return v

    @model_validator(mode="after")
    def _two_names(self) -> SimulatorConfig:
        if self.back_camera == self.camera:
            raise ValueError(f"back_camera must differ from camera ({self.camera!r}): each camera has its own frames key")
        if self.ros2 and self.back_camera is not None:
            raise ValueError("ros2 publishes one camera (the head's, on the RealSense driver's topics): drop back_camera")
        return self

    @field_validator("scenario")
    @classmethod
    def _known(cls, v: str) -> str:
        if v not in SCENARIOS:
            raise ValueError(f"unknown scenario {v!r}; choose one of {', '.join(SCENARIOS)}")
        return v
