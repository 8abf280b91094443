"""A floor of look-alike rooms, for global localization: the hard case of buildings such as
Intel's, where many rooms have the same size, door and furniture.

:func:`lookalike_world` draws a corridor with ``n_rooms`` identical rooms on each side (the same
door and the same desk, at the same place in every room). Only the two corridor ends and one
room's cabinet tell the places apart, so a localizer started anywhere must keep every matching
room as a hypothesis until the robot has seen one of them.
"""

from __future__ import annotations

import numpy as np

from crlam.sim.world import World

__all__ = ["INTEL_SCALE", "lookalike_world"]

INTEL_SCALE = {"n_rooms": 10, "room_w": 5.0, "room_d": 5.0, "corridor": 3.0}
"""The arguments of :func:`lookalike_world` for a floor of Intel's scale: ten 5 m x 5 m rooms on
each side of a 3 m corridor, 627 m² of free space (Intel's map: about 765 m²; the default floor:
150 m²)."""


def lookalike_world(
    n_rooms: int = 4,
    resolution: float = 0.05,
    room_w: float = 4.0,
    room_d: float = 3.5,
    corridor: float = 2.4,
) -> World:
    """The floor (module docstring): rooms ``room_w`` m wide and ``room_d`` m deep (default 4 m
    and 3.5 m) on both sides of a ``corridor`` m corridor (2.4 m); the west end of the corridor
    is closed, the east end opens into a 2 m alcove to the north, and the second room from the
    west on the south side holds a cabinet. The outer walls and the walls between rooms are
    0.15 m thick; each room's door (1 m) is 1 m from its west wall, and its desk (1.2 m x 0.6 m)
    stands against the back wall 2.2 m from it.
    """
    if n_rooms < 2:
        raise ValueError(f"n_rooms must be >= 2, got {n_rooms}")
    if not (room_w >= 3.6 and room_d >= 2.5 and corridor >= 1.5):
        raise ValueError(
            f"rooms need room_w >= 3.6 m (door and desk), room_d >= 2.5 m and corridor >= 1.5 m; "
            f"got {room_w}, {room_d}, {corridor}"
        )
    wall = 0.15
    width = n_rooms * room_w + 2.0 + 2 * wall  # the alcove's 2 m at the east end
    height = 2 * room_d + corridor + 2 * wall
    nx, ny = int(round(width / resolution)), int(round(height / resolution))
    occ = np.zeros((ny, nx), dtype=bool)

    def box(x0: float, y0: float, x1: float, y1: float) -> None:
        occ[
            int(round(y0 / resolution)) : int(round(y1 / resolution)), int(round(x0 / resolution)) : int(round(x1 / resolution))
        ] = True

    box(0, 0, width, wall)
    box(0, height - wall, width, height)
    box(0, 0, wall, height)
    box(width - wall, 0, width, height)
    south_y, north_y = wall + room_d, wall + room_d + corridor  # the corridor's walls
    east = wall + n_rooms * room_w  # where the rooms end and the alcove begins
    for side_y0, side_y1, wall_y, back_y0 in (
        (wall, south_y, south_y, wall),  # south rooms: back wall at the bottom
        (north_y, height - wall, north_y, height - wall - 0.6),  # north rooms: back wall at the top
    ):
        # The corridor wall of this side, with one door per room.
        for k in range(n_rooms):
            x0 = wall + k * room_w
            w0 = wall_y - (wall if wall_y == south_y else 0.0)
            box(x0, w0, x0 + 1.0, w0 + wall)
            box(x0 + 2.0, w0, x0 + room_w, w0 + wall)
            # The wall between this room and the next (and the last room's east wall).
            box(x0 + room_w - wall / 2, side_y0, x0 + room_w + wall / 2, side_y1)
            # The desk against the back wall.
            box(x0 + 2.2, back_y0, x0 + 3.4, back_y0 + 0.6)
    # The alcove: the north side east of the rooms stays open to the corridor; the south side is
    # solid.
    box(east, wall, width, south_y)
    # The cabinet in the second room from the west on the south side.
    box(wall + room_w + 0.3, wall + 1.5, wall + room_w + 0.9, wall + 2.3)
    name = (
        f"lookalike-{n_rooms}"
        if (room_w, room_d, corridor) == (4.0, 3.5, 2.4)
        else f"lookalike-{n_rooms}-{room_w:g}x{room_d:g}-{corridor:g}"
    )
    return World(occ, resolution, name=name)
