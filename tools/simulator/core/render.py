"""RGB and registered depth from a pinhole camera by vectorised ray casting.

Every pixel's ray is intersected analytically with the room box (floor, ceiling, outer
walls), with the axis-aligned boxes (inner walls, furniture) and with the people's
ellipsoids. Boxes and ellipsoids are only tested on the pixels of their projected
bounding rectangle, so a person costs a few thousand pixels, not the whole image.
Rays are ``d = R_map_cam @ ((u - cx) / fx, (v - cy) / fy, 1)``, so the ray parameter
``t`` of a hit *is* the depth along the optical axis.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from common.geometry.transforms import PinholeCamera
from tools.simulator.core.apartment import Apartment
from tools.simulator.core.body import Ellipsoids

__all__ = ["DEPTH_MAX_M", "RenderResult", "Renderer", "default_camera", "depth_sigma"]

NEAR_M = 0.1
#: Depth beyond this range is reported invalid (0), like a structured-light sensor.
DEPTH_MAX_M = 8.0
_LIGHT = np.array([0.35, -0.45, 0.82], dtype=np.float32) / np.linalg.norm([0.35, -0.45, 0.82])
_AMBIENT, _DIFFUSE, _HEADLIGHT = 0.38, 0.42, 0.28
_CUBE = np.array([[sx, sy, sz] for sx in (-1, 1) for sy in (-1, 1) for sz in (-1, 1)], np.float64)
#: The 12 edges of a box whose 8 corners are numbered by bits (x: 1, y: 2, z: 4).
_EDGES = np.array([(a, a | bit) for a in range(8) for bit in (1, 2, 4) if not a & bit])


def depth_sigma(z: np.ndarray) -> np.ndarray:
    """Standard deviation (m) of the depth noise at depth ``z`` (m): 1.425e-3 z^2 (Kinect-class)."""
    return 1.425e-3 * np.square(z)


def default_camera(width: int = 640, height: int = 480) -> PinholeCamera:
    """An Orbbec Astra / Kinect-like camera without distortion: f = 525 px at 640 wide, scaled
    with the width, the principal point at the image centre."""
    f = 525.0 * width / 640.0
    cx, cy = (width - 1) / 2.0, (height - 1) / 2.0
    return PinholeCamera(np.array([[f, 0.0, cx], [0.0, f, cy], [0.0, 0.0, 1.0]]), width, height)


@dataclass
class RenderResult:
    """rgb (H, W, 3) uint8; depth_mm (H, W) uint16 (0 = invalid, noisy); depth_true (H, W)
    float32 metres without noise (inf where nothing was hit); owner (H, W) int16: person index
    of the pixel, -1 for the scene."""

    rgb: np.ndarray
    depth_mm: np.ndarray
    depth_true: np.ndarray
    owner: np.ndarray


class Renderer:
    """Renders an :class:`Apartment` and people; deterministic given the noise ``seed`` (an int
    or a tuple of ints, as ``numpy.random.default_rng`` takes)."""

    def __init__(
        self,
        apartment: Apartment,
        camera: PinholeCamera,
        seed: int | tuple[int, ...] = 0,
        rgb_noise: float = 3.0,
        depth_noise: bool = True,
    ) -> None:
        if camera.distorted or camera.K[0, 1] != 0.0:
            raise ValueError("the renderer casts straight rays: give it a camera without distortion or skew")
        self.apartment = apartment
        self.camera = camera
        w, h = camera.width, camera.height
        u, v = np.meshgrid(np.arange(w, dtype=np.float32), np.arange(h, dtype=np.float32))
        rx, ry = (u - camera.cx) / camera.fx, (v - camera.cy) / camera.fy
        self._rays_cam = (rx.astype(np.float32), ry.astype(np.float32))  # camera-frame ray x, y (z = 1)
        self._inv_norm = (1.0 / np.sqrt(rx * rx + ry * ry + 1.0)).astype(np.float32)
        boxes = list(apartment.boxes)
        self._box_lo = np.array([b.lo for b in boxes], dtype=np.float32).reshape(-1, 3)
        self._box_hi = np.array([b.hi for b in boxes], dtype=np.float32).reshape(-1, 3)
        self._box_colour = np.array([b.colour for b in boxes], dtype=np.float32).reshape(-1, 3)
        rng = np.random.default_rng(seed)
        self._rng = rng
        pad = 64
        self._depth_bank = rng.standard_normal((h + pad, w + pad)).astype(np.float32) if depth_noise else None
        self._rgb_bank = (rng.standard_normal((h + pad, w + pad, 3)) * rgb_noise).astype(np.float32)
        self._pad = pad
        self._static_key: bytes | None = None
        self._static: tuple[np.ndarray, np.ndarray] | None = None

    # -------------------------------------------------------------- helpers
    def _rect(self, corners_cam: np.ndarray) -> tuple[int, int, int, int] | None:
        """Pixel rectangle (u0, v0, u1, v1) covering the convex hull of points (8, 3) (a box's
        corners, camera frame), clipped to the near plane; None when nothing is in view."""
        z = corners_cam[:, 2]
        front = z >= NEAR_M
        if not front.any():
            return None
        pts = corners_cam[front]
        if not front.all():  # add where the box edges cross the near plane
            a, b = corners_cam[_EDGES[:, 0]], corners_cam[_EDGES[:, 1]]
            cross = (a[:, 2] >= NEAR_M) != (b[:, 2] >= NEAR_M)
            a, b = a[cross], b[cross]
            s = (NEAR_M - a[:, 2]) / (b[:, 2] - a[:, 2])
            pts = np.concatenate([pts, a + s[:, None] * (b - a)])
        cam = self.camera
        w, h = cam.width, cam.height
        u = cam.fx * pts[:, 0] / pts[:, 2] + cam.cx
        v = cam.fy * pts[:, 1] / pts[:, 2] + cam.cy
        u0, u1 = max(0, int(np.floor(u.min()))), min(w, int(np.ceil(u.max())) + 1)
        v0, v1 = max(0, int(np.floor(v.min()))), min(h, int(np.ceil(v.max())) + 1)
        if u0 >= u1 or v0 >= v1:
            return None
        return u0, v0, u1, v1

    @staticmethod
    def _shade(
        nx: np.ndarray,
        ny: np.ndarray,
        nz: np.ndarray,
        dx: np.ndarray,
        dy: np.ndarray,
        dz: np.ndarray,
        inv_norm: np.ndarray,
    ) -> np.ndarray:
        """Light factor for unit normals (components, any shape) seen along ray directions d."""
        lam = np.maximum(nx * _LIGHT[0] + ny * _LIGHT[1] + nz * _LIGHT[2], 0.0)
        head = np.maximum(-(nx * dx + ny * dy + nz * dz) * inv_norm, 0.0)
        return _AMBIENT + _DIFFUSE * lam + _HEADLIGHT * head

    # -------------------------------------------------------------- passes
    def _room(
        self, o: np.ndarray, d: list[np.ndarray], inv: list[np.ndarray], zbuf: np.ndarray, col: np.ndarray
    ) -> None:
        lo, hi = self.apartment.bounds_lo, self.apartment.bounds_hi
        ts = [np.where(d[a] > 0, (hi[a] - o[a]) * inv[a], (lo[a] - o[a]) * inv[a]) for a in range(3)]
        for t_a in ts:
            t_a[~(t_a >= 0)] = np.inf
        t = np.minimum(np.minimum(ts[0], ts[1]), ts[2])
        zbuf[...] = t
        on_z = ts[2] <= t
        on_x = (ts[0] <= t) & ~on_z
        floor = on_z & (d[2] < 0)
        ceiling = on_z & ~floor
        px = o[0] + d[0] * t
        py = o[1] + d[1] * t
        pz = o[2] + d[2] * t
        col[...] = (0.86, 0.84, 0.79)
        plank = np.floor(px / 0.18)
        grain = 0.86 + 0.14 * np.mod(plank * 37.0 + np.floor(py / 1.2 + plank * 0.5) * 11.0, 7.0) / 6.0
        col[floor] = np.array([0.6, 0.45, 0.3], np.float32) * grain[floor][:, None]
        col[ceiling] = (0.95, 0.95, 0.93)
        col[~on_z & (pz < 0.1)] = (0.35, 0.3, 0.26)  # skirting board
        zero = np.zeros_like(t)
        nx = np.where(on_x, -np.sign(d[0]), zero)
        ny = np.where(~on_x & ~on_z, -np.sign(d[1]), zero)
        nz = np.where(on_z, -np.sign(d[2]), zero)
        col *= self._shade(nx, ny, nz, d[0], d[1], d[2], self._inv_norm)[..., None]

    def _boxes(
        self,
        o: np.ndarray,
        r_cam: np.ndarray,
        d: list[np.ndarray],
        inv: list[np.ndarray],
        zbuf: np.ndarray,
        col: np.ndarray,
    ) -> None:
        lo, hi = self._box_lo, self._box_hi
        corners = np.stack(
            [
                np.stack(
                    [
                        np.where(m & 1, hi[:, 0], lo[:, 0]),
                        np.where(m & 2, hi[:, 1], lo[:, 1]),
                        np.where(m & 4, hi[:, 2], lo[:, 2]),
                    ],
                    -1,
                )
                for m in range(8)
            ],
            1,
        )
        corners_cam = (corners - o) @ r_cam  # (N, 8, 3): R^T (p - o)
        for i in range(len(lo)):
            rect = self._rect(corners_cam[i])
            if rect is None:
                continue
            u0, v0, u1, v1 = rect
            tn, tf = [], []
            for a in range(3):
                ia = inv[a][v0:v1, u0:u1]
                t1 = (lo[i, a] - o[a]) * ia
                t2 = (hi[i, a] - o[a]) * ia
                tn.append(np.minimum(t1, t2))
                tf.append(np.maximum(t1, t2))
            t_in = np.maximum(np.maximum(tn[0], tn[1]), tn[2])
            t_out = np.minimum(np.minimum(tf[0], tf[1]), tf[2])
            zsub = zbuf[v0:v1, u0:u1]
            hit = (t_in <= t_out) & (t_in > NEAR_M) & (t_in < zsub)
            if not hit.any():
                continue
            th = t_in[hit]
            dh = [d[a][v0:v1, u0:u1][hit] for a in range(3)]
            normal = [np.where(tn[a][hit] >= th, -np.sign(dh[a]), 0.0) for a in range(3)]
            inv_norm = self._inv_norm[v0:v1, u0:u1][hit]
            shade = self._shade(normal[0], normal[1], normal[2], dh[0], dh[1], dh[2], inv_norm)
            zsub[hit] = th
            col[v0:v1, u0:u1][hit] = self._box_colour[i] * shade[:, None]

    def _ellipsoids(
        self,
        o: np.ndarray,
        r_cam: np.ndarray,
        d: list[np.ndarray],
        e: Ellipsoids,
        zbuf: np.ndarray,
        col: np.ndarray,
        owner: np.ndarray,
    ) -> None:
        for i in range(len(e.centres)):
            corners_cam = (e.centres[i] + _CUBE * e.radius[i] - o) @ r_cam
            rect = self._rect(corners_cam)
            if rect is None:
                continue
            u0, v0, u1, v1 = rect
            dx, dy, dz = (d[a][v0:v1, u0:u1] for a in range(3))
            m = e.inv[i].astype(np.float32)
            ol = (m @ (o - e.centres[i])).astype(np.float32)
            l0 = m[0, 0] * dx + m[0, 1] * dy + m[0, 2] * dz
            l1 = m[1, 0] * dx + m[1, 1] * dy + m[1, 2] * dz
            l2 = m[2, 0] * dx + m[2, 1] * dy + m[2, 2] * dz
            a = l0 * l0 + l1 * l1 + l2 * l2
            b = l0 * ol[0] + l1 * ol[1] + l2 * ol[2]
            disc = b * b - a * (float(ol @ ol) - 1.0)
            hit = disc > 0
            if not hit.any():
                continue
            zsub = zbuf[v0:v1, u0:u1]
            ah, bh = a[hit], b[hit]
            th = (-bh - np.sqrt(disc[hit])) / ah
            ok = (th > NEAR_M) & (th < zsub[hit])
            if not ok.any():
                continue
            hit[hit] = ok
            th = th[ok]
            ux = ol[0] + l0[hit] * th
            uy = ol[1] + l1[hit] * th
            uz = ol[2] + l2[hit] * th
            nx = ux * m[0, 0] + uy * m[1, 0] + uz * m[2, 0]
            ny = ux * m[0, 1] + uy * m[1, 1] + uz * m[2, 1]
            nz = ux * m[0, 2] + uy * m[1, 2] + uz * m[2, 2]
            norm = 1.0 / np.sqrt(nx * nx + ny * ny + nz * nz)
            dhx, dhy, dhz = dx[hit], dy[hit], dz[hit]
            shade = self._shade(nx * norm, ny * norm, nz * norm, dhx, dhy, dhz, self._inv_norm[v0:v1, u0:u1][hit])
            albedo = np.broadcast_to(e.colour[i].astype(np.float32), (len(th), 3))
            if e.stripe_period[i] > 0:
                z = o[2] + dhz * th
                striped = np.floor(z / e.stripe_period[i]).astype(np.int64) % 2 == 1
                albedo = np.where(striped[:, None], e.stripe[i].astype(np.float32), albedo)
            zsub[hit] = th
            col[v0:v1, u0:u1][hit] = albedo * shade[:, None]
            owner[v0:v1, u0:u1][hit] = e.owner[i]

    # -------------------------------------------------------------- public
    def render(self, camera_pose: np.ndarray, people: Ellipsoids) -> RenderResult:
        """Render the scene seen from ``camera_pose`` (4, 4) T_map_camera (optical frame)."""
        r = camera_pose[:3, :3].astype(np.float32)
        o = camera_pose[:3, 3].astype(np.float32)
        h, w = self.camera.height, self.camera.width
        rc = self._rays_cam
        d = [rc[0] * r[a, 0] + rc[1] * r[a, 1] + r[a, 2] for a in range(3)]  # ray z in the camera is 1
        key = np.asarray(camera_pose, np.float64).tobytes()
        if key == self._static_key and self._static is not None:
            zbuf, col = self._static[0].copy(), self._static[1].copy()
        else:
            with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
                inv = [1.0 / da for da in d]
                zbuf = np.empty((h, w), np.float32)
                col = np.empty((h, w, 3), np.float32)
                self._room(o, d, inv, zbuf, col)
                self._boxes(o, r, d, inv, zbuf, col)
            self._static_key, self._static = key, (zbuf.copy(), col.copy())
        owner = np.full((h, w), -1, np.int16)
        with np.errstate(invalid="ignore"):
            self._ellipsoids(o, r, d, people, zbuf, col, owner)
        return self._finish(zbuf, col, owner)

    def _finish(self, zbuf: np.ndarray, col: np.ndarray, owner: np.ndarray) -> RenderResult:
        h, w = zbuf.shape
        oy, ox = (int(x) for x in self._rng.integers(0, self._pad, size=2))
        depth = zbuf
        if self._depth_bank is not None:
            depth = zbuf + depth_sigma(zbuf) * self._depth_bank[oy : oy + h, ox : ox + w]
        valid = (zbuf <= DEPTH_MAX_M) & (depth > 0)
        depth_mm = np.where(valid, np.rint(depth * 1000.0), 0.0).astype(np.uint16)
        noisy = col * 255.0 + self._rgb_bank[oy : oy + h, ox : ox + w]
        rgb = np.clip(noisy, 0.0, 255.0).astype(np.uint8)
        return RenderResult(rgb=rgb, depth_mm=depth_mm, depth_true=zbuf, owner=owner)
