"""The map layers of one exploration decision, computed on a window around the written area.

A decision needs, per cell, whether it is observed, free, traversable (free with clearance) and
how far it is from unknown space. Cells the robot never scanned hold the prior, which is
unknown, so they are never free, traversable or a frontier: everything a decision uses lies in
the map's written area. The layers are therefore computed on that area, padded by a margin of
unknown cells and clipped to the exploration grid, and every cell outside the window reads the
prior. The clearance and unknown-distance maps are exact on the window: the window is framed by
a ring of the cells just outside it, blocked and unknown where that ring is inside the map (its
cells are unwritten) and, as on the whole map, blocked but not unknown where it is outside the
map. Any blocked or unknown cell beyond the ring is farther from a window cell than some ring
cell (the straight line to it crosses the ring), so the capped distances equal the whole map's on
every window cell. (The margin alone already makes them equal on the observed cells, the only
ones a decision reads: unknown cells are blocked and unknown themselves, at distance 0.)
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from crlam import _native
from crlam.sim.grid_ops import distance_map

__all__ = ["OBSERVED_BELOW_BITS", "DecisionMaps", "decision_maps", "map_window"]

OBSERVED_BELOW_BITS = math.log2(10.0) - 1e-3
"""A cell is observed when its entropy (bits) is below this: the uniform prior over the 10 levels
has log2(10) bits."""

CellRect = tuple[int, int, int, int]


@dataclass(frozen=True)
class DecisionMaps:
    """Layers of one decision on the window ``[iy0, iy0 + wny) x [ix0, ix0 + wnx)`` of the
    exploration grid (cells, ``[iy, ix]``, ``iy = 0`` at the minimum y); every cell outside the
    window holds the prior.

    Attributes
    ----------
    iy0, ix0 : int
        First window cell in the grid.
    shape : tuple of int
        ``(ny, nx)`` of the whole grid.
    mean, entropy : ndarray, shape (wny, wnx)
        Expected occupancy and entropy (bits) of the window cells.
    observed, free, traversable : ndarray of bool, shape (wny, wnx)
        Entropy below :data:`OBSERVED_BELOW_BITS`; observed with mean below the free threshold;
        free with the robot's clearance from every cell not known free (and the robot's own cell).
    to_unknown : ndarray, shape (wny, wnx)
        Distance (m) from the cell centre to the nearest unknown cell, capped (see
        :func:`decision_maps`); outside the map counts as known, as on the whole map.
    prior_mean, prior_entropy : float
        Expected occupancy and entropy (bits) of every cell outside the window.
    """

    iy0: int
    ix0: int
    shape: tuple[int, int]
    mean: NDArray[np.float64]
    entropy: NDArray[np.float64]
    observed: NDArray[np.bool_]
    free: NDArray[np.bool_]
    traversable: NDArray[np.bool_]
    to_unknown: NDArray[np.float64]
    prior_mean: float
    prior_entropy: float

    @property
    def window(self) -> tuple[slice, slice]:
        """The window as a slice of whole-grid arrays."""
        return (slice(self.iy0, self.iy0 + self.mean.shape[0]), slice(self.ix0, self.ix0 + self.mean.shape[1]))

    def whole(self, values: NDArray[np.generic], prior: float | int) -> NDArray[np.generic]:
        """A whole-grid array (ny, nx): ``values`` (wny, wnx) in the window, ``prior`` elsewhere."""
        out = np.full(self.shape, prior, dtype=values.dtype)
        out[self.window] = values
        return out

    def entropy_sum(self) -> float:
        """Total map entropy (bits) over the whole grid. Summed over a whole-grid array rather than
        as window sum + count x prior so that it is the same float as the sum of the whole map's
        layer (the pairwise sum's rounding depends on the order)."""
        return float(self.whole(self.entropy, self.prior_entropy).sum())

    def mean_uint8(self) -> NDArray[np.uint8]:
        """The whole grid's expected occupancy as 8-bit levels (0-255), for animation frames."""
        level = np.round(255 * np.array([self.prior_mean])).astype(np.uint8)[0]
        return np.asarray(self.whole(np.round(255 * self.mean).astype(np.uint8), int(level)), dtype=np.uint8)


def map_window(written: CellRect | None, rect: CellRect, here: tuple[int, int], margin: int) -> tuple[int, int, int, int]:
    """The window ``(iy0, ix0, wny, wnx)`` in grid cells: the written cell rectangle ``written``
    (map cells ``(ix0, iy0, nx, ny)``, None if nothing was written) grown by ``margin`` cells,
    clipped to the grid ``rect`` (map cells of grid cell (0, 0), and the grid's size), and grown
    to contain the robot's cell ``here`` = (iy, ix)."""
    gx0, gy0, nx, ny = rect
    hy, hx = here
    y0, y1, x0, x1 = hy, hy + 1, hx, hx + 1
    if written is not None:
        wx0 = max(written[0] - gx0 - margin, 0)
        wy0 = max(written[1] - gy0 - margin, 0)
        wx1 = min(written[0] + written[2] - gx0 + margin, nx)
        wy1 = min(written[1] + written[3] - gy0 + margin, ny)
        if wx0 < wx1 and wy0 < wy1:
            y0, y1, x0, x1 = min(wy0, hy), max(wy1, hy + 1), min(wx0, hx), max(wx1, hx + 1)
    return (y0, x0, y1 - y0, x1 - x0)


def decision_maps(
    native: _native.CrmMap,
    rect: CellRect,
    here: tuple[int, int],
    *,
    resolution: float,
    free_threshold: float,
    robot_radius: float,
    whole_map: bool = False,
) -> DecisionMaps:
    """The layers of a decision on the map ``native``.

    Parameters
    ----------
    native : CrmMap
        The map (the best particle's with SLAM).
    rect : tuple of int
        The exploration grid as map cells ``(ix0, iy0, nx, ny)``.
    here : tuple of int
        The robot's cell ``(iy, ix)`` in the grid (made traversable: the robot stands there).
    resolution : float
        Cell size (m).
    free_threshold : float
        Observed cells with expected occupancy below this are free.
    robot_radius : float
        Clearance (m) a traversable cell keeps from every cell not known free.
    whole_map : bool
        Compute on the whole grid (the reference the window must reproduce).

    Notes
    -----
    Distances are capped at ``reach_m = max(robot_radius, resolution) + 2 resolution`` (enough
    for the clearance test and the frontier test, ``robot_radius + 1.5 resolution``).
    """
    res = resolution
    gx0, gy0, nx, ny = rect
    reach_m = max(robot_radius, res) + 2 * res
    written = native.written_bounds()
    # Any cell outside the written tiles reads the prior: take one just left of them.
    probe = (written[0] - 1, written[1], 1, 1) if written is not None else (gx0, gy0, 1, 1)
    pm, _, ph = native.derived_maps(probe)
    prior_mean, prior_entropy = float(pm[0, 0]), float(ph[0, 0])
    # A prior that already counts as observed would make unwritten cells matter: no window then.
    if whole_map or prior_entropy < OBSERVED_BELOW_BITS:
        iy0, ix0, wny, wnx = 0, 0, ny, nx
    else:
        iy0, ix0, wny, wnx = map_window(written, rect, here, math.ceil(reach_m / res) + 2)
    mean, _, ent = native.derived_maps((gx0 + ix0, gy0 + iy0, wnx, wny))
    observed = ent < OBSERVED_BELOW_BITS
    free = observed & (mean < free_threshold)
    # The ring of cells around the window: inside the map they are unwritten (blocked, unknown),
    # outside it blocked (a path keeps its clearance from the map edge) but not unknown.
    ry = np.arange(iy0 - 1, iy0 + wny + 1)
    rx = np.arange(ix0 - 1, ix0 + wnx + 1)
    unknown = ((ry >= 0) & (ry < ny))[:, None] & ((rx >= 0) & (rx < nx))[None, :]
    unknown[1:-1, 1:-1] = ~observed
    # Clearance from unknown cells and from every observed cell that is not clearly free (a wall
    # may cover part of a cell whose mean is in between): paths keep robot_radius from anything
    # not known to be free, so they never cross an obstacle the map has not resolved.
    blocked = np.ones((wny + 2, wnx + 2), dtype=bool)
    blocked[1:-1, 1:-1] = ~observed | (mean >= free_threshold)
    clear = distance_map(blocked, res, reach_m)[1:-1, 1:-1]
    to_unknown = distance_map(unknown, res, reach_m)[1:-1, 1:-1]
    traversable = free & (clear >= robot_radius)
    traversable[here[0] - iy0, here[1] - ix0] = True
    return DecisionMaps(
        iy0=iy0,
        ix0=ix0,
        shape=(ny, nx),
        mean=mean,
        entropy=ent,
        observed=observed,
        free=free,
        traversable=traversable,
        to_unknown=to_unknown,
        prior_mean=prior_mean,
        prior_entropy=prior_entropy,
    )
