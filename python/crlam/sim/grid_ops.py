"""Grid algorithms used by the simulator: connected components and exact clearance.

Everything is pure numpy (no scipy). Grids follow the project convention: arrays indexed
``[iy, ix]``, ``iy = 0`` at the minimum y. Distances are measured from cell *centres* to the
nearest occupied cell *square* (not to its centre), which is what a disc-shaped robot centred on
the cell needs for an exact collision test.
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import NDArray

__all__ = [
    "ClearanceField",
    "column_gap",
    "distance_map",
    "fill_small_components",
    "label_components",
]

BoolGrid = NDArray[np.bool_]


def label_components(mask: BoolGrid, connectivity: int = 4) -> tuple[NDArray[np.int32], NDArray[np.int64]]:
    """Label the connected components of the true cells of ``mask``.

    Parameters
    ----------
    mask:
        Boolean grid, shape ``(ny, nx)``.
    connectivity:
        4 (edge neighbours) or 8 (edge and corner neighbours).

    Returns
    -------
    labels:
        int32 grid ``(ny, nx)``; 0 for false cells, ``1..K`` for the components, numbered in
        row-major order of their first cell (deterministic).
    sizes:
        int64 ``(K + 1,)``: number of cells per label, ``sizes[0]`` counts the false cells.

    Notes
    -----
    Works on horizontal runs: each run is a node, runs that touch in adjacent rows are joined by
    a vectorised union-find (hooking to the smaller root, then pointer jumping).
    """
    if connectivity not in (4, 8):
        raise ValueError(f"connectivity must be 4 or 8, not {connectivity}")
    m = np.asarray(mask, dtype=bool)
    ny, nx = m.shape
    if not m.any():
        return np.zeros((ny, nx), dtype=np.int32), np.array([m.size], dtype=np.int64)
    padded = np.zeros((ny, nx + 2), dtype=np.int8)
    padded[:, 1:-1] = m
    d = np.diff(padded, axis=1)
    sr, sc = np.nonzero(d == 1)  # run starts (row-major order)
    er, ec = np.nonzero(d == -1)  # run ends, exclusive, in the same order
    n_runs = len(sr)
    flat_start = sr * nx + sc
    flat_end = er * nx + ec
    marks = np.zeros(ny * nx + 1, dtype=np.int32)
    marks[flat_start] = 1
    run_id = (np.cumsum(marks[:-1], dtype=np.int32) - 1).reshape(ny, nx)  # valid where m is true

    # Runs of adjacent rows touch wherever both rows are true (shifted by one column for the
    # diagonals). Inside a horizontal stretch of such cells no run can start (the cell to the left
    # is true in both rows), so the first cell of each stretch gives all the distinct pairs.
    def stretch_pairs(both: NDArray[np.bool_], ra: NDArray[np.int32], rb: NDArray[np.int32]) -> tuple:
        first = both.copy()
        first[:, 1:] &= ~both[:, :-1]
        return ra[first], rb[first]

    pairs = [stretch_pairs(m[:-1] & m[1:], run_id[:-1], run_id[1:])]
    if connectivity == 8:
        pairs.append(stretch_pairs(m[:-1, :-1] & m[1:, 1:], run_id[:-1, :-1], run_id[1:, 1:]))
        pairs.append(stretch_pairs(m[:-1, 1:] & m[1:, :-1], run_id[:-1, 1:], run_id[1:, :-1]))
    a = np.concatenate([p[0] for p in pairs]).astype(np.int64)
    b = np.concatenate([p[1] for p in pairs]).astype(np.int64)

    parent = np.arange(n_runs, dtype=np.int64)
    while len(a):
        pa, pb = parent[a], parent[b]
        differ = pa != pb
        if not differ.any():
            break
        lo = np.minimum(pa[differ], pb[differ])
        hi = np.maximum(pa[differ], pb[differ])
        # Invariant: parent[i] <= i, so the structure stays a forest and roots only shrink.
        np.minimum.at(parent, hi, lo)
        while True:
            pp = parent[parent]
            if np.array_equal(pp, parent):
                break
            parent = pp
    roots, inverse = np.unique(parent, return_inverse=True)
    run_label = inverse.astype(np.int32) + 1
    # Paint each run with its label: +label at its start, -label at its end, then a cumsum.
    paint = np.zeros(ny * nx + 1, dtype=np.int32)
    paint[flat_start] = run_label
    np.subtract.at(paint, flat_end, run_label)
    labels = np.cumsum(paint[:-1], dtype=np.int32).reshape(ny, nx)
    lengths = (flat_end - flat_start).astype(np.int64)
    sizes = np.zeros(len(roots) + 1, dtype=np.int64)
    np.add.at(sizes, run_label, lengths)
    sizes[0] = m.size - lengths.sum()
    return labels, sizes


def column_gap(occupied: BoolGrid, cap: int) -> NDArray[np.int32]:
    """Distance in cells, along each column, to the nearest occupied cell of that column.

    Parameters
    ----------
    occupied:
        Boolean grid ``(ny, nx)``.
    cap:
        Values are clipped to ``cap`` (also used for columns with no occupied cell).

    Returns
    -------
    int32 grid ``(ny, nx)``; 0 on occupied cells.
    """
    occ = np.asarray(occupied, dtype=bool)
    ny = occ.shape[0]
    big = ny + cap + 1
    idx = np.arange(ny, dtype=np.int64)[:, None]
    last = np.maximum.accumulate(np.where(occ, idx, -big), axis=0)
    nxt = np.minimum.accumulate(np.where(occ, idx, 2 * big)[::-1], axis=0)[::-1]
    gap = np.minimum(idx - last, nxt - idx)
    return np.minimum(gap, cap).astype(np.int32)


def _offset_sq(k: NDArray[np.int64]) -> NDArray[np.float64]:
    """Squared distance (cells²) from a cell centre to a cell ``k`` cells away, along one axis.

    The nearest point of the other square is ``|k| - 1/2`` away (0 for the cell itself).
    """
    e = np.maximum(np.abs(k).astype(np.float64) - 0.5, 0.0)
    return e * e


class ClearanceField:
    """Exact clearance queries on an occupancy grid, capped at a maximum distance.

    The clearance of a cell is the Euclidean distance (m) from its centre to the nearest point of
    an occupied cell square, or ``max_distance`` if that is farther. It is exact: along each
    column the nearest occupied cell minimises the vertical offset, so
    ``d² = min over columns x' of h(x - x') + h(gap(x'))`` with ``h(k) = max(|k| - 1/2, 0)²``.

    Parameters
    ----------
    occupied:
        Boolean grid ``(ny, nx)``.
    resolution:
        Cell size (m).
    origin:
        World ``(x, y)`` of the lower-left corner of cell ``[0, 0]`` (m).
    max_distance:
        Cap (m). Query cost grows linearly with it.
    """

    def __init__(self, occupied: BoolGrid, resolution: float, origin: NDArray[np.float64], max_distance: float):
        self.resolution = float(resolution)
        self.origin = np.asarray(origin, dtype=np.float64).reshape(2)
        self.max_distance = float(max_distance)
        self.shape = np.asarray(occupied).shape
        self.radius_cells = math.ceil(max_distance / resolution) + 1
        r = self.radius_cells
        gap = column_gap(occupied, cap=r + 1)
        # Outside the grid counts as free here; callers treat out-of-grid queries separately.
        self._gap_sq = np.pad(_offset_sq(gap.astype(np.int64)), ((0, 0), (r, r)), constant_values=np.inf)
        self._dx = np.arange(-r, r + 1, dtype=np.int64)
        self._dx_sq = _offset_sq(self._dx)

    def at_cells(self, iy: NDArray[np.int64], ix: NDArray[np.int64]) -> NDArray[np.float64]:
        """Clearance (m) of the given in-grid cells; index arrays of any common shape."""
        iy = np.asarray(iy, dtype=np.int64)
        ix = np.asarray(ix, dtype=np.int64)
        shape = np.broadcast_shapes(iy.shape, ix.shape)
        iy = np.broadcast_to(iy, shape).ravel()
        ix = np.broadcast_to(ix, shape).ravel()
        out = np.empty(iy.shape, dtype=np.float64)
        chunk = 1 << 16
        for s in range(0, len(iy), chunk):
            cols = ix[s : s + chunk, None] + self.radius_cells + self._dx[None, :]
            d2 = self._gap_sq[iy[s : s + chunk, None], cols] + self._dx_sq[None, :]
            out[s : s + chunk] = np.sqrt(d2.min(axis=1))
        return np.minimum(out * self.resolution, self.max_distance).reshape(shape)

    def at_points(self, points: NDArray[np.float64]) -> NDArray[np.float64]:
        """Lower bound of the clearance (m) of world points ``(..., 2)``.

        It is the clearance of the containing cell's centre minus the offset to that centre
        (clearance is 1-Lipschitz), clipped at 0. Points outside the grid get 0.
        """
        p = np.asarray(points, dtype=np.float64)
        g = (p - self.origin) / self.resolution
        ix = np.floor(g[..., 0]).astype(np.int64)
        iy = np.floor(g[..., 1]).astype(np.int64)
        ny, nx = self.shape
        inside = (ix >= 0) & (ix < nx) & (iy >= 0) & (iy < ny)
        off = np.hypot(g[..., 0] - ix - 0.5, g[..., 1] - iy - 0.5) * self.resolution
        c = self.at_cells(np.where(inside, iy, 0), np.where(inside, ix, 0))
        return np.where(inside, np.maximum(c - off, 0.0), 0.0)


def distance_map(occupied: BoolGrid, resolution: float, max_distance: float) -> NDArray[np.float64]:
    """Clearance (m) of every cell centre, capped at ``max_distance``; shape ``(ny, nx)``.

    Same definition as :class:`ClearanceField`, computed for the whole grid by shifting columns.
    Cells outside the grid count as free.
    """
    occ = np.asarray(occupied, dtype=bool)
    ny, nx = occ.shape
    r = math.ceil(max_distance / resolution) + 1
    gap_sq = np.pad(_offset_sq(column_gap(occ, cap=r + 1).astype(np.int64)), ((0, 0), (r, r)), constant_values=np.inf)
    best = np.full((ny, nx), np.inf)
    for dx in range(-r, r + 1):
        np.minimum(best, gap_sq[:, r + dx : r + dx + nx] + float(_offset_sq(np.array(dx))), out=best)
    return np.minimum(np.sqrt(best) * resolution, max_distance)


def fill_small_components(occupied: BoolGrid, max_cells: int) -> tuple[BoolGrid, int, int]:
    """Mark as occupied every free 4-connected component except the largest one.

    Parameters
    ----------
    occupied:
        Boolean grid ``(ny, nx)``.
    max_cells:
        Components bigger than this are not filled (they indicate a real disconnection).

    Returns
    -------
    grid:
        New boolean grid with the small components filled.
    n_filled:
        Number of components filled.
    largest_other:
        Size (cells) of the largest free component left besides the main one (0 if none).
    """
    occ = np.asarray(occupied, dtype=bool)
    labels, sizes = label_components(~occ, connectivity=4)
    if len(sizes) <= 2:
        return occ.copy(), 0, 0
    comp = sizes[1:]
    main = int(np.argmax(comp)) + 1
    small = np.zeros(len(sizes), dtype=bool)
    small[1:] = comp <= max_cells
    small[main] = False
    big_other = np.zeros(len(sizes), dtype=bool)
    big_other[1:] = comp > max_cells
    big_other[main] = False
    out = occ | small[labels]
    largest_other = int(sizes[big_other].max()) if big_other.any() else 0
    return out, int(small.sum()), largest_other
