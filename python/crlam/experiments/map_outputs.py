"""The map files of a run folder (``map.pgm``, ``belief.npz``, the map of ``trajectory.png``, the
grids of ``run.mcap``), computed from the native map in bands of rows.

A campus-scale map spans millions of cells, most of them never seen: its bounding box holds ten
times more cells than the tiles the filter stores. Arrays over the whole box (the K-level pmfs,
float64 layers) would take several times the filter's own memory, so nothing here holds more
than one band of rows of them at a time. What is kept whole is one byte per cell (the Nav2
pixels; the MCAP grids when asked for) and a figure's map reduced to at most
:data:`FIGURE_CELLS` cells along a side.

Figure rule: when the map is more than ``n`` cells along its longer side, the figure draws
blocks of ``s x s`` cells, ``s = ceil(max(ny, nx) / n)``: a block shows the largest value
(occupancy, variance) among its observed cells, and is unknown only when all its cells are, so
that a wall one cell thick still shows. ``n`` is :data:`FIGURE_CELLS` (1,200) for
``trajectory.png`` and :data:`PANEL_CELLS` (600) for each of the two panels of ``crlam map``'s
``map.png``: about the pixels a panel has, since matplotlib takes several bytes per cell of
an image it has to shrink. The map files themselves are always at full resolution.
"""

from __future__ import annotations

import math
import os
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from crlam.io.belief import BAND_BYTES, save_belief_bands
from crlam.io.nav2 import nav2_pixels
from crlam.mapping import ConfidenceRichMap, LogOddsOccupancyMap, MapLayer

__all__ = ["FIGURE_CELLS", "PANEL_CELLS", "MapProducts", "UNKNOWN_ENTROPY_TOL", "map_products", "write_belief_archive"]

#: A cell whose entropy is within this of the prior's was never informed by any beam.
UNKNOWN_ENTROPY_TOL = 1e-6

FIGURE_CELLS = 1200
"""Most cells along a side of a figure's map: a 150 dpi figure 8 inches wide has 1,200 pixels."""

PANEL_CELLS = 600
"""Most cells along a side of a map in one of two panels side by side (13 inches at 150 dpi)."""

#: Thresholds of the map's cell classes (Nav2's defaults, as map.yaml states them).
OCCUPIED_THRESH, FREE_THRESH = 0.65, 0.196

Rect = tuple[int, int, int, int]


@dataclass
class MapProducts:
    """A map's files and figure layers, computed band by band by :func:`map_products`.

    Attributes
    ----------
    origin : (float, float)
        World ``(x, y)`` (m) of the lower-left corner of cell ``[0, 0]``.
    resolution : float
        Cell size (m).
    nav2 : ndarray, shape (ny, nx), uint8
        Pixels of ``map.pgm`` (:func:`crlam.io.nav2.nav2_pixels`; row 0 at the minimum y).
    figure_mean : MapLayer
        The occupancy for figures, reduced by the rule of the module docstring; at most
        :data:`FIGURE_CELLS` cells a side.
    figure_unknown : ndarray of bool, shape of ``figure_mean``
        Never-observed cells (blocks) of ``figure_mean``.
    figure_variance : MapLayer or None
        The belief variance reduced likewise (a CRM only).
    grid, confidence_grid : ndarray, shape (ny * nx,), int8, or None
        The ``OccupancyGrid`` data of ``/map`` and ``/map_confidence``
        (:func:`crlam.experiments.slam_mcap.occupancy_grid_values`), when asked for.
    n_known, n_occupied, n_free : int
        Observed cells, and those above / below the occupied / free thresholds.
    figure_stride : int
        ``s`` of the figure rule (1: cell for cell).
    """

    origin: tuple[float, float]
    resolution: float
    nav2: NDArray[np.uint8]
    figure_mean: MapLayer
    figure_unknown: NDArray[np.bool_]
    figure_variance: MapLayer | None
    grid: NDArray[np.int8] | None
    confidence_grid: NDArray[np.int8] | None
    n_known: int
    n_occupied: int
    n_free: int
    figure_stride: int

    @property
    def shape(self) -> tuple[int, int]:
        """``(ny, nx)`` of the full-resolution map."""
        return int(self.nav2.shape[0]), int(self.nav2.shape[1])


def _band_rows(nx: int, bytes_per_cell: int, multiple: int) -> int:
    """Rows of a band of at most :data:`BAND_BYTES` (at least ``multiple`` rows, a multiple of it)."""
    rows = max(1, BAND_BYTES // max(1, nx * bytes_per_cell))
    return max(multiple, rows // multiple * multiple)


def _bands(rect: Rect, rows: int) -> Iterator[tuple[int, Rect]]:
    """``(first row, band rectangle)`` of every band of ``rows`` rows of ``rect`` = (ix0, iy0, nx, ny)."""
    ix0, iy0, nx, ny = rect
    for r in range(0, ny, rows):
        yield r, (ix0, iy0 + r, nx, min(rows, ny - r))


def write_belief_archive(
    path: str | os.PathLike[str],
    crm: ConfidenceRichMap,
    *,
    estimate: NDArray[np.float64] | None = None,
    estimate_cov: NDArray[np.float64] | None = None,
) -> Path:
    """``belief.npz`` of ``crm`` over its written area (the file :meth:`ConfidenceRichMap.to_archive`
    and :func:`crlam.io.belief.save_belief` write), read from the native map band by band."""
    rect = crm.region()
    origin, metadata = crm.archive_header(rect)
    levels = crm.levels.copy()
    rows = _band_rows(rect[2], 4 * int(levels.shape[0]), 1)
    save_belief_bands(
        path,
        shape=(rect[3], rect[2]),
        levels=levels,
        origin=origin,
        resolution=crm.config.resolution,
        metadata=metadata,
        bands=(crm.native.beliefs(band) for _, band in _bands(rect, rows)),
        estimate=estimate,
        estimate_cov=estimate_cov,
    )
    return Path(path)


def _block_max(values: NDArray[np.floating], known: NDArray[np.bool_], s: int) -> NDArray[np.float64]:
    """The largest known value of every ``s x s`` block of a band (rows a multiple of ``s`` or the
    map's last band), NaN where a block has no known cell."""
    h, nx = values.shape
    hb, wb = -(-h // s), -(-nx // s)
    padded = np.full((hb * s, wb * s), np.nan, dtype=np.float64)
    padded[:h, :nx] = np.where(known, values, np.nan)
    blocks = padded.reshape(hb, s, wb, s)
    # fmax skips NaN unless both are: a block is NaN only when none of its cells is known.
    out: NDArray[np.float64] = np.fmax.reduce(np.fmax.reduce(blocks, axis=3), axis=1)
    return out


def map_products(
    best: ConfidenceRichMap | LogOddsOccupancyMap, *, grids: bool = False, figure_cells: int = FIGURE_CELLS
) -> MapProducts:
    """The map files' content of ``best`` over its written area, band by band (module docstring).

    A CRM gives its expected occupancy and variance (unknown: entropy within
    :data:`UNKNOWN_ENTROPY_TOL` of the prior's); a log-odds map its occupancy probability (unknown:
    log-odds exactly 0). ``grids`` also fills the MCAP grids (``/map_confidence`` for a CRM only).
    ``figure_cells``: ``n`` of the figure rule.
    """
    from crlam.experiments.slam_mcap import occupancy_grid_values

    crm = isinstance(best, ConfidenceRichMap)
    rect = best.region()
    ix0, iy0, nx, ny = rect
    res = float(best.config.resolution)
    ox, oy = best.config.origin
    origin = (ox + ix0 * res, oy + iy0 * res)
    stride = max(1, math.ceil(max(nx, ny) / max(1, figure_cells)))
    # derived_maps gives three float64 layers; the masks and products add about as much again.
    rows = _band_rows(nx, 48 if crm else 24, stride)
    nav2 = np.empty((ny, nx), dtype=np.uint8)
    fy, fx = -(-ny // stride), -(-nx // stride)
    fig_mean = np.empty((fy, fx), dtype=np.float64)
    fig_var = np.empty((fy, fx), dtype=np.float64) if crm else None
    grid = np.empty(ny * nx, dtype=np.int8) if grids else None
    confidence = np.empty(ny * nx, dtype=np.int8) if grids and crm else None
    h_prior = 0.0
    if isinstance(best, ConfidenceRichMap):
        p = best.native.prior
        h_prior = float(-(p * np.log2(p)).sum())
    n_known = n_occupied = n_free = 0
    for r, band in _bands(rect, rows):
        var = None
        if isinstance(best, ConfidenceRichMap):
            mean, var, ent = best.native.derived_maps(band)
            unknown = np.abs(ent - h_prior) < UNKNOWN_ENTROPY_TOL
            del ent
        else:
            lo = best.native.log_odds(band)
            mean = 0.5 * (1.0 + np.tanh(0.5 * math.log(best.config.base) * lo))
            unknown = lo == 0.0
            del lo
        known = ~unknown
        h = band[3]
        nav2[r : r + h] = nav2_pixels(np.where(unknown, np.nan, mean), occupied_thresh=OCCUPIED_THRESH, free_thresh=FREE_THRESH)
        n_known += int(known.sum())
        n_occupied += int((known & (mean > OCCUPIED_THRESH)).sum())
        n_free += int((known & (mean < FREE_THRESH)).sum())
        fr = r // stride
        block = _block_max(mean, known, stride)
        fig_mean[fr : fr + block.shape[0]] = block
        if fig_var is not None and var is not None:
            fig_var[fr : fr + block.shape[0]] = _block_max(var, known, stride)
        if grid is not None:
            grid[r * nx : (r + h) * nx] = occupancy_grid_values(mean, unknown)
        if confidence is not None and var is not None:
            confidence[r * nx : (r + h) * nx] = occupancy_grid_values(np.sqrt(np.maximum(var, 0.0)), unknown, scale=200.0)
    fig_unknown = np.isnan(fig_mean)
    fig_res = res * stride
    # Unknown cells are drawn from the mask; their value is 0 (in place: the figure's layers are
    # the largest arrays kept besides the one-byte-per-cell pixels).
    fig_mean[fig_unknown] = 0.0
    if fig_var is not None:
        fig_var[fig_unknown] = 0.0
    return MapProducts(
        origin=origin,
        resolution=res,
        nav2=nav2,
        figure_mean=MapLayer(fig_mean, origin, fig_res, "expected occupancy" if crm else "occupancy"),
        figure_unknown=fig_unknown,
        figure_variance=None if fig_var is None else MapLayer(fig_var, origin, fig_res, "variance"),
        grid=grid,
        confidence_grid=confidence,
        n_known=n_known,
        n_occupied=n_occupied,
        n_free=n_free,
        figure_stride=stride,
    )
