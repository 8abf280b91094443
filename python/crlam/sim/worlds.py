"""Procedural worlds built by the project (the default simulation data), and world lookup.

- :func:`museum_world`: 90 m x 90 m cluttered indoor "museum": halls, galleries and small
  cabinet rooms from a binary space partition, doors of at least 1.2 m, internal partitions
  with gaps, round and square pillars, exhibits (boxes, discs, L-shapes, glass cases) and
  irregular clutter.
- :func:`office_world`: a 20 m x 15 m office with a corridor, rooms, doors and furniture.

Both are deterministic functions of ``(seed, resolution)``: the layout is drawn in metres with a
``PCG64`` generator and only then rasterised, so a coarser grid shows the same building.
"""

from __future__ import annotations

import functools
import math
from collections.abc import Callable
from pathlib import Path

import numpy as np

from crlam.errors import ConfigError
from crlam.sim.layout import (
    Layout,
    LayoutError,
    Room,
    Split,
    bsp_split,
    outer_walls,
    place_doors,
)
from crlam.sim.shapes import Box, Disc, Furnisher, Shape, blob, l_shape, rotated_box
from crlam.sim.world import World

__all__ = ["WORLD_NAMES", "get_world", "museum_layout", "museum_world", "office_layout", "office_world"]

WORLD_NAMES = ("museum", "office")
_MAX_ATTEMPTS = 20


def _rng(seed: int, attempt: int) -> np.random.Generator:
    if seed < 0:
        raise ConfigError(f"seed must be >= 0, got {seed}")
    return np.random.Generator(np.random.PCG64(np.random.SeedSequence([seed, attempt])))


def _uniform_point(rng: np.random.Generator, box: Box, margin: float) -> tuple[float, float]:
    return (
        float(rng.uniform(box.x0 + margin, max(box.x0 + margin, box.x1 - margin))),
        float(rng.uniform(box.y0 + margin, max(box.y0 + margin, box.y1 - margin))),
    )


def _flush_box(rng: np.random.Generator, room: Box, length: float, depth: float) -> tuple[Box, str]:
    """A box of ``length x depth`` (m) against a random wall of ``room``; returns it and the side."""
    side = ("left", "right", "bottom", "top")[int(rng.integers(4))]
    if side in ("left", "right"):
        y = float(rng.uniform(room.y0, max(room.y0, room.y1 - length)))
        x0 = room.x0 if side == "left" else room.x1 - depth
        return Box(x0, y, x0 + depth, y + length), side
    x = float(rng.uniform(room.x0, max(room.x0, room.x1 - length)))
    y0 = room.y0 if side == "bottom" else room.y1 - depth
    return Box(x, y0, x + length, y0 + depth), side


def _place_n(n: int, make: Callable[[], bool], attempts: int = 12) -> int:
    """Try to place ``n`` objects, each with up to ``attempts`` random draws; return how many fit."""
    placed = 0
    for _ in range(n):
        for _ in range(attempts):
            if make():
                placed += 1
                break
    return placed


# ------------------------------------------------------------------------------ museum
def _exhibit(rng: np.random.Generator, x: float, y: float, big: bool) -> Shape | list[Shape]:
    """One free-standing exhibit of a random kind centred near ``(x, y)``."""
    s = 1.0 if big else 0.6
    kind = int(rng.integers(6))
    angle = float(rng.integers(0, 12)) * math.pi / 12.0
    if kind == 0:  # plinth or display table, possibly rotated
        return rotated_box(x, y, rng.uniform(1.5, 4.5) * s, rng.uniform(0.8, 2.0) * s, angle)
    if kind == 1:  # round sculpture base
        return Disc(x, y, float(rng.uniform(0.5, 1.4) * s))
    if kind == 2:  # L-shaped display wall
        return l_shape(x, y, rng.uniform(2.0, 4.0) * s, rng.uniform(1.5, 3.5) * s, rng.uniform(0.3, 0.6), angle)
    if kind == 3:  # glass cases in a row
        n, w, gap = int(rng.integers(2, 5)), float(rng.uniform(0.5, 0.9)), float(rng.uniform(0.15, 0.35))
        return [Box(x + i * (w + gap), y, x + i * (w + gap) + w, y + w) for i in range(n)]
    if kind == 4:  # statue group: a few small discs and boxes close together
        out: list[Shape] = []
        for _ in range(int(rng.integers(2, 5))):
            dx, dy = rng.uniform(-1.0, 1.0, 2) * s
            if rng.random() < 0.5:
                out.append(Disc(x + dx, y + dy, float(rng.uniform(0.2, 0.45))))
            else:
                out.append(rotated_box(x + dx, y + dy, rng.uniform(0.4, 0.8), rng.uniform(0.4, 0.8), angle))
        return out
    # irregular installation
    return blob(x, y, float(rng.uniform(0.5, 1.1) * s), rng, int(rng.integers(6, 11)))


def _clutter(rng: np.random.Generator, x: float, y: float) -> list[Shape]:
    """A cluster of 1-4 irregular blobs (crates, bins, plants, debris), up to ~2 m across."""
    out: list[Shape] = []
    for _ in range(int(rng.integers(1, 5))):
        dx, dy = rng.uniform(-0.7, 0.7, 2)
        out.append(blob(x + dx, y + dy, float(rng.uniform(0.2, 0.6)), rng, int(rng.integers(5, 10))))
    return out


def _colonnade(rng: np.random.Generator, f: Furnisher, room: Box) -> None:
    """Rows of pillars, inset from the walls of a hall; round or square per hall."""
    round_pillars = rng.random() < 0.5
    r = float(rng.uniform(0.25, 0.45))
    pitch = float(rng.uniform(4.5, 7.0))
    inset = float(rng.uniform(2.4, 3.6))
    xs = np.arange(room.x0 + inset, room.x1 - inset + 1e-9, pitch)
    ys = np.arange(room.y0 + inset, room.y1 - inset + 1e-9, pitch)
    for i, x in enumerate(xs):
        for j, y in enumerate(ys):
            ring = i in (0, len(xs) - 1) or j in (0, len(ys) - 1)
            if not ring and rng.random() > 0.35:
                continue
            pillar: Shape = Disc(float(x), float(y), r) if round_pillars else Box(x - r, y - r, x + r, y + r)
            f.place(pillar, room)


def _partition(rng: np.random.Generator, room: Box) -> list[Shape]:
    """A free-standing partition wall with a gap in the middle (exhibition panels)."""
    length = float(rng.uniform(5.0, min(11.0, 0.6 * max(room.width, room.height))))
    gap = float(rng.uniform(1.5, 2.5))
    t = 0.2
    x, y = _uniform_point(rng, room, 2.0)
    piece = 0.5 * (length - gap)
    if rng.random() < 0.5:
        return [Box(x, y, x + piece, y + t), Box(x + piece + gap, y, x + length, y + t)]
    return [Box(x, y, x + t, y + piece), Box(x, y + piece + gap, x + t, y + length)]


def _furnish_museum_room(rng: np.random.Generator, f: Furnisher, room: Room) -> None:
    """Fill one museum room according to its kind; densities scale with the floor area."""
    b = room.box
    g = f.gap
    area = b.area

    def exhibit(big: bool) -> Callable[[], bool]:
        return lambda: f.place(_exhibit(rng, *_uniform_point(rng, b, g), big), b)

    def clutter() -> bool:
        return f.place(_clutter(rng, *_uniform_point(rng, b, g)), b)

    def wall_case() -> bool:
        box, side = _flush_box(rng, b, float(rng.uniform(1.2, 4.0)), float(rng.uniform(0.4, 0.9)))
        return f.place(box, b, flush=side)

    if room.kind == "hall":
        if rng.random() < 0.8:
            _colonnade(rng, f, b)
        _place_n(int(rng.integers(1, 4)), lambda: f.place(_partition(rng, b), b))
        _place_n(int(area / 45.0), exhibit(True))
        _place_n(int(area / 60.0), exhibit(False))
        _place_n(int(area / 50.0), clutter)
        _place_n(int(rng.integers(3, 9)), wall_case)
    elif room.kind == "gallery":
        _place_n(int(area / 30.0), exhibit(bool(rng.random() < 0.5)))
        _place_n(int(area / 40.0), clutter)
        if rng.random() < 0.3:
            _place_n(int(rng.integers(2, 5)), lambda: f.place(Disc(*_uniform_point(rng, b, g), 0.3), b))
        _place_n(int(rng.integers(4, 10)), wall_case)
    else:  # cabinet room: a grid of glass cases, or a dense mix of small exhibits
        if rng.random() < 0.5:
            w = float(rng.uniform(0.6, 1.0))
            pitch = w + g + float(rng.uniform(0.05, 0.6))
            for x in np.arange(b.x0 + g + 0.1, b.x1 - g - w, pitch):
                for y in np.arange(b.y0 + g + 0.1, b.y1 - g - w, pitch):
                    if rng.random() < 0.7:
                        f.place(Box(float(x), float(y), float(x) + w, float(y) + w), b)
        else:
            _place_n(int(area / 15.0), exhibit(False))
        _place_n(int(area / 30.0) + 1, clutter)
        _place_n(int(rng.integers(2, 6)), wall_case)


def museum_layout(seed: int = 0, attempt: int = 0) -> Layout:
    """The museum layout in metres (before rasterisation) for ``(seed, attempt)``.

    See :func:`museum_world`. ``attempt`` selects another independent draw; it is used when a
    draw fails the connectivity checks.
    """
    rng = _rng(seed, attempt)
    size, outer, wall = 90.0, 0.4, 0.3
    interior = Box(outer, outer, size - outer, size - outer)
    leaves, splits = bsp_split(rng, interior, wall, min_side=6.0, stop_below=17.0, hall_below=34.0, hall_probability=0.35)
    doors, keepouts = place_doors(
        rng,
        splits,
        widths=(1.4, 2.4),
        wide=(3.0, 6.0),
        wide_probability=0.2,
        corner_clearance=0.8,
        approach_depth=1.6,
    )
    rooms = []
    for leaf in leaves:
        kind = "hall" if leaf.area >= 330.0 else ("gallery" if leaf.area >= 110.0 else "cabinet")
        rooms.append(Room(leaf, kind))
    furn = Furnisher(gap=1.2, keepouts=keepouts)
    for room in rooms:
        _furnish_museum_room(rng, furn, room)
    walls = outer_walls(size, size, outer) + [s.box for s in splits]
    return Layout("museum", size, size, walls, doors, rooms, furn)


@functools.lru_cache(maxsize=8)
def _museum_grid(seed: int, resolution: float) -> tuple[np.ndarray, int]:
    last: Exception | None = None
    for attempt in range(_MAX_ATTEMPTS):
        try:
            occ, _ = museum_layout(seed, attempt).rasterize(resolution, robot_radius=0.3)
        except LayoutError as exc:
            last = exc
            continue
        occ.setflags(write=False)
        return occ, attempt
    raise RuntimeError(f"no connected museum layout for seed {seed} in {_MAX_ATTEMPTS} attempts: {last}")


def museum_world(seed: int = 0, resolution: float = 0.05) -> World:
    """A 90 m x 90 m cluttered museum-like world (origin at (0, 0)).

    Parameters
    ----------
    seed:
        Non-negative integer; the same seed always gives the same world.
    resolution:
        Cell size (m). The layout is drawn in metres, so every resolution shows the same
        building (unless a draw fails the connectivity checks at one resolution only, in which
        case the next draw is used there); walls and partitions stay at least one cell thick.

    Returns
    -------
    World
        Free space is one 4-connected component, and the space a 0.3 m-radius robot can occupy
        is connected (doors are at least 1.4 m wide, obstacles at least 1.2 m apart).
    """
    occ, _ = _museum_grid(int(seed), float(resolution))
    return World(occ.copy(), float(resolution), np.zeros(2), "museum")


# ------------------------------------------------------------------------------ office
def _widths(rng: np.random.Generator, total: float, n: int, minimum: float) -> list[float]:
    extra = total - n * minimum
    return list(minimum + extra * rng.dirichlet(np.full(n, 3.0)))


def _furnish_office_room(rng: np.random.Generator, f: Furnisher, room: Room) -> None:
    """Desks with chairs and cabinets against the walls, a meeting table, plants and boxes."""
    b = room.box

    def flush(length: tuple[float, float], depth: tuple[float, float]) -> Callable[[], bool]:
        def make() -> bool:
            box, side = _flush_box(rng, b, float(rng.uniform(*length)), float(rng.uniform(*depth)))
            return f.place(box, b, flush=side)

        return make

    def desk() -> bool:
        box, side = _flush_box(rng, b, float(rng.uniform(1.2, 1.6)), 0.7)
        # The chair stands 0.15 m in front of the desk, as part of the same group.
        cx, cy = box.center
        ox, oy = {"left": (0.95, 0.0), "right": (-0.95, 0.0), "bottom": (0.0, 0.95), "top": (0.0, -0.95)}[side]
        chair = Box(cx + ox - 0.25, cy + oy - 0.25, cx + ox + 0.25, cy + oy + 0.25)
        return f.place([box, chair], b, flush=side)

    if room.kind == "meeting":
        tw, th = min(3.0, b.width - 3.4), 1.2

        def table() -> bool:
            cx, cy = b.center
            cx += float(rng.uniform(-1.0, 1.0))
            cy += float(rng.uniform(-1.0, 1.0))
            group: list[Shape] = [Box(cx - tw / 2, cy - th / 2, cx + tw / 2, cy + th / 2)]
            for k in range(3):  # chairs on both long sides, tucked close to the table
                x = cx - tw / 2 + (k + 0.5) * tw / 3
                group.append(Box(x - 0.22, cy + th / 2 + 0.1, x + 0.22, cy + th / 2 + 0.5))
                group.append(Box(x - 0.22, cy - th / 2 - 0.5, x + 0.22, cy - th / 2 - 0.1))
            return f.place(group, b)

        _place_n(1, table, attempts=30)
        _place_n(int(rng.integers(1, 3)), flush((1.0, 1.8), (0.4, 0.5)))
    elif room.kind == "office":
        _place_n(int(rng.integers(2, 5)), desk)
        _place_n(int(rng.integers(1, 4)), flush((0.6, 1.8), (0.4, 0.6)))
        if rng.random() < 0.5:  # small round table
            _place_n(1, lambda: f.place(Disc(*_uniform_point(rng, b, 1.6), 0.45), b))
        _place_n(int(rng.integers(0, 2)), lambda: f.place(_clutter(rng, *_uniform_point(rng, b, 1.3)), b))
    else:  # corridor: bins, a bench, a water cooler against the walls
        _place_n(int(rng.integers(2, 5)), flush((0.4, 1.5), (0.35, 0.5)))
    _place_n(int(rng.integers(0, 2)), lambda: f.place(Disc(*_uniform_point(rng, b, 1.3), 0.25), b))


def office_layout(seed: int = 0, attempt: int = 0) -> Layout:
    """The office layout in metres (before rasterisation); see :func:`office_world`."""
    rng = _rng(seed, attempt)
    width, height, outer, wall = 20.0, 15.0, 0.3, 0.15
    y_c0 = round(float(rng.uniform(5.8, 7.0)) * 20.0) / 20.0  # corridor lower wall
    y_c1 = y_c0 + 2.2
    rooms: list[Room] = [Room(Box(outer, y_c0 + wall / 2, width - outer, y_c1 - wall / 2), "corridor")]
    splits: list[Split] = []
    walls = outer_walls(width, height, outer)
    corridor_walls = [Split(False, y_c0, outer, width - outer, wall), Split(False, y_c1, outer, width - outer, wall)]
    walls += [s.box for s in corridor_walls]
    doors_out = []
    keepouts = []
    from crlam.sim.layout import Door

    for side, (y0, y1, wall_split) in enumerate(
        [(outer, y_c0 - wall / 2, corridor_walls[0]), (y_c1 + wall / 2, height - outer, corridor_walls[1])]
    ):
        n = 3 if side == 0 else 4
        ws = _widths(rng, width - 2 * outer - (n - 1) * wall, n, 3.8)
        x = outer
        meeting = int(rng.integers(n))
        for k, w in enumerate(ws):
            box = Box(x, y0, x + w, y1)
            rooms.append(Room(box, "meeting" if k == meeting else "office"))
            # Door from the room to the corridor, away from the side walls.
            dw = round(float(rng.uniform(1.2, 1.5)) * 20.0) / 20.0
            a = round(float(rng.uniform(x + 0.5, x + w - 0.5 - dw)) * 20.0) / 20.0
            doors_out.append(Door(wall_split.opening(a, a + dw), dw))
            keepouts.append(wall_split.approach(a, a + dw, 1.0))
            if k < n - 1:
                sep = Split(True, x + w + wall / 2, y0, y1, wall)
                splits.append(sep)
                walls.append(sep.box)
                if rng.random() < 0.4:  # connecting door between neighbouring rooms
                    dw = 1.2
                    a = round(float(rng.uniform(y0 + 0.8, y1 - 0.8 - dw)) * 20.0) / 20.0
                    doors_out.append(Door(sep.opening(a, a + dw), dw))
                    keepouts.append(sep.approach(a, a + dw, 1.0))
            x += w + wall
    furn = Furnisher(gap=1.0, keepouts=keepouts)
    for room in rooms:
        _furnish_office_room(rng, furn, room)
    return Layout("office", width, height, walls, doors_out, rooms, furn)


@functools.lru_cache(maxsize=8)
def _office_grid(seed: int, resolution: float) -> np.ndarray:
    last: Exception | None = None
    for attempt in range(_MAX_ATTEMPTS):
        try:
            occ, _ = office_layout(seed, attempt).rasterize(resolution, robot_radius=0.3)
        except LayoutError as exc:
            last = exc
            continue
        occ.setflags(write=False)
        return occ
    raise RuntimeError(f"no connected office layout for seed {seed}: {last}")


def office_world(seed: int = 0, resolution: float = 0.05) -> World:
    """A 20 m x 15 m office: a corridor, seven rooms with doors (>= 1.2 m), desks and cabinets.

    Small and quick to simulate; meant for tests. Same guarantees as :func:`museum_world`.
    """
    return World(_office_grid(int(seed), float(resolution)).copy(), float(resolution), np.zeros(2), "office")


# ------------------------------------------------------------------------------ lookup
def get_world(name_or_path: str | Path, seed: int = 0, resolution: float | None = None) -> World:
    """A world by name (``"museum"``, ``"office"``) or from a file.

    Parameters
    ----------
    name_or_path:
        A built-in name, a Nav2 YAML (``.yaml``/``.yml``), or an image (PGM, PNG, ...).
    seed:
        Seed of the procedural worlds (ignored for files).
    resolution:
        Cell size (m): for procedural worlds (default 0.05), and required for a bare image
        without a YAML of the same stem next to it.
    """
    key = str(name_or_path)
    if key in WORLD_NAMES:
        res = 0.05 if resolution is None else float(resolution)
        return museum_world(seed, res) if key == "museum" else office_world(seed, res)
    path = Path(key)
    if not path.exists():
        raise ConfigError(f"unknown world {key!r}: not one of {WORLD_NAMES} and no such file")
    if path.suffix.lower() in (".yaml", ".yml"):
        return World.from_nav2_yaml(path)
    for sidecar in (path.with_suffix(".yaml"), path.with_suffix(".yml")):
        if resolution is None and sidecar.exists():
            return World.from_nav2_yaml(sidecar)
    if resolution is None:
        raise ConfigError(f"{path}: a bare image needs resolution= (m per pixel)")
    return World.from_image(path, resolution=resolution)
