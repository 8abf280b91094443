"""Geometric primitives for building procedural worlds, and their rasterisation.

A cell is covered by a shape when its *centre* lies inside the shape. Axis-aligned boxes are
always at least one cell thick, so thin walls never vanish on a coarse grid.

The :class:`Furnisher` places obstacles into rectangular rooms with a clearance rule on their
axis-aligned bounding boxes (AABBs). The rule guarantees connectivity: obstacles whose AABBs,
expanded by ``gap``, are pairwise disjoint and stay ``gap`` away from the room walls (or sit flush
against exactly one wall) cannot enclose any part of the room, and every passage between them is
at least ``gap`` wide.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from crlam.errors import ConfigError
from crlam.limits import check_limit

__all__ = ["Box", "Canvas", "Disc", "Furnisher", "Polygon", "Shape", "blob", "l_shape", "rotated_box"]


@dataclass(frozen=True)
class Box:
    """Axis-aligned rectangle ``[x0, x1] x [y0, y1]`` in world metres."""

    x0: float
    y0: float
    x1: float
    y1: float

    @property
    def width(self) -> float:
        return self.x1 - self.x0

    @property
    def height(self) -> float:
        return self.y1 - self.y0

    @property
    def area(self) -> float:
        return self.width * self.height

    @property
    def center(self) -> tuple[float, float]:
        return (0.5 * (self.x0 + self.x1), 0.5 * (self.y0 + self.y1))

    @property
    def aabb(self) -> Box:
        return self

    def expanded(self, d: float) -> Box:
        """The box grown by ``d`` on every side (shrunk if ``d < 0``)."""
        return Box(self.x0 - d, self.y0 - d, self.x1 + d, self.y1 + d)

    def overlaps(self, other: Box) -> bool:
        """Whether the interiors intersect."""
        return self.x0 < other.x1 and other.x0 < self.x1 and self.y0 < other.y1 and other.y0 < self.y1

    def contains(self, other: Box, tol: float = 1e-9) -> bool:
        """Whether ``other`` lies inside this box."""
        return other.x0 >= self.x0 - tol and other.y0 >= self.y0 - tol and other.x1 <= self.x1 + tol and other.y1 <= self.y1 + tol

    def draw(self, canvas: Canvas, value: bool = True) -> None:
        canvas.fill_box(self, value)


@dataclass(frozen=True)
class Disc:
    """Disc of centre ``(cx, cy)`` and radius ``r`` (m)."""

    cx: float
    cy: float
    r: float

    @property
    def aabb(self) -> Box:
        return Box(self.cx - self.r, self.cy - self.r, self.cx + self.r, self.cy + self.r)

    def draw(self, canvas: Canvas, value: bool = True) -> None:
        canvas.fill_disc(self.cx, self.cy, self.r, value)


@dataclass(frozen=True)
class Polygon:
    """Simple polygon; ``vertices`` is a tuple of ``(x, y)`` in metres (either orientation)."""

    vertices: tuple[tuple[float, float], ...]

    @property
    def aabb(self) -> Box:
        v = np.asarray(self.vertices)
        return Box(float(v[:, 0].min()), float(v[:, 1].min()), float(v[:, 0].max()), float(v[:, 1].max()))

    def draw(self, canvas: Canvas, value: bool = True) -> None:
        canvas.fill_polygon(np.asarray(self.vertices, dtype=np.float64), value)


Shape = Box | Disc | Polygon


def _poly(points: NDArray[np.float64]) -> Polygon:
    return Polygon(tuple((float(x), float(y)) for x, y in points))


def rotated_box(cx: float, cy: float, w: float, h: float, angle: float) -> Polygon:
    """Rectangle ``w x h`` (m) centred at ``(cx, cy)``, rotated by ``angle`` (rad)."""
    local = np.array([[-w, -h], [w, -h], [w, h], [-w, h]]) * 0.5
    c, s = math.cos(angle), math.sin(angle)
    pts = local @ np.array([[c, s], [-s, c]]) + np.array([cx, cy])
    return _poly(pts)


def l_shape(cx: float, cy: float, a: float, b: float, t: float, angle: float) -> Polygon:
    """L-shaped exhibit: arms of lengths ``a`` (along x) and ``b`` (along y), thickness ``t``.

    The corner of the L is at ``(cx, cy)`` before rotation by ``angle`` (rad) about that point.
    """
    local = np.array([[0, 0], [a, 0], [a, t], [t, t], [t, b], [0, b]], dtype=np.float64)
    local -= np.array([a, b]) * 0.25  # roughly centre the shape on (cx, cy)
    c, s = math.cos(angle), math.sin(angle)
    pts = local @ np.array([[c, s], [-s, c]]) + np.array([cx, cy])
    return _poly(pts)


def blob(cx: float, cy: float, radius: float, rng: np.random.Generator, n_vertices: int = 8) -> Polygon:
    """Irregular star-shaped polygon around ``(cx, cy)`` with mean radius ``radius`` (m)."""
    angles = np.sort(rng.uniform(0.0, 2.0 * math.pi, n_vertices))
    radii = radius * rng.uniform(0.55, 1.25, n_vertices)
    pts = np.stack([cx + radii * np.cos(angles), cy + radii * np.sin(angles)], axis=1)
    return _poly(pts)


class Canvas:
    """A boolean raster being drawn on, in world coordinates.

    Parameters
    ----------
    width, height:
        Extent (m); the grid has ``round(width / resolution)`` columns.
    resolution:
        Cell size (m).
    origin:
        World ``(x, y)`` of the lower-left corner of cell ``[0, 0]``.
    """

    def __init__(self, width: float, height: float, resolution: float, origin: tuple[float, float] = (0.0, 0.0)):
        self.resolution = float(resolution)
        self.origin = np.array(origin, dtype=np.float64)
        if not (np.isfinite(resolution) and resolution > 0 and np.isfinite(width) and np.isfinite(height)):
            raise ConfigError(f"a world canvas needs a finite size and cell size > 0, got {width} x {height} m at {resolution} m")
        check_limit(
            "map_cells",
            round(width / resolution) * round(height / resolution),
            f"a {width:g} m x {height:g} m world at {resolution:g} m cells",
        )
        self.nx = round(width / resolution)
        self.ny = round(height / resolution)
        self.grid = np.zeros((self.ny, self.nx), dtype=bool)

    def _range(self, lo: float, hi: float, o: float, n: int) -> tuple[int, int]:
        """Index range ``[i0, i1)`` of cells whose centres lie in ``[lo, hi)`` along one axis."""
        r = self.resolution
        i0 = math.ceil((lo - o) / r - 0.5 - 1e-9)
        i1 = math.ceil((hi - o) / r - 0.5 - 1e-9)
        if i1 <= i0:  # thinner than a cell: keep the cell containing the middle
            i0 = math.floor((0.5 * (lo + hi) - o) / r)
            i1 = i0 + 1
        return max(i0, 0), min(i1, n)

    def fill_box(self, box: Box, value: bool = True) -> None:
        """Set the cells of an axis-aligned box."""
        x0, x1 = self._range(box.x0, box.x1, self.origin[0], self.nx)
        y0, y1 = self._range(box.y0, box.y1, self.origin[1], self.ny)
        if x0 < x1 and y0 < y1:
            self.grid[y0:y1, x0:x1] = value

    def _window(self, box: Box) -> tuple[slice, slice, NDArray[np.float64], NDArray[np.float64]] | None:
        """Slices of the cells around ``box`` and the world coordinates of their centres."""
        x0, x1 = self._range(box.x0 - self.resolution, box.x1 + self.resolution, self.origin[0], self.nx)
        y0, y1 = self._range(box.y0 - self.resolution, box.y1 + self.resolution, self.origin[1], self.ny)
        if x0 >= x1 or y0 >= y1:
            return None
        xs = self.origin[0] + (np.arange(x0, x1) + 0.5) * self.resolution
        ys = self.origin[1] + (np.arange(y0, y1) + 0.5) * self.resolution
        return slice(y0, y1), slice(x0, x1), xs[None, :], ys[:, None]

    def fill_disc(self, cx: float, cy: float, r: float, value: bool = True) -> None:
        """Set the cells whose centre is within ``r`` of ``(cx, cy)`` (at least the centre cell)."""
        win = self._window(Disc(cx, cy, r).aabb)
        if win is None:
            return
        sy, sx, xs, ys = win
        inside = (xs - cx) ** 2 + (ys - cy) ** 2 <= r * r
        self.grid[sy, sx][inside] = value
        ix = math.floor((cx - self.origin[0]) / self.resolution)
        iy = math.floor((cy - self.origin[1]) / self.resolution)
        if 0 <= ix < self.nx and 0 <= iy < self.ny:
            self.grid[iy, ix] = value

    def fill_polygon(self, vertices: NDArray[np.float64], value: bool = True) -> None:
        """Set the cells whose centre is inside the polygon ``(k, 2)`` (even-odd rule)."""
        v = np.asarray(vertices, dtype=np.float64)
        win = self._window(_poly(v).aabb)
        if win is None:
            return
        sy, sx, xs, ys = win
        inside = np.zeros((ys.shape[0], xs.shape[1]), dtype=bool)
        for (xa, ya), (xb, yb) in zip(v, np.roll(v, -1, axis=0)):
            if ya == yb:
                continue
            # Crossing test: the edge straddles the horizontal line through the centre, and the
            # crossing lies right of it. Half-open in y so shared vertices count once.
            straddle = (ya > ys) != (yb > ys)
            x_cross = xa + (ys - ya) * (xb - xa) / (yb - ya)
            inside ^= straddle & (xs < x_cross)
        self.grid[sy, sx][inside] = value


_BUCKET = 4.0  # m, spatial-hash cell of Furnisher


class Furnisher:
    """Places obstacles in rectangular rooms with an AABB clearance rule (see module docstring).

    Parameters
    ----------
    gap:
        Minimum free distance (m) between obstacle AABBs, and between free-standing obstacles
        and room walls.
    keepouts:
        Boxes no obstacle may come within ``gap`` of (e.g. the approach zones of doors).
    """

    def __init__(self, gap: float, keepouts: list[Box] | None = None):
        self.gap = float(gap)
        self.shapes: list[Shape] = []
        self.groups: list[list[Shape]] = []
        # Blocked boxes (keep-outs and placed AABBs) in a spatial hash of _BUCKET-metre cells,
        # so a placement test only looks at nearby boxes.
        self._buckets: dict[tuple[int, int], list[Box]] = {}
        for b in keepouts or []:
            self._block(b)

    def _keys(self, box: Box) -> list[tuple[int, int]]:
        i0, i1 = math.floor(box.x0 / _BUCKET), math.floor(box.x1 / _BUCKET)
        j0, j1 = math.floor(box.y0 / _BUCKET), math.floor(box.y1 / _BUCKET)
        return [(i, j) for i in range(i0, i1 + 1) for j in range(j0, j1 + 1)]

    def _block(self, box: Box) -> None:
        for key in self._keys(box):
            self._buckets.setdefault(key, []).append(box)

    def _free(self, aabb: Box, room: Box, flush: str | None) -> bool:
        g = self.gap
        grown = aabb.expanded(g)
        if flush is not None:
            # Flush against one wall: no gap on that side, the full gap on the three others.
            grown = Box(
                aabb.x0 if flush == "left" else grown.x0,
                aabb.y0 if flush == "bottom" else grown.y0,
                aabb.x1 if flush == "right" else grown.x1,
                aabb.y1 if flush == "top" else grown.y1,
            )
        if not room.contains(grown):
            return False
        return not any(grown.overlaps(b) for key in self._keys(grown) for b in self._buckets.get(key, ()))

    def place(self, shapes: Shape | list[Shape], room: Box, flush: str | None = None) -> bool:
        """Add ``shapes`` (treated as one group with a joint AABB) if the rule allows it."""
        group = shapes if isinstance(shapes, list) else [shapes]
        boxes = [s.aabb for s in group]
        aabb = Box(min(b.x0 for b in boxes), min(b.y0 for b in boxes), max(b.x1 for b in boxes), max(b.y1 for b in boxes))
        if not self._free(aabb, room, flush):
            return False
        self._block(aabb)
        self.shapes.extend(group)
        self.groups.append(group)
        return True

    def draw(self, canvas: Canvas) -> None:
        """Rasterise every placed shape."""
        for s in self.shapes:
            s.draw(canvas, True)
