"""``crlam slam|localize --foxglove [PORT]``: an offline run served live on a Foxglove WebSocket.

The topics are those of ``run.mcap`` (:mod:`crlam.experiments.slam_mcap`: frames ``map``,
``odom``, ``base_link``, ``laser``), sent while the run goes rather than at its end:

``/scan``, ``/tf`` (``odom -> base_link``; ``map -> odom`` at processed scans)
    At every scan.
``/tf_static``
    Once, at the first scan: ``base_link -> laser``.
``/particles`` (PoseArray), ``/pose`` (PoseWithCovarianceStamped)
    At every processed scan.
``/map`` and ``/map_confidence`` (OccupancyGrid, as in ``run.mcap``), ``/path`` (Path)
    The best particle's map at most every ``map_period`` s of wall time while a client
    subscribes to it (making a map costs time: nothing is made for nobody), and once more, the
    run's final map (exactly ``run.mcap``'s ``/map``), when the run ends. A localization
    publishes its known map once, at the start (:meth:`SlamLiveFeed.publish_known_map`), and
    ``/path`` at the end.

``/map``, ``/map_confidence`` and ``/tf_static`` are latched (:meth:`crlam.live_view.LiveView.publish`):
a client that subscribes later receives the newest one at once.
"""

from __future__ import annotations

import time
from typing import Any

import numpy as np
from numpy.typing import NDArray

from crlam.experiments.slam_mcap import BASE_FRAME, LASER_FRAME, MAP_FRAME, ODOM_FRAME, GridInfo
from crlam.io.carmen_types import LaserScan
from crlam.io.rosbag_writer import LASER_SCAN, OCCUPANCY_GRID, PATH, POSE_ARRAY, TF_MESSAGE, RosMessageBuilder, ros_time
from crlam.live_view import LiveView
from crlam.pose import compose, inverse

__all__ = ["TOPICS", "SlamLiveFeed"]

POSE_COV = "geometry_msgs/msg/PoseWithCovarianceStamped"

#: Topic -> ROS 2 type of an offline run's view.
TOPICS = {
    "/scan": LASER_SCAN,
    "/tf": TF_MESSAGE,
    "/tf_static": TF_MESSAGE,
    "/particles": POSE_ARRAY,
    "/pose": POSE_COV,
    "/path": PATH,
    "/map": OCCUPANCY_GRID,
    "/map_confidence": OCCUPANCY_GRID,
}


class SlamLiveFeed:
    """Feeds a :class:`~crlam.live_view.LiveView` from an offline run.

    Call :meth:`scan` after every ``SlamRun.step``, :meth:`finish` with the run's final
    trajectory and map, and :meth:`publish_final` once the run folder is written.

    Parameters
    ----------
    view : LiveView
        The server.
    map_period : float
        Wall seconds between two maps during the run (s).
    """

    def __init__(self, view: LiveView, map_period: float = 1.0) -> None:
        self.view = view
        self.msgs = RosMessageBuilder(view.types)
        self.map_period = float(map_period)
        self._last_map_wall = -np.inf
        self._static: Any = None
        self._last_t = 0.0
        self.path: list[tuple[float, NDArray[np.float64]]] = []
        self._final: tuple[Any, ...] | None = None
        self.fixed_map = False
        view.announce(TOPICS)

    def _ns(self, t: float) -> int:
        sec, nsec = ros_time(max(float(t), 0.0))
        return sec * 1_000_000_000 + nsec

    def publish_known_map(self, occupancy: Any) -> None:
        """A localization's map (a :class:`crlam.mapping.MapLayer` of expected occupancy, NaN
        unknown), published once, latched; the run then publishes no map of its own."""
        from crlam.experiments.slam_mcap import occupancy_grid_values

        values = np.asarray(occupancy.values, dtype=np.float64)
        grid = GridInfo(values.shape, tuple(occupancy.origin), float(occupancy.resolution))  # type: ignore[arg-type]
        self._publish_grids(0.0, grid, occupancy_grid_values(values, ~np.isfinite(values)), None)
        self.fixed_map = True

    def scan(
        self,
        run: Any,
        rec: LaserScan,
        processed: bool,
        estimate: NDArray[np.float64],
        particles: NDArray[np.float64] | None,
        spread: tuple[float, float] | None = None,
    ) -> None:
        """Publishes one scan's messages (``particles``: shape (n, 3), or None; ``spread``: the
        particles' (position m, heading rad) spread, default the SLAM run's last particle set's)."""
        v, b = self.view, self.msgs
        t = max(float(rec.timestamp), self._last_t)
        self._last_t = t
        t_ns = self._ns(t)
        wall = time.monotonic()
        if self._static is None:
            self._static = b.tf([b.transform(t, BASE_FRAME, LASER_FRAME, rec.laser_offset)])
            v.publish("/tf_static", TF_MESSAGE, self._static, t_ns, latched=True)
        if v.has_subscriber("/scan", LASER_SCAN):  # messages are built only for someone
            ranges = np.where(rec.ranges >= rec.max_range, np.inf, rec.ranges)
            scan = b.laser_scan(t, LASER_FRAME, ranges, rec.angle_min, rec.angle_increment, rec.max_range)
            v.publish("/scan", LASER_SCAN, scan, t_ns)
        transforms = [b.transform(t, ODOM_FRAME, BASE_FRAME, rec.odom)]
        est = np.asarray(estimate, dtype=np.float64)
        self.path.append((t, est))
        if processed:
            transforms.insert(0, b.transform(t, MAP_FRAME, ODOM_FRAME, compose(est, inverse(rec.odom))))
        v.publish("/tf", TF_MESSAGE, b.tf(transforms), t_ns)
        if not processed:
            return
        if particles is not None and v.has_subscriber("/particles", POSE_ARRAY):
            v.publish(
                "/particles",
                POSE_ARRAY,
                v.types[POSE_ARRAY](header=b.header(t, MAP_FRAME), poses=[b.pose(p) for p in particles]),
                t_ns,
            )
        if particles is not None:
            if spread is None and getattr(run, "particle_sets", None):
                spread = (float(run.particle_sets[-1].spread_xy), float(run.particle_sets[-1].spread_theta))
            v.publish("/pose", POSE_COV, self._pose_msg(t, est, spread), t_ns)
        if self.fixed_map:
            return
        if wall - self._last_map_wall >= self.map_period and (v.wants("/map") or v.wants("/map_confidence") or v.wants("/path")):
            self._last_map_wall = wall
            self._publish_map(run, t)

    def _pose_msg(self, t: float, est: NDArray[np.float64], spread: tuple[float, float] | None) -> Any:
        T, b = self.view.types, self.msgs
        cov = np.zeros(36)
        if spread is not None:
            # The particle set's spread: RMS position spread shared by x and y, heading spread (as crlam ros slam).
            cov[0] = cov[7] = spread[0] ** 2 / 2
            cov[35] = spread[1] ** 2
        return T[POSE_COV](
            header=b.header(t, MAP_FRAME), pose=T["geometry_msgs/msg/PoseWithCovariance"](pose=b.pose(est), covariance=cov)
        )

    def _publish_map(self, run: Any, t: float) -> None:
        from crlam.experiments.map_outputs import map_products

        products = map_products(run.best_map(), grids=True)
        assert products.grid is not None
        grid = GridInfo(products.shape, products.origin, products.resolution)
        self._publish_grids(t, grid, products.grid, products.confidence_grid)
        stamps = np.array([s for s, _ in self.path])
        poses = np.array([p for _, p in self.path])
        self._publish_path(t, stamps, poses)

    def _grid_msg(self, t: float, layer: GridInfo, data: NDArray[np.int8]) -> Any:
        return self.msgs.occupancy_grid(t, MAP_FRAME, layer.shape, layer.origin, layer.resolution, data)

    def _publish_grids(self, t: float, grid: GridInfo, data: NDArray[np.int8], confidence: NDArray[np.int8] | None) -> None:
        t_ns = self._ns(t)
        self.view.publish("/map", OCCUPANCY_GRID, self._grid_msg(t, grid, data), t_ns, latched=True)
        if confidence is not None:
            self.view.publish("/map_confidence", OCCUPANCY_GRID, self._grid_msg(t, grid, confidence), t_ns, latched=True)

    def _publish_path(self, t: float, stamps: NDArray[np.float64], poses: NDArray[np.float64]) -> None:
        T, b = self.view.types, self.msgs
        stamped = [
            T["geometry_msgs/msg/PoseStamped"](header=b.header(float(s), MAP_FRAME), pose=b.pose(p))
            for s, p in zip(stamps, poses)
        ]
        self.view.publish("/path", PATH, T[PATH](header=b.header(t, MAP_FRAME), poses=stamped), self._ns(t))

    def finish(
        self,
        stamps: NDArray[np.float64],
        poses: NDArray[np.float64],
        grid: GridInfo,
        data: NDArray[np.int8],
        confidence: NDArray[np.int8] | None,
    ) -> None:
        """Keeps the run's final trajectory and grids (those of
        :func:`crlam.experiments.map_outputs.map_products`, as ``run.mcap`` holds them) for
        :meth:`publish_final`: the command publishes them once its run folder is in place."""
        self._final = (np.asarray(stamps), np.asarray(poses), grid, data, confidence)

    def finish_path(self, stamps: NDArray[np.float64], poses: NDArray[np.float64]) -> None:
        """:meth:`finish` for a run without a map of its own (a localization): the trajectory only."""
        self._final = (np.asarray(stamps), np.asarray(poses), None, None, None)

    def publish_final(self) -> bool:
        """Publishes the final ``/path``, ``/map`` and ``/map_confidence``, stamped with the last
        scan's time; False if :meth:`finish` was not called."""
        if self._final is None:
            return False
        stamps, poses, grid, data, confidence = self._final
        t = self._last_t
        self._publish_path(t, stamps, poses)
        if grid is not None:
            self._publish_grids(t, grid, data, confidence)
        return True
