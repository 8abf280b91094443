"""Prior map states for the information functions (planner-spec 2.1-2.2, crm-spec 6.5).

A prior is an :class:`~crlam._native.OccupancyLattice`: one occupancy probability per node, the
nodes being cell centres. The planner's reference prior puts ``p_occupied`` (0.85) on the nodes
of obstacle points and ``p_free`` (0.3) everywhere else, with a margin of free nodes around the
map (1 m in the reference).
"""

from __future__ import annotations

import math
import os
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from crlam import _native
from crlam.errors import ConfigError, DataFormatError
from crlam.io.nav2 import read_nav2_map, read_pgm
from crlam.limits import check_limit
from crlam.pose import number_pair

__all__ = ["MapPrior", "lattice_from_obstacles", "load_map_prior", "prior_from_crm_mean"]


@dataclass(frozen=True)
class MapPrior:
    """A prior lattice and which of its nodes are candidate (free, in-map) cells.

    Attributes
    ----------
    lattice : OccupancyLattice
        Prior occupancy probabilities (ny, nx) on cell centres.
    free : ndarray, shape (ny, nx), bool
        Nodes inside the source map classified free: where a surface is evaluated.
    obstacle : ndarray, shape (ny, nx), bool
        Nodes of obstacle points (for figures).
    source : str
        Where the prior came from.
    """

    lattice: _native.OccupancyLattice
    free: NDArray[np.bool_]
    obstacle: NDArray[np.bool_]
    source: str

    @property
    def extent(self) -> tuple[float, float, float, float]:
        """``(xmin, xmax, ymin, ymax)`` (m) of the lattice cells."""
        ny, nx = self.lattice.shape
        ox, oy = self.lattice.origin
        r = self.lattice.resolution
        return (ox, ox + nx * r, oy, oy + ny * r)

    def node_positions(self, mask: NDArray[np.bool_]) -> NDArray[np.float64]:
        """World (x, y) (m) of the nodes where ``mask`` is true, shape (n, 2), row-major order."""
        iy, ix = np.nonzero(mask)
        ox, oy = self.lattice.origin
        r = self.lattice.resolution
        return np.column_stack([ox + (ix + 0.5) * r, oy + (iy + 0.5) * r])


def lattice_from_obstacles(
    obstacle: NDArray[np.bool_],
    unknown: NDArray[np.bool_] | None,
    resolution: float,
    node_origin: tuple[float, float],
    *,
    margin: float = 1.0,
    p_occupied: float = 0.85,
    p_free: float = 0.3,
    p_unknown: float = 0.5,
) -> MapPrior:
    """The reference prior from an obstacle mask (ny, nx), ``[iy, ix]`` with iy = 0 at min y.

    Node ``[iy, ix]`` of the mask sits at ``node_origin + (ix, iy) * resolution``; the lattice adds
    ``round(margin / resolution)`` free nodes on every side.
    """
    for name, p in (("p_occupied", p_occupied), ("p_free", p_free), ("p_unknown", p_unknown)):
        if not (0.0 < p < 1.0):
            raise ConfigError(f"{name} must be in (0, 1), got {p}")
    if not (math.isfinite(resolution) and resolution > 0):
        raise ConfigError(f"resolution must be finite and > 0, got {resolution}")
    obstacle = np.asarray(obstacle)
    if obstacle.ndim != 2 or obstacle.size == 0 or obstacle.dtype != np.bool_:
        raise ConfigError(
            f"the obstacle mask must be a non-empty 2-D boolean array, got {obstacle.dtype} of shape {obstacle.shape}"
        )
    if unknown is not None:
        unknown = np.asarray(unknown)
        if unknown.shape != obstacle.shape or unknown.dtype != np.bool_:
            raise ConfigError(
                f"the unknown mask must be a boolean array of the obstacle mask's shape {obstacle.shape}, got "
                f"{unknown.dtype} of shape {unknown.shape}"
            )
    if not (math.isfinite(margin) and margin >= 0):
        raise ConfigError(f"margin must be finite and >= 0, got {margin}")
    ny, nx = obstacle.shape
    m_float = round(margin / resolution)
    check_limit(
        "map_cells",
        (ny + 2.0 * m_float) * (nx + 2.0 * m_float),
        f"a map prior of {nx} x {ny} cells of {resolution} m with a {margin} m margin",
    )
    m = int(m_float)
    prob = np.full((ny + 2 * m, nx + 2 * m), p_free)
    inner = prob[m : m + ny, m : m + nx]
    unk = np.zeros_like(obstacle) if unknown is None else unknown
    inner[unk] = p_unknown
    inner[obstacle] = p_occupied
    free = np.zeros(prob.shape, dtype=bool)
    free[m : m + ny, m : m + nx] = ~obstacle & ~unk
    obst = np.zeros(prob.shape, dtype=bool)
    obst[m : m + ny, m : m + nx] = obstacle
    ox, oy = number_pair(node_origin, "node_origin")
    origin = (ox - (m + 0.5) * resolution, oy - (m + 0.5) * resolution)
    lat = _native.OccupancyLattice(np.ascontiguousarray(prob), resolution, origin)
    return MapPrior(lattice=lat, free=free, obstacle=obst, source="obstacles")


def _planner_pgm(path: Path, resolution: float, margin: float, p_occupied: float, p_free: float) -> MapPrior:
    """planner-spec 2.1: pixel >= half the max value is free; pixel (row i, col j) is the point
    (res (j - 1), res (rows - i)) (1-based), i.e. the lower-left corner of its cell; border walls
    on the map's outline."""
    img = read_pgm(path).astype(np.float64)
    maxval = 65535.0 if img.dtype == np.uint16 or img.max() > 255 else 255.0
    obstacle_img = img < 0.5 * (maxval + 1)
    obstacle = obstacle_img[::-1].copy()  # iy = 0 at min y
    ny, nx = obstacle.shape
    # Border walls at x = 0, x = nx res, y = 0, y = ny res (the reference's 4 x (n+1) points).
    grid = np.zeros((ny + 1, nx + 1), dtype=bool)
    grid[:ny, :nx] = obstacle
    grid[0, :] = grid[-1, :] = True
    grid[:, 0] = grid[:, -1] = True
    prior = lattice_from_obstacles(grid, None, resolution, (0.0, 0.0), margin=margin, p_occupied=p_occupied, p_free=p_free)
    return MapPrior(prior.lattice, prior.free, prior.obstacle, source=f"{path} (planner prior)")


def load_map_prior(
    path: str | os.PathLike[str],
    *,
    resolution: float = 0.2,
    margin: float = 1.0,
    p_occupied: float = 0.85,
    p_free: float = 0.3,
) -> MapPrior:
    """The prior of a map file: a Nav2 ``.yaml`` (trinary classes, its own resolution and origin;
    unknown cells get 0.5) or a bare ``.pgm`` read as the planner reads the Cave map
    (``resolution`` m per pixel, origin at its lower-left corner, border walls added)."""
    p = Path(path)
    if not p.exists():
        raise DataFormatError(f"{p}: no such map file")
    suffix = p.suffix.lower()
    if suffix in (".yaml", ".yml"):
        nav = read_nav2_map(p)
        occ = nav.occupancy
        unknown = np.isnan(occ)
        obstacle = np.nan_to_num(occ, nan=0.0) > 0.5
        node0 = (float(nav.origin[0]) + 0.5 * nav.resolution, float(nav.origin[1]) + 0.5 * nav.resolution)
        prior = lattice_from_obstacles(
            obstacle, unknown, nav.resolution, node0, margin=margin, p_occupied=p_occupied, p_free=p_free
        )
        return MapPrior(prior.lattice, prior.free, prior.obstacle, source=f"{p} (nav2)")
    if suffix == ".pgm":
        return _planner_pgm(p, resolution, margin, p_occupied, p_free)
    raise DataFormatError(f"{p}: expected a Nav2 .yaml map or a .pgm image")


def prior_from_crm_mean(mean: NDArray[np.float64], origin: tuple[float, float], resolution: float) -> MapPrior:
    """A lattice of a CRM's expected occupancy (e.g. from ``belief.npz``); cells with mean below
    0.5 are the free candidates, above it obstacles."""
    m = np.clip(np.ascontiguousarray(mean, dtype=np.float64), 0.0, 1.0)
    lat = _native.OccupancyLattice(m, resolution, origin)
    return MapPrior(lattice=lat, free=m < 0.5, obstacle=m > 0.5, source="crm mean")
