"""``crlam slam --mcap``: a run recorded as ``run.mcap``, a ROS 2 MCAP file of standard messages.

It opens in Foxglove and plays with ``ros2 bag play`` (ROS 2 Iron and later take a ``.mcap``
file). Topics (frames ``map``, ``odom``, ``base_link``, ``laser``):

``/scan`` (``sensor_msgs/msg/LaserScan``)
    Every scan the filter was given, stamped with its timestamp, as the filter saw it
    (no-returns ``+inf``; ranges and bearings float32, as the message stores them).
``/tf`` (``tf2_msgs/msg/TFMessage``)
    At every scan ``odom -> base_link`` (the odometry pose), and at every processed scan
    ``map -> odom`` as well: the weighted-mean estimate composed with the inverse odometry pose.
``/tf_static`` (``tf2_msgs/msg/TFMessage``)
    ``base_link -> laser``, the laser offset of the first scan.
``/particles`` (``geometry_msgs/msg/PoseArray``)
    The particle poses after every processed scan (after resampling, when the step resampled).
``/path`` (``nav_msgs/msg/Path``)
    Once, at the last scan: the estimate of every scan (the poses of ``trajectory.tum``).
``/map`` (``nav_msgs/msg/OccupancyGrid``)
    Once, at the last scan: the best particle's map (``map.pgm``): expected occupancy (or, for
    RBPF-OGM, the occupancy probability) times 100, rounded; -1 for unknown cells.
``/map_confidence`` (``nav_msgs/msg/OccupancyGrid``)
    Once, beside ``/map``, RBPF-CLAM only: the standard deviation of each cell's occupancy
    times 200 (0 = certain; 100 = 0.5, the largest a value in [0, 1] can have), -1 for
    unknown cells. Shown with a costmap colour scheme it marks where the map is unsure.

``/map`` and ``/map_confidence`` and ``/tf_static`` are offered as transient-local (latched).
Message receive times are the stamps, kept in order (a scan stamped before the previous one is
received when that one was).
"""

from __future__ import annotations

import os
from typing import Any, NamedTuple

import numpy as np
from numpy.typing import NDArray

from crlam.io.carmen_types import LaserScan
from crlam.io.rosbag_writer import (
    LASER_SCAN,
    OCCUPANCY_GRID,
    PATH,
    POSE_ARRAY,
    TF_MESSAGE,
    McapBagWriter,
    ros_time,
)
from crlam.mapping import MapLayer
from crlam.pose import compose, inverse

__all__ = ["GridInfo", "SlamMcapRecorder", "occupancy_grid_values"]

MAP_FRAME = "map"
ODOM_FRAME = "odom"
BASE_FRAME = "base_link"
LASER_FRAME = "laser"


class GridInfo(NamedTuple):
    """Where an OccupancyGrid lies: ``shape`` (ny, nx), ``origin`` world (x, y) of the lower-left
    corner of cell [0, 0] (m), ``resolution`` cell size (m)."""

    shape: tuple[int, int]
    origin: tuple[float, float]
    resolution: float


def occupancy_grid_values(values: NDArray[np.float64], unknown: NDArray[np.bool_], scale: float = 100.0) -> NDArray[np.int8]:
    """``round(scale * values)`` clipped to 0..100, -1 where ``unknown`` (or not finite), as the
    row-major int8 data of an OccupancyGrid (row 0 at the minimum y, as in a :class:`MapLayer`)."""
    v = np.asarray(values, dtype=np.float64)
    out = np.clip(np.rint(np.nan_to_num(v, nan=0.0) * scale), 0, 100).astype(np.int8)
    out[np.asarray(unknown, dtype=bool) | ~np.isfinite(v)] = -1
    return out.reshape(-1)


class SlamMcapRecorder:
    """Writes a run to an MCAP file while it runs (see the module docstring).

    Call :meth:`scan` after every ``SlamRun.step``, then :meth:`finish` with the trajectory and
    the map, or :meth:`close` (after an error: the file is dropped).
    """

    def __init__(self, path: str | os.PathLike[str]) -> None:
        self.bag = McapBagWriter(path)
        self.path = self.bag.path
        self._last_ns = 0
        self._last_t = 0.0
        self._first = True

    def _time(self, t: float) -> int:
        sec, nsec = ros_time(max(float(t), 0.0))
        self._last_ns = max(self._last_ns, sec * 1_000_000_000 + nsec)
        self._last_t = max(self._last_t, float(t))
        return self._last_ns

    def scan(self, rec: LaserScan, processed: bool, estimate: NDArray[np.float64], particles: NDArray[np.float64] | None) -> None:
        """Record one scan: the scan, ``odom -> base_link``, and for a processed scan
        ``map -> odom`` and the particle poses (``particles``, shape (n, 3), or None)."""
        bag = self.bag
        t = float(rec.timestamp)
        t_ns = self._time(t)
        if self._first:
            static = bag.transform(t, BASE_FRAME, LASER_FRAME, rec.laser_offset)
            bag.write("/tf_static", TF_MESSAGE, t_ns, bag.tf([static]), latched=True)
            self._first = False
        ranges = np.where(rec.ranges >= rec.max_range, np.inf, rec.ranges)
        msg = bag.laser_scan(t, LASER_FRAME, ranges, rec.angle_min, rec.angle_increment, rec.max_range)
        bag.write("/scan", LASER_SCAN, t_ns, msg)
        transforms = [bag.transform(t, ODOM_FRAME, BASE_FRAME, rec.odom)]
        if processed:
            # map -> odom such that map -> odom -> base_link is the estimate.
            map_odom = compose(estimate, inverse(rec.odom))
            transforms.insert(0, bag.transform(t, MAP_FRAME, ODOM_FRAME, map_odom))
        bag.write("/tf", TF_MESSAGE, t_ns, bag.tf(transforms))
        if processed and particles is not None:
            pa = bag.types[POSE_ARRAY](header=bag.header(t, MAP_FRAME), poses=[bag.pose(p) for p in particles])
            bag.write("/particles", POSE_ARRAY, t_ns, pa)

    def _grid(self, t: float, layer: GridInfo, data: NDArray[np.int8]) -> Any:
        return self.bag.occupancy_grid(t, MAP_FRAME, layer.shape, layer.origin, layer.resolution, data)

    def finish(
        self,
        stamps: NDArray[np.float64],
        poses: NDArray[np.float64],
        occupancy: MapLayer,
        unknown: NDArray[np.bool_],
        std: MapLayer | None,
    ) -> dict[str, int]:
        """Write ``/path``, ``/map`` and (with ``std``) ``/map_confidence`` at the last scan's
        time and close the file; returns the message count of every topic."""
        grid = GridInfo(occupancy.shape, occupancy.origin, occupancy.resolution)
        data = occupancy_grid_values(occupancy.values, unknown)
        confidence = None if std is None else occupancy_grid_values(std.values, unknown, scale=200.0)
        return self.finish_grids(stamps, poses, grid, data, confidence)

    def finish_grids(
        self,
        stamps: NDArray[np.float64],
        poses: NDArray[np.float64],
        grid: GridInfo,
        data: NDArray[np.int8],
        confidence: NDArray[np.int8] | None,
    ) -> dict[str, int]:
        """:meth:`finish` with the grids' data already made (:func:`occupancy_grid_values`,
        ``(ny * nx,)`` int8 each; e.g. band by band by :func:`crlam.experiments.map_outputs.map_products`)."""
        bag = self.bag
        t = self._last_t
        t_ns = self._last_ns
        T = bag.types
        stamped = [
            T["geometry_msgs/msg/PoseStamped"](header=bag.header(float(s), MAP_FRAME), pose=bag.pose(p))
            for s, p in zip(stamps, poses)
        ]
        bag.write("/path", PATH, t_ns, T[PATH](header=bag.header(t, MAP_FRAME), poses=stamped))
        bag.write("/map", OCCUPANCY_GRID, t_ns, self._grid(t, grid, data), latched=True)
        if confidence is not None:
            bag.write("/map_confidence", OCCUPANCY_GRID, t_ns, self._grid(t, grid, confidence), latched=True)
        counts = dict(bag.counts)
        bag.close()
        return counts

    def close(self) -> None:
        """Drop an unfinished recording."""
        self.bag.close(keep=False)
