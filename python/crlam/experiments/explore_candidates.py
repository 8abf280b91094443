"""The candidate goals of one exploration decision: the rule shared by the simulated exploration
(:func:`crlam.experiments.explore.explore`) and the live ROS explorer
(:func:`crlam.ros.explore_goal.choose_goal`).

Up to ``n_candidates`` cells in all: half of them reachable cells within ``radius_m`` of the
robot, half frontier cells (anywhere reachable), each half topped up from the other when it runs
short, drawn without replacement from ``rng`` (the near cells first, then the frontier cells:
the order of the draws is part of a seeded run's result).
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
from numpy.typing import NDArray

__all__ = ["Candidates", "pick_candidates", "sorted_unique"]


class Candidates(NamedTuple):
    """The candidates of one decision.

    Attributes
    ----------
    idx : ndarray of int64, shape (n,)
        The chosen reachable cells, sorted: indices into ``wy``, ``wx`` and ``centres``.
    wy, wx : ndarray of int64, shape (m,)
        Every reachable cell of the window (rows, columns of the window), in row-major order.
    centres : ndarray of float64, shape (m, 2)
        The world position (x, y) in metres of each reachable cell's centre.
    """

    idx: NDArray[np.int64]
    wy: NDArray[np.int64]
    wx: NDArray[np.int64]
    centres: NDArray[np.float64]


def sorted_unique(a: NDArray[np.int64]) -> NDArray[np.int64]:
    """``np.unique(a)`` for a 1-D integer array. numpy >= 2.3's ``unique`` imports ``numpy.ma`` on
    its first call (~50 ms, which would land in the first decision's time)."""
    s = np.sort(a)
    return s[np.concatenate([[True], s[1:] != s[:-1]])] if s.size else s


def pick_candidates(
    reach: NDArray[np.bool_],
    frontier: NDArray[np.bool_],
    window_origin: tuple[int, int],
    grid_origin: tuple[float, float],
    resolution: float,
    position: NDArray[np.float64],
    radius_m: float,
    n_candidates: int,
    rng: np.random.Generator,
) -> Candidates:
    """The candidate cells of one decision (the rule of the module docstring).

    Parameters
    ----------
    reach, frontier : ndarray of bool, shape (wny, wnx)
        The window's reachable cells and its frontier cells (a subset of ``reach``).
    window_origin : (iy0, ix0)
        The grid cell of the window's cell (0, 0).
    grid_origin : (x, y)
        The world position (m) of the grid's corner (the lower-left corner of its cell (0, 0)).
    resolution : float
        Cell size (m).
    position : ndarray, shape (>= 2,)
        The robot's position (x, y, ...) in metres.
    radius_m : float
        Reachable cells within this distance (m) of ``position`` are the near candidates.
    n_candidates : int
        The most candidates returned.
    rng : numpy.random.Generator
        The draws among the near and the frontier cells when there are more than are taken.
    """
    # Window cells (wy, wx) in row-major order, the order of the whole map's cells.
    wy, wx = np.nonzero(reach)
    cy, cx = wy + window_origin[0], wx + window_origin[1]
    centres = np.column_stack([grid_origin[0] + (cx + 0.5) * resolution, grid_origin[1] + (cy + 0.5) * resolution])
    within = np.hypot(*(centres - position[:2]).T) <= radius_m
    pick = np.flatnonzero(within)
    fr = np.flatnonzero(frontier[wy, wx])
    n_fr = min(len(fr), max(n_candidates // 2, n_candidates - len(pick)))
    n_near = min(len(pick), n_candidates - n_fr)
    if len(pick) > n_near:
        pick = rng.choice(pick, n_near, replace=False)
    if len(fr) > n_fr:
        fr = rng.choice(fr, n_fr, replace=False)
    idx = sorted_unique(np.concatenate([pick, fr]).astype(np.int64))
    return Candidates(idx, wy.astype(np.int64), wx.astype(np.int64), centres)
