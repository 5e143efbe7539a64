"""Configuration of the simulator (``perception simulate``)."""

from __future__ import annotations

from pydantic import ConfigDict, field_validator, model_validator

from common.runtime.settings import AdvancedBlock, setting

from common.messages.keys import validate_chunk
from tools.simulator.core.cameras import back_camera
from tools.simulator.core.scenarios import SCENARIOS
from tools.simulator.core.simulation import MIN_VISIBLE
from tools.simulator.faults import FAULTS
from tools.simulator.messages import FRAME_NAMES

__all__ = ["SimulatorConfig"]


class SimulatorConfig(AdvancedBlock):
    """What to simulate and how fast. ``duration_s`` None = the scenario's length, 0 = until stopped."""

    model_config = ConfigDict(extra="forbid")

    scenario: str = setting("still", "the scenario to play (perception simulate --list)")
    seed: int = setting(0, "random seed: same seed, same run (people, clothes, odometry errors, noise)", ge=0)
    fps: float = setting(15.0, "camera frames per simulated second", unit="Hz", gt=0.0, le=120.0)
    width: int = setting(640, "image width", unit="px", ge=16, le=4096)
    height: int = setting(480, "image height", unit="px", ge=16, le=4096)
    camera: str = setting("head", "camera name in the frames key and header.source", min_length=1)
    back_camera: str | None = setting(None, "name of a second camera, fixed on the base looking backwards (0.95 m up, "
                                      "yaw 180 deg, the head camera's intrinsics), published on frames/{name} with "
                                      "frame id {name}_optical; None = none")
    laser: str | None = setting(None, "name of a 2-D laser on the base (laser_fov_deg, laser_step_deg, laser_rate_hz; "
                                "at 0.2 m above the floor, 1 cm noise, 1 % dropouts), published on scans/{name} (with "
                                "ros2: on /scan, as its driver would) with frame id base_laser, and the ground "
                                "truth's laser_seen; None = none (--laser)")
    laser_fov_deg: float = setting(360.0, "the laser's sweep (a Hokuyo UST-10LX or a SICK TiM: 270)", unit="deg",
                                   gt=0.0, le=360.0, advanced=True)
    laser_step_deg: float = setting(0.25, "the laser's angle between beams (0.25-0.5 on most)", unit="deg", gt=0.0,
                                    le=5.0, advanced=True)
    laser_rate_hz: float = setting(15.0, "the laser's sweeps per second (at most one a camera frame)", unit="Hz",
                                   gt=0.0, le=100.0, advanced=True)
    rate: float = setting(1.0, "speed relative to real time", gt=0.0, le=100.0)
    max_speed: bool = setting(False, "as fast as the detector keeps up instead of --rate")
    max_wait_s: float = setting(1.0, "--max: longest wait for the detector per frame", unit="s", gt=0.0, advanced=True)
    duration_s: float | None = setting(None, "simulated time to run; none: the scenario's length, 0: until stopped",
                                       unit="s", ge=0.0)
    alike: bool = setting(False, "dress the first two people the same")
    min_visible: float = setting(MIN_VISIBLE, "GT rule: visible share of the body", ge=0.0, le=1.0, advanced=True)
    depth_noise: bool = setting(True, "add the depth sensor's noise; false: exact depth (for debugging)")
    start_ns: int | None = setting(None, "stamp of frame 0 (default: the wall clock at start)", unit="ns", ge=0)
    static_period_s: float = setting(1.0, "how often tf_static is re-sent for late joiners", unit="s", gt=0.0, advanced=True)
    head_control: bool = setting(False, "the head obeys HeadCommand on head/command (the attention node's) instead of "
                                 "the scenario's head motion")
    ros2: bool = setting(False, "publish the head camera and the transforms as a ROS 2 robot does (rmw_zenoh, the "
                         "RealSense driver's topics), for perception ros2")
    ros2_domain_id: int = setting(0, "the ROS 2 domain of --ros2", ge=0, le=232)
    faults: list[str] = setting(description="setup mistakes to make on purpose (tools/simulator/faults.py)",
                                default_factory=list)

    @field_validator("faults")
    @classmethod
    def _known_faults(cls, v: list[str]) -> list[str]:
        unknown = [f for f in v if f not in FAULTS]
        if unknown:
            raise ValueError(f"unknown fault {unknown[0]!r}; choose from {', '.join(FAULTS)}")
        return v

    @field_validator("laser")
    @classmethod
    def _laser_name(cls, v: str | None) -> str | None:
        return v if v is None else validate_chunk(v, "laser")

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
