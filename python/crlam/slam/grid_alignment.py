"""The dominant wall direction of a scan, to turn the map's grid parallel to a building's walls.

Most buildings are rectilinear: their walls run along two perpendicular directions. A map grid at
an angle to them draws every wall as a staircase of cells, and an endpoint matcher that places a
wall at its cells' centres then sees the wall up to half a cell off its line, differently from
every viewpoint: the heading drifts. :func:`wall_direction` estimates the walls' direction from
one scan; a filter that starts its map in a frame turned by that angle about the first pose has
its grid on the walls, whatever the robot's first heading.

The estimate: each endpoint whose ``2 * window + 1`` neighbours lie on a straight line (principal
axes of the points; residual below ``max_residual``) gives the line's direction phi, weighted by
the length of wall it stands for (the mean gap to its neighbours). Directions are taken modulo
90 deg as the fourfold circular mean, ``arg(sum w exp(4 i phi)) / 4``, so the two perpendicular
wall directions of a rectilinear building vote together. The length of that mean over the total
weight (0 to 1) says how rectilinear the scan is.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from crlam.errors import DataFormatError
from crlam.pose import compose, inverse

__all__ = [
    "GRID_ALIGNMENTS",
    "MIN_CONCENTRATION",
    "MIN_TURN",
    "MIN_WALL_LENGTH",
    "SUB_CELL_CHOICES",
    "WallDirection",
    "frame_from_record",
    "from_map_frame",
    "into_map_frame",
    "map_frame",
    "map_turn",
    "wall_direction",
    "walls_found",
]

#: Values of ``SlamConfig.grid_alignment``.
GRID_ALIGNMENTS = ("none", "walls")
#: Values of ``SlamConfig.sub_cell``: when the filter uses the sub-cell geometry.
SUB_CELL_CHOICES = ("off", "on", "unaligned")
#: The first scan must show at least this much straight wall (m) ...
MIN_WALL_LENGTH = 2.0
#: ... of which at least this share within ``agreement_deg`` of the dominant direction.
MIN_CONCENTRATION = 0.5
#: Smaller turns (rad) are not made.
MIN_TURN = math.radians(1.0)


@dataclass(frozen=True)
class WallDirection:
    """The dominant wall direction of a scan.

    Attributes
    ----------
    angle : float
        Direction of the walls (rad) in the robot's frame, modulo 90 deg, in [-pi/4, pi/4).
    concentration : float
        Length of the fourfold circular mean (0: no dominant direction, 1: every straight piece
        of wall along one of two perpendicular directions).
    wall_length : float
        Total length (m) of the straight pieces of wall that voted.
    """

    angle: float
    concentration: float
    wall_length: float


def wall_direction(
    angles: ArrayLike,
    ranges: ArrayLike,
    laser_offset: ArrayLike = (0.0, 0.0, 0.0),
    *,
    max_range: float = 8.0,
    window: int = 3,
    max_residual: float = 0.03,
    bandwidth_deg: float = 2.0,
    agreement_deg: float = 5.0,
) -> WallDirection:
    """The dominant direction of the straight walls one scan sees (module docstring).

    Parameters
    ----------
    angles, ranges : array_like, shape (n,)
        Beam bearings (rad) in the laser's frame and ranges (m).
    laser_offset : array_like, shape (3,)
        The laser's pose (x m, y m, theta rad) in the robot's frame.
    max_range : float
        Readings at or beyond it (m), and non-finite or non-positive ones, are left out.
    window : int
        Neighbours on each side of an endpoint that must lie on its line.
    max_residual : float
        Largest root-mean-square distance (m) of those points from their fitted line.

    Returns
    -------
    WallDirection
        ``angle`` 0 with ``concentration`` 0 when no straight piece of wall was found.
    """
    a = np.asarray(angles, dtype=np.float64).reshape(-1)
    r = np.asarray(ranges, dtype=np.float64).reshape(-1)
    off = np.asarray(laser_offset, dtype=np.float64).reshape(-1)
    if a.shape != r.shape:
        raise DataFormatError(f"wall_direction: {a.shape[0]} bearings for {r.shape[0]} ranges")
    if off.shape != (3,):
        raise DataFormatError(f"wall_direction: laser_offset must have 3 values, got {off.shape[0]}")
    n = a.shape[0]
    valid = np.isfinite(r) & np.isfinite(a) & (r > 0.0) & (r < max_range)
    # Endpoints in the laser's frame; a direction in the robot's frame adds the laser's heading.
    r0 = np.where(valid, r, 0.0)
    a0 = np.where(np.isfinite(a), a, 0.0)
    xy = np.stack([r0 * np.cos(a0), r0 * np.sin(a0)], axis=1)
    k = 2 * window + 1
    if n < k:
        return WallDirection(0.0, 0.0, 0.0)
    gaps = np.linalg.norm(np.diff(xy, axis=0), axis=1)
    # A gap wider than a beam's footprint at grazing incidence (three spacings, at least 0.2 m)
    # is a break in the wall: a door, an occlusion, another surface.
    spacing = np.abs(np.diff(a0))
    max_gap = np.maximum(0.2, 3.0 * np.maximum(r0[:-1], r0[1:]) * spacing)
    joined = valid[:-1] & valid[1:] & (gaps <= max_gap)
    phis: list[float] = []
    weights: list[float] = []
    for i in range(window, n - window):
        if not joined[i - window : i + window].all():
            continue
        pts = xy[i - window : i + window + 1]
        centred = pts - pts.mean(axis=0)
        evals, evecs = np.linalg.eigh(centred.T @ centred / k)
        if np.sqrt(max(evals[0], 0.0)) > max_residual:
            continue
        phis.append(float(np.arctan2(evecs[1, 1], evecs[0, 1]) + off[2]))
        weights.append(float(gaps[i - window : i + window].mean()))
    total = float(sum(weights))
    if total <= 0.0:
        return WallDirection(0.0, 0.0, 0.0)
    phi = np.array(phis)
    w = np.array(weights)
    # The mode of the fourfold direction density (von Mises kernels of about 2 deg in phi) on a
    # 0.25 deg raster: a few walls at other angles (furniture, a diagonal wall) do not pull it.
    grid = np.deg2rad(np.arange(-45.0, 45.0, 0.25))
    kappa = 1.0 / np.deg2rad(4.0 * bandwidth_deg) ** 2
    density = (w[None, :] * np.exp(kappa * (np.cos(4.0 * (phi[None, :] - grid[:, None])) - 1.0))).sum(axis=1)
    coarse = float(grid[int(np.argmax(density))])
    # Refine: the weighted fourfold mean of the directions within the agreement band of the mode.
    dev = (phi - coarse + np.pi / 4) % (np.pi / 2) - np.pi / 4
    near = np.abs(dev) <= np.deg2rad(agreement_deg)
    angle = coarse + float(np.average(dev[near], weights=w[near])) if near.any() else coarse
    angle = (angle + np.pi / 4) % (np.pi / 2) - np.pi / 4
    return WallDirection(angle, float(w[near].sum() / total), total)


def map_turn(
    angles: ArrayLike, ranges: ArrayLike, laser_offset: ArrayLike, heading: float, *, max_range: float = 8.0
) -> tuple[float, WallDirection]:
    """The turn (rad) of the map's frame that puts the grid on the walls of a first scan.

    ``heading`` is the robot's heading (rad) in the odometry frame when it took the scan. A
    frame turned by the returned angle about the robot's position sees the walls along its axes.
    The turn is 0 unless the scan shows ``MIN_WALL_LENGTH`` of straight wall, ``MIN_CONCENTRATION``
    of it along one rectilinear direction, and the walls are at least ``MIN_TURN`` off the grid.

    Returns
    -------
    turn : float
        In [-pi/4, pi/4).
    walls : WallDirection
        The scan's estimate it was taken from.
    """
    walls = wall_direction(angles, ranges, laser_offset, max_range=max_range)
    if not walls_found(walls):
        return 0.0, walls
    off_grid = (walls.angle + heading + math.pi / 4) % (math.pi / 2) - math.pi / 4
    if abs(off_grid) < MIN_TURN:
        return 0.0, walls
    return -off_grid, walls


def walls_found(walls: WallDirection) -> bool:
    """Whether a scan shows rectilinear walls to lay the grid on: at least ``MIN_WALL_LENGTH`` of
    straight wall, ``MIN_CONCENTRATION`` of it along one rectilinear direction. When it does,
    :func:`map_turn` puts the grid on them (or finds it already there)."""
    return walls.wall_length >= MIN_WALL_LENGTH and walls.concentration >= MIN_CONCENTRATION


def map_frame(turn: float, pivot: ArrayLike) -> NDArray[np.float64]:
    """The map's frame in the odometry frame's terms, as the pose (3,) F with ``compose(F, q)``
    the odometry pose ``q`` in the map's frame: a turn by ``turn`` (rad) about ``pivot`` (x, y m).
    """
    c, s = math.cos(turn), math.sin(turn)
    px, py = float(np.asarray(pivot, dtype=np.float64)[0]), float(np.asarray(pivot, dtype=np.float64)[1])
    return np.array([px - (c * px - s * py), py - (s * px + c * py), turn])


def into_map_frame(frame: NDArray[np.float64], poses: ArrayLike) -> NDArray[np.float64]:
    """Odometry-frame poses (..., 3) in the map's frame ``frame`` (:func:`map_frame`)."""
    p = np.array(poses, dtype=np.float64)
    return p if float(frame[2]) == 0.0 else compose(frame, p)


def from_map_frame(frame: NDArray[np.float64], poses: ArrayLike) -> NDArray[np.float64]:
    """Poses (..., 3) of the map's frame ``frame`` (:func:`map_frame`) in the odometry's frame."""
    p = np.array(poses, dtype=np.float64)
    return p if float(frame[2]) == 0.0 else compose(inverse(frame), p)


def frame_from_record(record: Mapping[str, Any] | None) -> NDArray[np.float64]:
    """The map's frame from what ``metrics.json`` records under ``map_frame`` (the identity for
    a run folder written without it)."""
    if not record or not record.get("turn_deg") or record.get("pivot") is None:
        return np.zeros(3)
    return map_frame(math.radians(float(record["turn_deg"])), record["pivot"])
