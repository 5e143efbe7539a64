"""The apartment: a room box (floor, ceiling, outer walls), inner walls, furniture, seats,
and a grid planner that keeps walkers clear of all of them.

Map frame: x east, y north, z up, metres; the floor is z = 0.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from scipy.sparse import csr_matrix
from scipy.sparse.csgraph import dijkstra

__all__ = ["Apartment", "Box", "Seat", "default_apartment"]


def _shifted(offset: int, n: int) -> tuple[slice, slice]:
    """Slices selecting index k and k + offset along an axis of length n."""
    return (slice(0, n - offset), slice(offset, n)) if offset >= 0 else (slice(-offset, n), slice(0, n + offset))


@dataclass(frozen=True)
class Box:
    """An axis-aligned solid: ``lo`` and ``hi`` corners (3,) in the map frame, RGB albedo in [0, 1]."""

    name: str
    lo: tuple[float, float, float]
    hi: tuple[float, float, float]
    colour: tuple[float, float, float]
    kind: str = "furniture"  # "wall" or "furniture"


@dataclass(frozen=True)
class Seat:
    """Where a person sits: seat centre (x, y), seat height, and the yaw the sitter faces."""

    name: str
    x: float
    y: float
    height: float
    yaw: float


def _chair(name: str, x: float, y: float, yaw: float, colour: tuple[float, float, float]) -> tuple[list[Box], Seat]:
    """A chair (seat + backrest) centred at (x, y) whose sitter faces ``yaw`` (a multiple of pi/2)."""
    s, h = 0.23, 0.45
    seat = Box(f"{name}-seat", (x - s, y - s, h - 0.05), (x + s, y + s, h), colour)
    dx, dy = -np.cos(yaw), -np.sin(yaw)  # the backrest is behind the sitter
    bx, by = x + dx * (s - 0.03), y + dy * (s - 0.03)
    hx, hy = (0.03, s) if abs(dx) > 0.5 else (s, 0.03)
    back = Box(f"{name}-back", (bx - hx, by - hy, h), (bx + hx, by + hy, 0.95), colour)
    legs = [
        Box(
            f"{name}-leg{i}",
            (x + sx * s - 0.03, y + sy * s - 0.03, 0.0),
            (x + sx * s + 0.03, y + sy * s + 0.03, h - 0.05),
            (0.2, 0.2, 0.2),
        )
        for i, (sx, sy) in enumerate(((-0.85, -0.85), (0.85, -0.85), (-0.85, 0.85), (0.85, 0.85)))
    ]
    return [seat, back, *legs], Seat(name, x, y, h, yaw)


@dataclass
class Apartment:
    """Room bounds, solids, seats and named places, plus a walkable-space planner."""

    bounds_lo: tuple[float, float, float]
    bounds_hi: tuple[float, float, float]
    boxes: list[Box]
    seats: dict[str, Seat]
    places: dict[str, tuple[float, float]]
    resolution: float = 0.1
    _grids: dict[float, tuple[np.ndarray, csr_matrix]] = field(default_factory=dict, repr=False)

    # ------------------------------------------------------------------ occupancy
    def footprints(self, min_height: float = 0.05) -> np.ndarray:
        """(N, 4) x0, y0, x1, y1 of every solid reaching below 2 m (walkers must avoid them)."""
        return np.array(
            [[b.lo[0], b.lo[1], b.hi[0], b.hi[1]] for b in self.boxes if b.hi[2] > min_height and b.lo[2] < 2.0]
        )

    def clearance_ok(self, xy: np.ndarray, radius: float) -> np.ndarray:
        """(N,) bool: points (N, 2) at least ``radius`` from every footprint and inside the walls."""
        p = np.atleast_2d(np.asarray(xy, dtype=np.float64))
        fp = self.footprints()
        dx = np.maximum(np.maximum(fp[None, :, 0] - p[:, None, 0], p[:, None, 0] - fp[None, :, 2]), 0.0)
        dy = np.maximum(np.maximum(fp[None, :, 1] - p[:, None, 1], p[:, None, 1] - fp[None, :, 3]), 0.0)
        free = np.all(np.hypot(dx, dy) >= radius, axis=1)
        lo, hi = np.array(self.bounds_lo[:2]), np.array(self.bounds_hi[:2])
        return free & np.all((p >= lo + radius) & (p <= hi - radius), axis=1)

    def _grid(self, radius: float) -> tuple[np.ndarray, csr_matrix]:
        if radius not in self._grids:
            r = self.resolution
            xs = np.arange(self.bounds_lo[0] + r / 2, self.bounds_hi[0], r)
            ys = np.arange(self.bounds_lo[1] + r / 2, self.bounds_hi[1], r)
            gx, gy = np.meshgrid(xs, ys, indexing="ij")
            # a little extra margin, so diagonal steps past box corners keep the full radius
            free = self.clearance_ok(np.stack([gx.ravel(), gy.ravel()], 1), radius + 0.02).reshape(gx.shape)
            nx, ny = free.shape
            idx = np.arange(nx * ny).reshape(nx, ny)
            rows, cols, w = [], [], []
            for ox, oy in ((1, 0), (0, 1), (1, 1), (1, -1)):
                ax, bx = _shifted(ox, nx)
                ay, by = _shifted(oy, ny)
                ok = free[ax, ay] & free[bx, by]
                rows.append(idx[ax, ay][ok])
                cols.append(idx[bx, by][ok])
                w.append(np.full(int(ok.sum()), r * np.hypot(ox, oy)))
            rr, cc, ww = np.concatenate(rows), np.concatenate(cols), np.concatenate(w)
            graph = csr_matrix(
                (np.concatenate([ww, ww]), (np.concatenate([rr, cc]), np.concatenate([cc, rr]))),
                shape=(nx * ny, nx * ny),
            )
            self._grids[radius] = (free, graph)
        return self._grids[radius]

    def _cell(self, xy: np.ndarray, radius: float) -> tuple[int, int]:
        """The nearest free grid cell that ``xy`` reaches in a straight, clear line."""
        free, _ = self._grid(radius)
        cells = np.argwhere(free)
        r = self.resolution
        centres = np.asarray(self.bounds_lo[:2]) + (cells + 0.5) * r
        order = np.argsort(np.linalg.norm(centres - xy, axis=1))[:25]
        for k in order:
            if self.segment_free(xy, centres[k], radius):
                return int(cells[k, 0]), int(cells[k, 1])
        return int(cells[order[0], 0]), int(cells[order[0], 1])

    def _centre(self, i: int, j: int) -> np.ndarray:
        r = self.resolution
        return np.array([self.bounds_lo[0] + (i + 0.5) * r, self.bounds_lo[1] + (j + 0.5) * r])

    @staticmethod
    def _along(a: np.ndarray, b: np.ndarray) -> np.ndarray:
        """Points (K, 2) every 5 cm or less on the segment a -> b, both ends included."""
        n = max(2, int(np.ceil(np.linalg.norm(b - a) / 0.05)) + 1)
        return a[None, :] + np.linspace(0.0, 1.0, n)[:, None] * (b - a)[None, :]

    def segment_free(self, a: np.ndarray, b: np.ndarray, radius: float) -> bool:
        """Whether the straight segment a -> b (2,) keeps ``radius`` clearance everywhere."""
        return bool(np.all(self.clearance_ok(self._along(a, b), radius)))

    def line_of_sight(self, a: np.ndarray, b: np.ndarray, eye_height: float = 1.2) -> bool:
        """Whether nothing that reaches above ``eye_height`` (walls, door frames, tall shelves)
        stands on the straight segment a -> b (2,): a camera at that height sees across low
        furniture, not through walls."""
        fp = self.footprints(min_height=eye_height)
        pts = self._along(np.asarray(a, float), np.asarray(b, float))
        inside = ((pts[:, None, 0] > fp[None, :, 0]) & (pts[:, None, 0] < fp[None, :, 2])
                  & (pts[:, None, 1] > fp[None, :, 1]) & (pts[:, None, 1] < fp[None, :, 3]))
        return not bool(inside.any())

    def plan(self, start: np.ndarray, goal: np.ndarray, radius: float) -> np.ndarray:
        """(K, 2) waypoints from ``start`` to ``goal`` keeping ``radius`` clearance (shortest grid path,
        then shortcut where the straight line is free). Raises ValueError if either end is blocked."""
        start, goal = np.asarray(start, float), np.asarray(goal, float)
        for what, p in (("start", start), ("goal", goal)):
            if not self.clearance_ok(p, radius)[0]:
                raise ValueError(f"{what} {p.round(2).tolist()} is not {radius} m clear of walls and furniture")
        if self.segment_free(start, goal, radius):
            return np.stack([start, goal])
        free, graph = self._grid(radius)
        ny = free.shape[1]
        si, sj = self._cell(start, radius)
        gi, gj = self._cell(goal, radius)
        _, pred = dijkstra(graph, indices=si * ny + sj, return_predecessors=True)
        node, cells = gi * ny + gj, []
        while node >= 0:
            cells.append(node)
            node = pred[node]
        if cells[-1] != si * ny + sj:
            raise ValueError(f"no free path from {start.round(2).tolist()} to {goal.round(2).tolist()}")
        path = [start] + [self._centre(c // ny, c % ny) for c in reversed(cells[1:-1])] + [goal]
        out, i = [path[0]], 0
        while i < len(path) - 1:  # string pulling
            j = len(path) - 1
            while j > i + 1 and not self.segment_free(path[i], path[j], radius):
                j -= 1
            out.append(path[j])
            i = j
        return np.stack(out)

    def random_free_point(
        self, rng: np.random.Generator, region: tuple[float, float, float, float], radius: float
    ) -> np.ndarray:
        """A uniformly drawn point of ``region`` (x0, y0, x1, y1) that is ``radius`` clear."""
        for _ in range(1000):
            p = rng.uniform(region[:2], region[2:])
            if self.clearance_ok(p, radius)[0]:
                return p
        raise ValueError(f"no free point in region {region}")


def default_apartment() -> Apartment:
    """A 9 x 7 m apartment: living room with a sofa (west), dining table and four chairs (east) (x < 6),
    and a bedroom/kitchen behind a partition wall with a door at y in [3.6, 4.8]."""
    wall = (0.85, 0.83, 0.78)
    wood = (0.55, 0.36, 0.2)
    boxes = [
        Box("partition-south", (6.0, 0.0, 0.0), (6.12, 3.6, 2.6), wall, "wall"),
        Box("partition-north", (6.0, 4.8, 0.0), (6.12, 7.0, 2.6), wall, "wall"),
        # sofa along the west side facing east; people walking behind it are hidden from the knees down
        Box("sofa-seat", (1.0, 3.0, 0.0), (1.9, 5.2, 0.45), (0.25, 0.35, 0.55)),
        Box("sofa-back", (1.0, 3.0, 0.45), (1.25, 5.2, 0.9), (0.22, 0.31, 0.5)),
        Box("sofa-arm-s", (1.25, 3.0, 0.45), (1.9, 3.2, 0.65), (0.22, 0.31, 0.5)),
        Box("sofa-arm-n", (1.25, 5.0, 0.45), (1.9, 5.2, 0.65), (0.22, 0.31, 0.5)),
        Box("tv-stand", (2.4, 6.55, 0.0), (3.8, 7.0, 0.5), (0.15, 0.15, 0.17)),
        Box("tv", (2.5, 6.85, 0.5), (3.7, 6.95, 1.2), (0.05, 0.05, 0.06)),
        Box("bookshelf", (0.0, 0.8, 0.0), (0.4, 2.2, 1.8), wood),
        Box("table-top", (4.0, 4.9, 0.72), (5.2, 5.9, 0.77), wood),
        *[
            Box(f"table-leg{i}", (x, y, 0.0), (x + 0.06, y + 0.06, 0.72), wood)
            for i, (x, y) in enumerate(((4.02, 4.92), (5.12, 4.92), (4.02, 5.82), (5.12, 5.82)))
        ],
        Box("counter", (8.3, 0.5, 0.0), (9.0, 3.0, 0.9), (0.7, 0.7, 0.72)),
        Box("bed", (7.0, 5.1, 0.0), (9.0, 7.0, 0.5), (0.75, 0.6, 0.6)),
    ]
    seats: dict[str, Seat] = {}
    chair_colour = (0.45, 0.28, 0.15)
    for name, x, y, yaw in (
        ("chair-w", 3.65, 5.4, 0.0),
        ("chair-e", 5.55, 5.4, np.pi),
        ("chair-s", 4.6, 4.55, np.pi / 2),
        ("chair-n", 4.6, 6.25, -np.pi / 2),
    ):
        parts, seat = _chair(name, x, y, yaw, chair_colour)
        boxes += parts
        seats[name] = seat
    seats["sofa-left"] = Seat("sofa-left", 1.5, 4.6, 0.45, 0.0)
    seats["sofa-right"] = Seat("sofa-right", 1.5, 3.6, 0.45, 0.0)
    places = {
        "door": (6.06, 4.2),
        "bedroom": (7.6, 3.8),
        "kitchen": (7.5, 1.5),
        "tv": (3.1, 6.2),
        "window": (0.6, 6.2),
        "hall": (4.4, 2.2),
        "shelf": (1.0, 1.5),
        "centre": (2.8, 3.8),
    }
    return Apartment((0.0, 0.0, 0.0), (9.0, 7.0, 2.6), boxes, seats, places)
