"""Camera model, rigid transforms and a TF-style transform buffer (numpy, scipy, cv2 only).

Conventions follow ROS:

* The camera frame is the *optical* frame: x right, y down, z forward along the optical
  axis. Pixel ``(u, v)`` has its origin at the centre of the top-left pixel.
* A transform ``parent -> child`` maps points expressed in ``child`` into ``parent``:
  ``p_parent = R @ p_child + t``. :meth:`TransformBuffer.lookup` ``(target, source, t)``
  returns the transform that maps ``source`` points into ``target``.
* Time is integer nanoseconds (``stamp_ns``); durations are seconds (``*_s``).

Nothing here knows about messages; :mod:`common.geometry.messages` builds these objects
from :class:`~common.messages.schemas.CameraInfo` and :class:`~common.messages.schemas.Transform`.
"""

from __future__ import annotations

import bisect
from dataclasses import dataclass, field
from typing import Literal

import cv2
import numpy as np
from scipy.spatial.transform import Rotation, Slerp

__all__ = [
    "ExtrapolationError",
    "FrameTreeError",
    "MissingTransformError",
    "PinholeCamera",
    "RigidTransform",
    "TransformBuffer",
    "TransformError",
    "interpolate",
]

DistortionModel = Literal["plumb_bob", "rational_polynomial", "equidistant", "none"]

# cv2.undistortPoints stops after 5 fixed-point iterations, which leaves millimetre errors
# near the corners of strongly distorted lenses; iterate to convergence instead.
_UNDISTORT_CRITERIA = (cv2.TERM_CRITERIA_COUNT | cv2.TERM_CRITERIA_EPS, 50, 1e-10)


# ------------------------------------------------------------------------------ camera


@dataclass(frozen=True)
class PinholeCamera:
    """Intrinsics ``K`` (3, 3) and distortion ``D`` (k,) of a ``width`` x ``height`` camera."""

    K: np.ndarray
    width: int
    height: int
    D: np.ndarray = field(default_factory=lambda: np.zeros(0))
    distortion_model: DistortionModel = "plumb_bob"

    def __post_init__(self) -> None:
        K = np.asarray(self.K, dtype=np.float64).reshape(3, 3)
        D = np.asarray(self.D, dtype=np.float64).reshape(-1)
        if not (np.all(np.isfinite(K)) and np.all(np.isfinite(D))):
            raise ValueError("camera K and D must be finite")
        if not (K[0, 0] > 0 and K[1, 1] > 0):
            raise ValueError(f"camera focal lengths must be positive, got fx={K[0, 0]}, fy={K[1, 1]}")
        if self.width <= 0 or self.height <= 0:
            raise ValueError(f"camera size must be positive, got {self.width}x{self.height}")
        object.__setattr__(self, "K", K)
        object.__setattr__(self, "D", D)

    @property
    def distorted(self) -> bool:
        return self.distortion_model != "none" and bool(np.any(self.D != 0.0))

    @property
    def fx(self) -> float:
        return float(self.K[0, 0])

    @property
    def fy(self) -> float:
        return float(self.K[1, 1])

    @property
    def cx(self) -> float:
        return float(self.K[0, 2])

    @property
    def cy(self) -> float:
        return float(self.K[1, 2])

    def project(self, points: np.ndarray) -> np.ndarray:
        """Pixels (N, 2) of camera-frame points (N, 3) with z > 0 (distortion applied)."""
        pts = np.asarray(points, dtype=np.float64).reshape(-1, 3)
        if not self.distorted:
            uvw = pts @ self.K.T
            return uvw[:, :2] / uvw[:, 2:3]
        zero = np.zeros(3)
        if self.distortion_model == "equidistant":
            out, _ = cv2.fisheye.projectPoints(pts.reshape(-1, 1, 3), zero, zero, self.K, self.D[:4])
        else:
            out, _ = cv2.projectPoints(pts.reshape(-1, 1, 3), zero, zero, self.K, self.D)
        return out.reshape(-1, 2)

    def rays(self, pixels: np.ndarray) -> np.ndarray:
        """Rays (N, 3) through pixels (N, 2), scaled so that z = 1 (distortion removed)."""
        px = np.asarray(pixels, dtype=np.float64).reshape(-1, 2)
        if not self.distorted:
            xy = (px - self.K[:2, 2]) / np.array([self.fx, self.fy])
            xy[:, 0] -= self.K[0, 1] * xy[:, 1] / self.fx  # skew, zero for real cameras
        elif self.distortion_model == "equidistant":
            xy = cv2.fisheye.undistortPoints(px.reshape(-1, 1, 2), self.K, self.D[:4]).reshape(-1, 2)
        else:
            src = px.reshape(-1, 1, 2)
            xy = cv2.undistortPointsIter(src, self.K, self.D, None, None, _UNDISTORT_CRITERIA)  # type: ignore[call-overload]
            xy = xy.reshape(-1, 2)
        return np.column_stack([xy, np.ones(len(xy))])

    def back_project(self, pixels: np.ndarray, depth_z: np.ndarray) -> np.ndarray:
        """Camera-frame points (N, 3) at optical-axis depth ``depth_z`` (N,) m through pixels (N, 2)."""
        return self.rays(pixels) * np.asarray(depth_z, dtype=np.float64).reshape(-1, 1)

    def ray_jacobians(self, pixels: np.ndarray, step_px: float = 0.5) -> np.ndarray:
        """d(ray)/d(u, v) as (N, 3, 2), for the z = 1 rays of :meth:`rays`.

        Exact for an undistorted camera; central differences through the distortion
        model otherwise (one batched undistortion call).
        """
        px = np.asarray(pixels, dtype=np.float64).reshape(-1, 2)
        n = len(px)
        if not self.distorted:
            jac = np.zeros((n, 3, 2))
            jac[:, 0, 0] = 1.0 / self.fx
            jac[:, 0, 1] = -self.K[0, 1] / (self.fx * self.fy)
            jac[:, 1, 1] = 1.0 / self.fy
            return jac
        offsets = np.array([[step_px, 0.0], [-step_px, 0.0], [0.0, step_px], [0.0, -step_px]])
        r = self.rays((px[:, None, :] + offsets[None]).reshape(-1, 2)).reshape(n, 4, 3)
        return np.stack([(r[:, 0] - r[:, 1]), (r[:, 2] - r[:, 3])], axis=2) / (2.0 * step_px)


# -------------------------------------------------------------------- rigid transforms


def _quat_mul(a: tuple[float, float, float, float], b: tuple[float, float, float, float]) -> tuple[float, float, float, float]:
    """Hamilton product ``a * b`` of (x, y, z, w) quaternions: rotate by ``b``, then ``a``."""
    ax, ay, az, aw = a
    bx, by, bz, bw = b
    return (aw * bx + ax * bw + ay * bz - az * by,
            aw * by - ax * bz + ay * bw + az * bx,
            aw * bz + ax * by - ay * bx + az * bw,
            aw * bw - ax * bx - ay * by - az * bz)


def _quat_matrix(q: tuple[float, float, float, float]) -> np.ndarray:
    x, y, z, w = q
    return np.array([[1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
                     [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
                     [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)]])


class RigidTransform:
    """A rotation and a translation: ``apply(p) = R @ p + t``.

    The rotation is held as a unit quaternion and its matrix; composing, inverting and
    applying are plain float and numpy arithmetic (a transform lookup along a robot's
    chain of frames is a few microseconds, not the hundreds that scipy's per-call
    overhead costs). :attr:`rotation` gives the scipy :class:`Rotation` when needed.
    Immutable.
    """

    __slots__ = ("_q", "_m", "_rotation", "translation")

    _q: tuple[float, float, float, float]
    _m: np.ndarray
    _rotation: Rotation | None
    translation: np.ndarray

    def __init__(self, rotation: Rotation, translation: np.ndarray) -> None:
        x, y, z, w = (float(v) for v in rotation.as_quat())
        self._init((x, y, z, w), translation)
        object.__setattr__(self, "_rotation", rotation)

    def _init(self, q: tuple[float, float, float, float], translation: np.ndarray) -> None:
        t = np.asarray(translation, dtype=np.float64).reshape(3)
        if not np.isfinite(t).all():
            raise ValueError("translation must be finite")
        m = _quat_matrix(q)
        m.flags.writeable = False
        t = t.copy() if t is translation else t
        t.flags.writeable = False
        object.__setattr__(self, "_q", q)
        object.__setattr__(self, "_m", m)
        object.__setattr__(self, "_rotation", None)
        object.__setattr__(self, "translation", t)

    @classmethod
    def _of(cls, q: tuple[float, float, float, float], translation: np.ndarray) -> RigidTransform:
        """From a unit quaternion (x, y, z, w) and a translation, without going through scipy."""
        out = cls.__new__(cls)
        out._init(q, translation)
        return out

    def __setattr__(self, name: str, value: object) -> None:
        raise AttributeError(f"RigidTransform is immutable (cannot set {name!r})")

    def __repr__(self) -> str:
        return f"RigidTransform(quat_xyzw={list(self._q)}, translation={self.translation.tolist()})"

    @property
    def rotation(self) -> Rotation:
        """The rotation as a scipy :class:`Rotation` (built on first use)."""
        if self._rotation is None:
            object.__setattr__(self, "_rotation", Rotation.from_quat(self._q))
        return self._rotation  # type: ignore[return-value]

    @classmethod
    def identity(cls) -> RigidTransform:
        return cls._of((0.0, 0.0, 0.0, 1.0), np.zeros(3))

    @classmethod
    def from_quat(cls, translation: np.ndarray, quat_xyzw: np.ndarray) -> RigidTransform:
        """From a translation (3,) and a quaternion (4,) in (x, y, z, w) order (normalised here)."""
        q = np.asarray(quat_xyzw, dtype=np.float64).reshape(4)
        x, y, z, w = (float(v) for v in q)
        norm = (x * x + y * y + z * z + w * w) ** 0.5
        if not np.isfinite(norm) or norm < 1e-9:
            raise ValueError(f"quaternion {q.tolist()} cannot be normalised")
        return cls._of((x / norm, y / norm, z / norm, w / norm), translation)

    @classmethod
    def from_matrix(cls, matrix: np.ndarray) -> RigidTransform:
        """From a homogeneous (4, 4) matrix."""
        m = np.asarray(matrix, dtype=np.float64)
        return cls(Rotation.from_matrix(m[:3, :3]), m[:3, 3])

    @property
    def rotation_matrix(self) -> np.ndarray:
        """The (3, 3) rotation matrix (read-only)."""
        return self._m

    @property
    def quat_xyzw(self) -> np.ndarray:
        return np.array(self._q)

    @property
    def matrix(self) -> np.ndarray:
        """Homogeneous (4, 4) matrix."""
        m = np.eye(4)
        m[:3, :3] = self._m
        m[:3, 3] = self.translation
        return m

    def __matmul__(self, other: RigidTransform) -> RigidTransform:
        """Composition: ``(a @ b).apply(p) == a.apply(b.apply(p))``."""
        return RigidTransform._of(_quat_mul(self._q, other._q), self._m @ other.translation + self.translation)

    def inverse(self) -> RigidTransform:
        x, y, z, w = self._q
        return RigidTransform._of((-x, -y, -z, w), -(self._m.T @ self.translation))

    def apply(self, points: np.ndarray) -> np.ndarray:
        """Transformed points, (N, 3) -> (N, 3) or (3,) -> (3,)."""
        p = np.asarray(points, dtype=np.float64)
        return p @ self._m.T + self.translation

    def rotate_covariances(self, covs: np.ndarray) -> np.ndarray:
        """``R @ C @ R.T`` for covariances (N, 3, 3) or (3, 3) (translation does not change them)."""
        r = self._m
        return np.einsum("ij,...jk,lk->...il", r, np.asarray(covs, dtype=np.float64), r)


def interpolate(a: RigidTransform, b: RigidTransform, alpha: float) -> RigidTransform:
    """Translation linearly, rotation by slerp; ``alpha`` 0 gives ``a``, 1 gives ``b``."""
    slerp = Slerp([0.0, 1.0], Rotation.concatenate([a.rotation, b.rotation]))
    return RigidTransform(slerp([alpha])[0], (1.0 - alpha) * a.translation + alpha * b.translation)


# ------------------------------------------------------------------- transform buffer


class TransformError(LookupError):
    """A transform lookup that cannot be answered."""


class MissingTransformError(TransformError):
    """No chain of transforms links ``source`` to ``target``.

    ``source_root`` is the top of ``source``'s tree (a frame without a parent) and
    ``target_tree`` the frames of ``target``'s tree: a transform from one of those
    frames to ``source_root`` is what is missing (for a robot, usually
    ``odom -> base_link`` or ``map -> odom``).
    """

    def __init__(self, target: str, source: str, target_tree: list[str], source_root: str) -> None:
        self.target, self.source = target, source
        self.target_tree, self.source_root = target_tree, source_root
        super().__init__(
            f"no transform chain from {source!r} to {target!r}: {source_root!r} (the top of the tree of {source!r}) "
            f"has no parent in the tree of {target!r} ({', '.join(target_tree)}); publish the missing transform "
            f"{self.edge}"
        )

    @property
    def edge(self) -> str:
        """``"map|odom -> base_link"``: the missing edge, its parent being one of the listed frames."""
        return f"{'|'.join(self.target_tree)} -> {self.source_root}"


class ExtrapolationError(TransformError):
    """The edge ``parent -> child`` has no data near ``stamp_ns`` (beyond the tolerance)."""

    def __init__(
        self, parent: str, child: str, stamp_ns: int, oldest_ns: int, newest_ns: int, tolerance_ns: int
    ) -> None:
        self.parent, self.child = parent, child
        self.stamp_ns, self.oldest_ns, self.newest_ns = stamp_ns, oldest_ns, newest_ns
        self.future = stamp_ns > newest_ns
        gap = (stamp_ns - newest_ns if self.future else oldest_ns - stamp_ns) / 1e9
        where = "newer than the latest" if self.future else "older than the oldest"
        super().__init__(
            f"transform {parent} -> {child} at t={stamp_ns / 1e9:.6f} s is {gap:.3f} s {where} one held "
            f"(buffer spans {oldest_ns / 1e9:.6f} .. {newest_ns / 1e9:.6f} s, tolerance {tolerance_ns / 1e9:.3f} s)"
        )

    @property
    def edge(self) -> str:
        return f"{self.parent} -> {self.child}"


class FrameTreeError(ValueError):
    """A transform that would break the frame tree (second parent, cycle, static/dynamic mix)."""


class _Edge:
    """Time-sorted history of one ``parent -> child`` edge."""

    __slots__ = ("parent", "child", "static", "stamps", "transforms")

    def __init__(self, parent: str, child: str, static: bool) -> None:
        self.parent, self.child, self.static = parent, child, static
        self.stamps: list[int] = []
        self.transforms: list[RigidTransform] = []

    def insert(self, stamp_ns: int, tf: RigidTransform, history_ns: int) -> None:
        if self.static:
            self.stamps, self.transforms = [stamp_ns], [tf]
            return
        if self.stamps and stamp_ns < self.stamps[-1] - history_ns:
            # older than the whole history: a new clock (a replay that loops, a clock
            # reset), not a late transform; start the history over from it
            self.stamps, self.transforms = [], []
        i = bisect.bisect_left(self.stamps, stamp_ns)
        if i < len(self.stamps) and self.stamps[i] == stamp_ns:
            self.transforms[i] = tf
        else:
            self.stamps.insert(i, stamp_ns)
            self.transforms.insert(i, tf)
        cut = bisect.bisect_left(self.stamps, self.stamps[-1] - history_ns)
        if cut:
            del self.stamps[:cut], self.transforms[:cut]

    def at(self, stamp_ns: int, tolerance_ns: int) -> RigidTransform:
        if self.static:
            return self.transforms[0]
        stamps = self.stamps
        if stamp_ns <= stamps[0] or stamp_ns >= stamps[-1]:
            end = 0 if stamp_ns <= stamps[0] else -1
            if abs(stamp_ns - stamps[end]) > tolerance_ns:
                raise ExtrapolationError(self.parent, self.child, stamp_ns, stamps[0], stamps[-1], tolerance_ns)
            return self.transforms[end]
        i = bisect.bisect_right(stamps, stamp_ns)
        t0, t1 = stamps[i - 1], stamps[i]
        if t0 == stamp_ns:
            return self.transforms[i - 1]
        return interpolate(self.transforms[i - 1], self.transforms[i], (stamp_ns - t0) / (t1 - t0))


class TransformBuffer:
    """Timestamped transforms of a frame tree, answering chain lookups at any time.

    Each child frame has one parent. Dynamic edges keep ``history_s`` seconds of
    history (measured from their newest stamp); a lookup between two stamps
    interpolates (translation linearly, rotation by slerp), and a lookup up to
    ``tolerance_s`` before the oldest or after the newest stamp uses that end stamp.
    Beyond that it raises :class:`ExtrapolationError`. Static edges hold at all times. A
    dynamic transform older than an edge's whole history starts that history over: it is
    a new clock (a replay that loops, a clock reset), not a late transform.
    Not thread-safe: feed and query it from one thread.
    """

    def __init__(self, history_s: float = 10.0, tolerance_s: float = 0.05) -> None:
        if not history_s > 0:
            raise ValueError(f"history_s must be > 0, got {history_s}")
        if not tolerance_s >= 0:
            raise ValueError(f"tolerance_s must be >= 0, got {tolerance_s}")
        self.history_ns = int(history_s * 1e9)
        self.tolerance_ns = int(tolerance_s * 1e9)
        self._edges: dict[str, _Edge] = {}  # by child frame

    def set_transform(
        self, parent: str, child: str, stamp_ns: int, transform: RigidTransform, static: bool = False
    ) -> None:
        """Add ``parent -> child`` at ``stamp_ns`` (maps ``child`` points into ``parent``)."""
        if parent == child:
            raise FrameTreeError(f"transform {parent} -> {child} links a frame to itself")
        edge = self._edges.get(child)
        if edge is None:
            if child in self._ancestors(parent):
                raise FrameTreeError(
                    f"transform {parent} -> {child} would close a cycle ({child!r} is above {parent!r})"
                )
            edge = self._edges[child] = _Edge(parent, child, static)
        elif edge.parent != parent:
            raise FrameTreeError(f"frame {child!r} already has parent {edge.parent!r}, got a transform from {parent!r}")
        elif edge.static != static:
            kind = "static" if edge.static else "dynamic"
            raise FrameTreeError(
                f"transform {parent} -> {child} is {kind}, got a {'static' if static else 'dynamic'} update"
            )
        edge.insert(int(stamp_ns), transform, self.history_ns)

    def frames(self) -> set[str]:
        return set(self._edges) | {e.parent for e in self._edges.values()}

    def edges(self) -> list[tuple[str, str, bool, int, int]]:
        """(parent, child, static, oldest_ns, newest_ns) of every edge."""
        return [(e.parent, e.child, e.static, e.stamps[0], e.stamps[-1]) for e in self._edges.values()]

    def _ancestors(self, frame: str) -> list[str]:
        """``frame`` and its parents up to the root of its tree."""
        chain = [frame]
        while (edge := self._edges.get(chain[-1])) is not None:
            chain.append(edge.parent)
        return chain

    def _path(self, target: str, source: str) -> tuple[list[_Edge], list[_Edge]]:
        """Edges from ``source`` up to the common ancestor, and from ``target`` up to it."""
        up_source = self._ancestors(source)
        up_target = self._ancestors(target)
        in_target = {f: i for i, f in enumerate(up_target)}
        for i, frame in enumerate(up_source):
            if frame in in_target:
                j = in_target[frame]
                return ([self._edges[f] for f in up_source[:i]], [self._edges[f] for f in up_target[:j]])
        root = up_target[-1]
        tree = sorted(f for f in self.frames() | {target} if self._ancestors(f)[-1] == root)
        raise MissingTransformError(target, source, tree, up_source[-1])

    def latest_common_stamp(self, target: str, source: str) -> int | None:
        """The newest stamp at which every dynamic edge between the frames has data (None if all static)."""
        a, b = self._path(target, source)
        newest = [e.stamps[-1] for e in a + b if not e.static]
        return min(newest) if newest else None

    def lookup(self, target: str, source: str, stamp_ns: int | None) -> RigidTransform:
        """The transform mapping ``source`` points into ``target`` at ``stamp_ns``.

        ``stamp_ns=None`` means the latest time every edge on the chain has data.
        Raises :class:`MissingTransformError` or :class:`ExtrapolationError`.
        """
        if target == source:
            return RigidTransform.identity()
        up_source, up_target = self._path(target, source)
        if stamp_ns is None:
            newest = [e.stamps[-1] for e in up_source + up_target if not e.static]
            stamp_ns = min(newest) if newest else 0
        result = RigidTransform.identity()
        for edge in up_source:  # source -> ... -> common ancestor
            result = edge.at(stamp_ns, self.tolerance_ns) @ result
        down = RigidTransform.identity()
        for edge in up_target:
            down = edge.at(stamp_ns, self.tolerance_ns) @ down
        return down.inverse() @ result

    def can_transform(self, target: str, source: str, stamp_ns: int | None) -> bool:
        try:
            self.lookup(target, source, stamp_ns)
        except TransformError:
            return False
        return True
