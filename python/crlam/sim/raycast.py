"""Exact grid ray casting in numpy: the fallback for ``crlam._native.cast_ranges``.

Same contract as the native function: for every pose and beam angle, the distance (m) from the
pose's ``(x, y)`` along heading ``theta + angle`` to the *entry point* of the first occupied cell,
``inf`` if there is none within ``max_range``, 0 if the start cell is occupied. Cells outside the
grid are free (a ray may leave the grid and come back in).

The traversal is Amanatides-Woo: for each ray keep the ray parameter at which it crosses the
next vertical and the next horizontal grid line, and step through whichever comes first. All rays
advance together as numpy vectors; finished rays are dropped from the working set.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

__all__ = ["cast_ranges_numpy"]


def cast_ranges_numpy(
    occupied: NDArray[np.bool_] | NDArray[np.uint8],
    origin_x: float,
    origin_y: float,
    resolution: float,
    poses: NDArray[np.float64],
    angles: NDArray[np.float64],
    max_range: float,
) -> NDArray[np.float64]:
    """Distances (m) to the first occupied cell along each beam; shape ``(n_poses, n_angles)``.

    Parameters
    ----------
    occupied:
        ``(ny, nx)``, nonzero = occupied, indexed ``[iy, ix]`` with ``iy = 0`` at the minimum y.
    origin_x, origin_y:
        World coordinates (m) of the lower-left corner of cell ``[0, 0]``.
    resolution:
        Cell size (m).
    poses:
        ``(n, 3)`` sensor poses ``(x, y, theta)`` in m, rad.
    angles:
        ``(m,)`` beam angles (rad) relative to the heading.
    max_range:
        Rays are followed up to this distance (m).
    """
    occ = np.asarray(occupied) != 0
    ny, nx = occ.shape
    poses = np.asarray(poses, dtype=np.float64).reshape(-1, 3)
    angles = np.asarray(angles, dtype=np.float64).reshape(-1)
    n, m = len(poses), len(angles)
    out = np.full(n * m, np.inf)
    if n == 0 or m == 0:
        return out.reshape(n, m)
    # Work in cell units: grid coordinates g = (p - origin) / res, ray parameter t in cells.
    phi = (poses[:, 2, None] + angles[None, :]).ravel()
    dx, dy = np.cos(phi), np.sin(phi)
    gx = np.repeat((poses[:, 0] - origin_x) / resolution, m)
    gy = np.repeat((poses[:, 1] - origin_y) / resolution, m)
    t_max = max_range / resolution
    ix = np.floor(gx).astype(np.int64)
    iy = np.floor(gy).astype(np.int64)

    def occupied_at(cx: NDArray[np.int64], cy: NDArray[np.int64]) -> NDArray[np.bool_]:
        inside = (cx >= 0) & (cx < nx) & (cy >= 0) & (cy < ny)
        return inside & occ[np.clip(cy, 0, ny - 1), np.clip(cx, 0, nx - 1)]

    start_hit = occupied_at(ix, iy)
    out[start_hit] = 0.0
    with np.errstate(divide="ignore", invalid="ignore"):
        step_x = np.where(dx > 0, 1, -1).astype(np.int64)
        step_y = np.where(dy > 0, 1, -1).astype(np.int64)
        # Parameter of the next grid-line crossing on each axis; inf for axis-parallel rays.
        next_x = np.where(dx > 0, (ix + 1 - gx) / dx, np.where(dx < 0, (gx - ix) / -dx, np.inf))
        next_y = np.where(dy > 0, (iy + 1 - gy) / dy, np.where(dy < 0, (gy - iy) / -dy, np.inf))
        delta_x = np.where(dx != 0, 1.0 / np.abs(dx), np.inf)
        delta_y = np.where(dy != 0, 1.0 / np.abs(dy), np.inf)

    active = np.nonzero(~start_hit)[0]
    ix, iy = ix[active], iy[active]
    step_x, step_y = step_x[active], step_y[active]
    next_x, next_y = next_x[active], next_y[active]
    delta_x, delta_y = delta_x[active], delta_y[active]
    while len(active):
        cross_x = next_x <= next_y
        t = np.where(cross_x, next_x, next_y)
        ix = ix + np.where(cross_x, step_x, 0)
        iy = iy + np.where(cross_x, 0, step_y)
        next_x = next_x + np.where(cross_x, delta_x, 0.0)
        next_y = next_y + np.where(cross_x, 0.0, delta_y)
        hit = occupied_at(ix, iy) & (t <= t_max)
        out[active[hit]] = t[hit] * resolution
        # A ray is done once it hits, or once its entry parameter passes the range limit.
        keep = ~hit & (t <= t_max)
        if not keep.all():
            active, ix, iy = active[keep], ix[keep], iy[keep]
            step_x, step_y = step_x[keep], step_y[keep]
            next_x, next_y = next_x[keep], next_y[keep]
            delta_x, delta_y = delta_x[keep], delta_y[keep]
    # Hits beyond max_range are "nothing within range".
    out[out > max_range] = np.inf
    return out.reshape(n, m)
