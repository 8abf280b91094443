"""Room layouts for procedural worlds: walls, doors, rooms, obstacles, rasterisation and repair.

A :class:`Layout` is built in world metres, independent of the grid resolution, then rasterised
by :meth:`Layout.rasterize`, which also checks (and repairs) connectivity:

1. free space must be one 4-connected component; small enclosed pockets (inside clusters of
   clutter) are filled, a large disconnected region is a generation failure;
2. the space reachable by a disc robot (cells with clearance above ``robot_radius``) must be one
   component up to a small tolerance, otherwise generation also fails.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from numpy.typing import NDArray

from crlam.sim.grid_ops import distance_map, fill_small_components, label_components
from crlam.sim.shapes import Box, Canvas, Furnisher

__all__ = ["Door", "Layout", "LayoutError", "Room", "Split", "bsp_split", "place_doors"]


class LayoutError(RuntimeError):
    """A random layout violated a connectivity requirement; the caller draws another one."""


@dataclass(frozen=True)
class Room:
    """A rectangular room; ``box`` is its interior (inside the walls). ``kind`` says how it is furnished."""

    box: Box
    kind: str


@dataclass(frozen=True)
class Door:
    """An opening of width ``width`` (m) cleared through a wall; ``box`` is the cleared region."""

    box: Box
    width: float


@dataclass(frozen=True)
class Split:
    """A straight interior wall made by a binary space partition.

    ``vertical`` walls lie at ``x = pos`` and span ``y`` in ``[lo, hi]``; horizontal walls lie at
    ``y = pos`` and span ``x`` in ``[lo, hi]``. ``thickness`` is in metres.
    """

    vertical: bool
    pos: float
    lo: float
    hi: float
    thickness: float

    @property
    def box(self) -> Box:
        h = 0.5 * self.thickness
        if self.vertical:
            return Box(self.pos - h, self.lo, self.pos + h, self.hi)
        return Box(self.lo, self.pos - h, self.hi, self.pos + h)

    def opening(self, a: float, b: float) -> Box:
        """The part of the wall between ``a`` and ``b`` along its length."""
        h = 0.5 * self.thickness
        if self.vertical:
            return Box(self.pos - h, a, self.pos + h, b)
        return Box(a, self.pos - h, b, self.pos + h)

    def approach(self, a: float, b: float, depth: float) -> Box:
        """Zone of ``depth`` (m) on both sides of the opening ``[a, b]``, kept free of obstacles."""
        h = 0.5 * self.thickness + depth
        if self.vertical:
            return Box(self.pos - h, a - 0.3, self.pos + h, b + 0.3)
        return Box(a - 0.3, self.pos - h, b + 0.3, self.pos + h)


@dataclass
class Layout:
    """A procedural world in metres: outer walls, interior walls, doors, rooms and obstacles."""

    name: str
    width: float
    height: float
    walls: list[Box] = field(default_factory=list)
    doors: list[Door] = field(default_factory=list)
    rooms: list[Room] = field(default_factory=list)
    furniture: Furnisher = field(default_factory=lambda: Furnisher(1.0))

    def rasterize(
        self, resolution: float, robot_radius: float = 0.3, max_pocket_area: float = 6.0
    ) -> tuple[NDArray[np.bool_], int]:
        """Rasterise and check connectivity (see module docstring).

        Parameters
        ----------
        resolution:
            Cell size (m); the grid covers ``[0, width] x [0, height]``.
        robot_radius:
            Radius (m) of the robot whose reachable space must be connected.
        max_pocket_area:
            Enclosed free pockets up to this area (m²) are filled; a bigger one raises.

        Returns
        -------
        occupied:
            bool ``(ny, nx)``.
        n_filled:
            Number of pockets filled.

        Raises
        ------
        LayoutError
            If the free space or the robot-reachable space is not connected.
        """
        canvas = Canvas(self.width, self.height, resolution)
        for w in self.walls:
            canvas.fill_box(w, True)
        for d in self.doors:
            canvas.fill_box(d.box, False)
        self.furniture.draw(canvas)
        cell_area = resolution * resolution
        occ, n_filled, largest_other = fill_small_components(canvas.grid, int(max_pocket_area / cell_area))
        if largest_other:
            raise LayoutError(f"free space split: a detached region of {largest_other * cell_area:.1f} m²")
        # Robot-reachable space: clearance strictly above the radius (plus a rounding margin).
        reach = distance_map(occ, resolution, robot_radius + 2 * resolution) > robot_radius + 0.5 * resolution
        _, sizes = label_components(reach, connectivity=4)
        if len(sizes) > 2:
            main = sizes[1:].max()
            stray = sizes[1:].sum() - main
            # Concave clutter clusters can leave tiny robot-unreachable nooks; tolerate 0.5 %.
            if stray > 0.005 * sizes[1:].sum():
                raise LayoutError(f"robot-reachable space split: {stray * cell_area:.1f} m² detached")
        return occ, n_filled


def bsp_split(
    rng: np.random.Generator,
    interior: Box,
    wall: float,
    min_side: float,
    stop_below: float,
    hall_below: float,
    hall_probability: float,
) -> tuple[list[Box], list[Split]]:
    """Binary space partition of ``interior`` into rooms separated by walls of ``wall`` m.

    A region is a leaf when its longer side is below ``stop_below``, or, with probability
    ``hall_probability``, below ``hall_below`` (which gives the big halls). Children are at least
    ``min_side`` wide. Returns the leaf interiors and the walls, in a deterministic order.
    """
    leaves: list[Box] = []
    splits: list[Split] = []
    stack = [(interior, 0)]
    while stack:
        box, depth = stack.pop()
        longest = max(box.width, box.height)
        if longest < stop_below or (depth >= 1 and longest < hall_below and rng.random() < hall_probability):
            leaves.append(box)
            continue
        if abs(box.width - box.height) > 2.0:
            vertical = box.width > box.height
        else:
            vertical = bool(rng.random() < 0.5)
        start, length = (box.x0, box.width) if vertical else (box.y0, box.height)
        if length < 2 * min_side + wall:
            leaves.append(box)
            continue
        cut = float(np.clip(rng.uniform(0.3, 0.7) * length, min_side + wall / 2, length - min_side - wall / 2))
        pos = round((start + cut) * 20.0) / 20.0  # snap to 5 cm so walls align across resolutions
        h = wall / 2
        if vertical:
            splits.append(Split(True, pos, box.y0, box.y1, wall))
            a, b = Box(box.x0, box.y0, pos - h, box.y1), Box(pos + h, box.y0, box.x1, box.y1)
        else:
            splits.append(Split(False, pos, box.x0, box.x1, wall))
            a, b = Box(box.x0, box.y0, box.x1, pos - h), Box(box.x0, pos + h, box.x1, box.y1)
        stack.append((b, depth + 1))
        stack.append((a, depth + 1))
    return leaves, splits


def _junctions(s: Split, splits: list[Split]) -> list[float]:
    """Positions along ``s`` where perpendicular walls end against it."""
    out = []
    h = 0.5 * s.thickness
    for t in splits:
        if t.vertical == s.vertical or not (s.lo - 1e-6 <= t.pos <= s.hi + 1e-6):
            continue
        if abs(t.lo - (s.pos + h)) < 1e-6 or abs(t.hi - (s.pos - h)) < 1e-6:
            out.append(t.pos)
    return out


def _subtract(intervals: list[tuple[float, float]], a: float, b: float) -> list[tuple[float, float]]:
    out = []
    for lo, hi in intervals:
        if b <= lo or a >= hi:
            out.append((lo, hi))
            continue
        if a > lo:
            out.append((lo, a))
        if b < hi:
            out.append((b, hi))
    return out


def place_doors(
    rng: np.random.Generator,
    splits: list[Split],
    widths: tuple[float, float],
    wide: tuple[float, float],
    wide_probability: float,
    corner_clearance: float,
    approach_depth: float,
) -> tuple[list[Door], list[Box]]:
    """Cut doors in every BSP wall and return them with their approach zones (keep-outs).

    Every wall gets at least one door, away from wall ends and junctions by
    ``corner_clearance`` (m), so each door opens between two rooms without being half blocked
    by a perpendicular wall. As each BSP wall separates two sibling subtrees, one door per wall
    connects all rooms. Long walls get more doors; some get a wide opening (``wide``).

    Raises
    ------
    LayoutError
        If a wall has no room for a door.
    """
    doors: list[Door] = []
    keepouts: list[Box] = []
    for s in splits:
        h = 0.5 * s.thickness
        allowed = [(s.lo + corner_clearance, s.hi - corner_clearance)]
        for j in _junctions(s, splits):
            allowed = _subtract(allowed, j - h - corner_clearance, j + h + corner_clearance)
        length = s.hi - s.lo
        n_doors = 1 + int(length > 18.0) + int(length > 35.0) + int(rng.random() < 0.3)
        for k in range(n_doors):
            if rng.random() < wide_probability:
                width = float(rng.uniform(*wide))
            else:
                width = float(rng.uniform(*widths))
            fits = [(lo, hi) for lo, hi in allowed if hi - lo >= width]
            if not fits:
                width = widths[0]
                fits = [(lo, hi) for lo, hi in allowed if hi - lo >= width]
            if not fits:
                if k == 0:
                    raise LayoutError(f"no room for a door in wall at {s.pos:.2f}")
                break
            lengths = np.array([hi - lo - width for lo, hi in fits]) + 1e-3
            lo, hi = fits[int(rng.choice(len(fits), p=lengths / lengths.sum()))]
            a = round(float(rng.uniform(lo, hi - width)) * 20.0) / 20.0
            a = min(max(a, lo), hi - width)
            doors.append(Door(s.opening(a, a + width), width))
            keepouts.append(s.approach(a, a + width, approach_depth))
            allowed = _subtract(allowed, a - 2.0, a + width + 2.0)
    return doors, keepouts


def outer_walls(width: float, height: float, thickness: float) -> list[Box]:
    """The four boundary walls of a ``width x height`` world."""
    t = thickness
    return [
        Box(0.0, 0.0, width, t),
        Box(0.0, height - t, width, height),
        Box(0.0, 0.0, t, height),
        Box(width - t, 0.0, width, height),
    ]
