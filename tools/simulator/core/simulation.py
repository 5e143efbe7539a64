"""One simulated frame: render the world at time t and compute the people's ground truth.

Ground-truth rule (documented in the README): a person is a ground-truth *object* of a
frame when at least ``min_visible`` (default 0.25) of its body sample points -- the centre
of each solid and two points along its long axis, about 50 points -- project inside the
image onto pixels where that person is the nearest surface. People outside the field of
view or hidden behind walls, furniture or other people are recorded too, for debugging,
with ``counted = False``.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np

from common.geometry.transforms import PinholeCamera
from tools.simulator.core.body import Clothing, Ellipsoids, body_ellipsoids, torso_centre
from tools.simulator.core.cameras import FixedCamera
from tools.simulator.core.laser_map import LASER_HEIGHT_M
from tools.simulator.core.laser_scan import LaserSpec, cast_hits, legs_of, rectangles_at, sense
from tools.simulator.core.render import NEAR_M, Renderer, RenderResult
from tools.simulator.core.scenarios import World

__all__ = ["BaseLaser", "FixedView", "FrameData", "PersonTruth", "ScanData", "Simulation", "visible_fraction"]

MIN_VISIBLE = 0.25
#: Beams on a person's legs for the laser to count as seeing them (the leg detector's least segment).
MIN_LASER_BEAMS = 3


@dataclass(frozen=True)
class BaseLaser:
    """A 2-D laser on the base: ``spec`` (its sweep, rate, noise), ``name`` (its stream,
    ``scans/{name}``) and frame ``frame`` at ``mount`` (4, 4) T_base_laser (by default 0.2 m
    ahead of the base's centre at the map's laser height, facing forward)."""

    spec: LaserSpec = field(default_factory=lambda: LaserSpec(fov_deg=360.0))
    name: str = "front"
    frame: str = "base_laser"
    mount: np.ndarray = field(default_factory=lambda: _mount(0.2, LASER_HEIGHT_M))


def _mount(x: float, z: float) -> np.ndarray:
    m = np.eye(4)
    m[0, 3], m[2, 3] = x, z
    return m


@dataclass
class ScanData:
    """One sweep of the base laser: ``map_laser`` (4, 4) the scanner's true pose, ``ranges`` as the
    scanner reports them (float32, 0: no return) and ``beams`` (N,) how many beams hit each person's
    legs, in :attr:`FrameData.people`'s order."""

    laser: BaseLaser
    map_laser: np.ndarray
    ranges: np.ndarray
    beams: np.ndarray


@dataclass(frozen=True)
class PersonTruth:
    """Ground truth of one person in one frame (map frame, metres)."""

    id: int
    position: np.ndarray  # (3,) torso centre
    velocity: np.ndarray  # (3,)
    visible_fraction: float
    in_view_fraction: float
    counted: bool
    posture: str
    height_m: float
    clothing: Clothing
    outfit: int
    facing_rad: float = 0.0  # the direction the body faces in the map (0 along +x)
    laser_seen: bool | None = None  # the base laser's beams hit their legs (None: no laser)


@dataclass
class FixedView:
    """What a camera fixed on the base saw in one frame. ``map_camera`` (4, 4) is its true
    T_map_optical; ``visible``, ``in_view`` (N,) float and ``counted`` (N,) bool are the
    visibility rule's fractions and verdict per person, in :attr:`FrameData.people`'s order."""

    camera: FixedCamera
    render: RenderResult
    map_camera: np.ndarray
    visible: np.ndarray
    in_view: np.ndarray
    counted: np.ndarray


@dataclass
class FrameData:
    """A rendered frame with its time, poses and ground truth. Poses are (4, 4) T_parent_child.

    ``render``, ``map_camera`` and ``people``' visibility are the head camera's; ``views``
    holds the cameras fixed on the base, by name (empty without them); ``scan`` the base laser's
    sweep at this frame's time (None: no laser, or not one of its frames)."""

    seq: int
    t: float
    render: RenderResult
    map_base: np.ndarray
    map_odom: np.ndarray
    odom_base: np.ndarray
    base_head: np.ndarray
    head_camera: np.ndarray
    map_camera: np.ndarray
    people: list[PersonTruth]
    views: dict[str, FixedView] = field(default_factory=dict)
    scan: ScanData | None = None


def visible_fraction(
    points: np.ndarray, owner: int, map_camera: np.ndarray, camera: PinholeCamera, owner_image: np.ndarray
) -> tuple[float, float]:
    """(visible, in-view) fractions of ``points`` (K, 3): in view = in front of the camera and
    inside the image; visible = also on a pixel whose nearest surface is person ``owner``."""
    cam = (points - map_camera[:3, 3]) @ map_camera[:3, :3]
    z = cam[:, 2]
    front = z > NEAR_M
    zs = np.where(front, z, 1.0)
    u = np.floor(camera.fx * cam[:, 0] / zs + camera.cx + 0.5).astype(np.int64)
    v = np.floor(camera.fy * cam[:, 1] / zs + camera.cy + 0.5).astype(np.int64)
    inside = front & (u >= 0) & (u < camera.width) & (v >= 0) & (v < camera.height)
    seen = np.zeros_like(inside)
    seen[inside] = owner_image[v[inside], u[inside]] == owner
    n = max(len(points), 1)
    return float(seen.sum()) / n, float(inside.sum()) / n


class Simulation:
    """Frames of a :class:`World` at ``fps``; frame ``seq`` is at t = seq / fps.

    ``fixed_cameras`` are rendered too, from the same scene at the same time, each with the
    head camera's intrinsics and its own renderer (its own background cache and noise, so
    the head camera's images do not depend on them)."""

    def __init__(
        self,
        world: World,
        camera: PinholeCamera,
        fps: float = 15.0,
        seed: int = 0,
        min_visible: float = MIN_VISIBLE,
        depth_noise: bool = True,
        fixed_cameras: Sequence[FixedCamera] = (),
        laser: BaseLaser | None = None,
    ) -> None:
        self.world = world
        self.camera = camera
        self.fps = fps
        self.min_visible = min_visible
        self.renderer = Renderer(world.apartment, camera, seed=seed, depth_noise=depth_noise)
        self.fixed_cameras = tuple(fixed_cameras)
        self._fixed_renderers = [
            Renderer(world.apartment, camera, seed=(seed, k + 1), depth_noise=depth_noise)
            for k in range(len(self.fixed_cameras))
        ]
        self.laser = laser
        self._seed = seed
        if laser is not None:
            self._solids_at_laser = rectangles_at(world.apartment, float(laser.mount[2, 3]))
            #: a sweep every this many frames: the scanner's own rate, at most the camera's
            self.laser_every = max(1, round(fps / laser.spec.rate_hz))

    def people_solids(
        self, t: float
    ) -> tuple[Ellipsoids, list[tuple[int, np.ndarray, np.ndarray, str, float, Clothing, int, float]]]:
        """All people's solids at ``t``, and per person: (id, torso centre (3,), velocity (3,),
        posture, height, clothing, outfit index, facing yaw)."""
        solids, info = [], []
        for k, (walker, pid) in enumerate(zip(self.world.walkers, self.world.ids)):
            pose, outfit, vel = walker.state(t)
            clothing = walker.wardrobe[outfit]
            solids.append(body_ellipsoids(walker.height, pose, clothing, k))
            info.append(
                (
                    pid,
                    torso_centre(walker.height, pose),
                    np.array([vel[0], vel[1], 0.0]),
                    pose.posture,
                    walker.height,
                    clothing,
                    outfit,
                    float(pose.yaw),
                )
            )
        return Ellipsoids.concat(solids), info

    def frame(self, seq: int) -> FrameData:
        """Render frame ``seq`` and compute its ground truth."""
        t = seq / self.fps
        robot = self.world.robot
        map_base = robot.base_pose(t)
        odom_base = robot.odometry.pose(t)
        base_head = robot.head_joint(t)
        head_cam = robot.camera_mount()
        map_cam = map_base @ base_head @ head_cam
        solids, info = self.people_solids(t)
        result = self.renderer.render(map_cam, solids)
        people = []
        scan = self._scan(seq, t, map_base, info) if self.laser is not None else None
        for k, (pid, centre, vel, posture, height, clothing, outfit, yaw) in enumerate(info):
            vis, in_view = visible_fraction(solids.sample_points(k), k, map_cam, self.camera, result.owner)
            people.append(
                PersonTruth(pid, centre, vel, vis, in_view, vis >= self.min_visible, posture, height, clothing, outfit,
                            yaw, None if scan is None else bool(scan.beams[k] >= MIN_LASER_BEAMS))
            )
        if scan is not None and seq % self.laser_every:
            scan = None  # seen (the ground truth), not sent: not one of the scanner's frames
        return FrameData(
            seq,
            t,
            result,
            map_base,
            map_base @ np.linalg.inv(odom_base),
            odom_base,
            base_head,
            head_cam,
            map_cam,
            people,
            {cam.name: self._fixed_view(cam, renderer, map_base, solids)
             for cam, renderer in zip(self.fixed_cameras, self._fixed_renderers)},
            scan,
        )

    def _scan(self, seq: int, t: float, map_base: np.ndarray,
              info: list[tuple[int, np.ndarray, np.ndarray, str, float, Clothing, int, float]]) -> ScanData:
        """The base laser's sweep at ``t``: the apartment's solids at its height and everyone's legs."""
        laser = self.laser
        assert laser is not None
        map_laser = map_base @ laser.mount
        xy = np.array([c[:2] for _, c, *_ in info]).reshape(-1, 2)
        heading = np.array([yaw for *_, yaw in info])
        speed = np.array([float(np.hypot(v[0], v[1])) for _, _, v, *_ in info])
        seated = np.array([posture == "sitting" for _, _, _, posture, *_ in info], bool)
        legs = legs_of(xy, heading, speed, t, seated)
        yaw = float(np.arctan2(map_laser[1, 0], map_laser[0, 0]))
        exact, owner = cast_hits(map_laser[:2, 3], yaw, laser.spec.angles(), self._solids_at_laser, legs,
                                 laser.spec.range_max)
        ranges = sense(exact, laser.spec, np.random.default_rng((self._seed, 7, seq)))
        hit = owner[(owner >= 0) & (ranges > 0)] // 2
        return ScanData(laser, map_laser, ranges, np.bincount(hit, minlength=len(info)))

    def _fixed_view(self, cam: FixedCamera, renderer: Renderer, map_base: np.ndarray, solids: Ellipsoids) -> FixedView:
        map_cam = map_base @ cam.base_optical
        result = renderer.render(map_cam, solids)
        n = len(self.world.walkers)
        visible, in_view = np.zeros(n), np.zeros(n)
        for k in range(n):
            visible[k], in_view[k] = visible_fraction(solids.sample_points(k), k, map_cam, self.camera, result.owner)
        return FixedView(cam, result, map_cam, visible, in_view, visible >= self.min_visible)
