"""``crlam explore --foxglove [PORT]``: a simulated exploration served live on a Foxglove WebSocket.

The topics of ``crlam ros explore`` (ROS 2 messages, :mod:`crlam.live_view`), stamped with the
simulation's time (:data:`SCAN_PERIOD` s per scan from 0):

``/scan`` (LaserScan, frame ``base_link``), ``/tf`` (``map -> base_link``: the estimate)
    At every scan.
``/map`` (OccupancyGrid: expected occupancy x 100, -1 unobserved; latched), ``/path``, ``/pose``
    At every decision.
``/goal_pose`` (PoseStamped), ``/explore/candidates`` (MarkerArray)
    At every decision: the chosen goal, and every candidate as a sphere coloured by its score
    (blue low, red high; the goal larger), after a DELETEALL marker.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np
from numpy.typing import NDArray

from crlam.experiments.slam_mcap import occupancy_grid_values
from crlam.io.rosbag_writer import LASER_SCAN, OCCUPANCY_GRID, PATH, TF_MESSAGE, RosMessageBuilder, ros_time
from crlam.live_view import LiveView

__all__ = ["SCAN_PERIOD", "TOPICS", "ExploreLiveFeed"]

#: Simulated seconds between two scans (the stamps of the view).
SCAN_PERIOD = 0.1

POSE_STAMPED = "geometry_msgs/msg/PoseStamped"
POSE_COV = "geometry_msgs/msg/PoseWithCovarianceStamped"
MARKER_ARRAY = "visualization_msgs/msg/MarkerArray"

#: Topic -> ROS 2 type of an exploration's view.
TOPICS = {
    "/scan": LASER_SCAN,
    "/tf": TF_MESSAGE,
    "/map": OCCUPANCY_GRID,
    "/path": PATH,
    "/pose": POSE_COV,
    "/goal_pose": POSE_STAMPED,
    "/explore/candidates": MARKER_ARRAY,
}


class ExploreLiveFeed:
    """The ``on_event`` of :func:`crlam.experiments.explore.explore` that feeds a :class:`LiveView`."""

    def __init__(self, view: LiveView) -> None:
        self.view = view
        self.msgs = RosMessageBuilder(view.types)
        self.n_scans = 0
        view.announce(TOPICS)

    @property
    def t(self) -> float:
        """The simulation's time of the latest scan (s)."""
        return max(self.n_scans - 1, 0) * SCAN_PERIOD

    def _ns(self) -> int:
        sec, nsec = ros_time(self.t)
        return sec * 1_000_000_000 + nsec

    def scan(
        self, estimate: NDArray[np.float64], angles: NDArray[np.float64], ranges: NDArray[np.float64], max_range: float
    ) -> None:
        """One scan at the estimate (the sensor at the robot's centre, bearings from its heading)."""
        self.n_scans += 1
        v, b, t = self.view, self.msgs, self.t
        a = np.asarray(angles, dtype=np.float64)
        inc = float(a[1] - a[0]) if len(a) > 1 else 0.0
        v.publish("/tf", TF_MESSAGE, b.tf([b.transform(t, "map", "base_link", estimate)]), self._ns())
        v.publish("/scan", LASER_SCAN, b.laser_scan(t, "base_link", ranges, float(a[0]), inc, max_range), self._ns())

    def decision(
        self,
        maps: Any,
        origin: tuple[float, float],
        resolution: float,
        candidates: NDArray[np.float64],
        scores: NDArray[np.float64],
        best: int,
        estimates: NDArray[np.float64],
    ) -> None:
        """One decision: the map it was made on, the path, the goal and the scored candidates."""
        v, b, t, t_ns = self.view, self.msgs, self.t, self._ns()
        T = v.types
        if v.has_subscriber("/map", OCCUPANCY_GRID):
            mean = maps.whole(maps.mean, maps.prior_mean)
            observed = maps.whole(maps.observed, False)
            ny, nx = mean.shape
            sec, nsec = ros_time(t)
            info = T["nav_msgs/msg/MapMetaData"](
                map_load_time=T["builtin_interfaces/msg/Time"](sec=sec, nanosec=nsec),
                resolution=float(resolution),
                width=nx,
                height=ny,
                origin=b.pose((origin[0], origin[1], 0.0)),
            )
            grid = T[OCCUPANCY_GRID](header=b.header(t, "map"), info=info, data=occupancy_grid_values(mean, ~observed))
            v.publish("/map", OCCUPANCY_GRID, grid, t_ns, latched=True)
        est = np.asarray(estimates[-1], dtype=np.float64)
        stamped = [T[POSE_STAMPED](header=b.header(t, "map"), pose=b.pose(p)) for p in estimates]
        v.publish("/path", PATH, T[PATH](header=b.header(t, "map"), poses=stamped), t_ns)
        with_cov = T["geometry_msgs/msg/PoseWithCovariance"](pose=b.pose(est), covariance=np.zeros(36))
        v.publish("/pose", POSE_COV, T[POSE_COV](header=b.header(t, "map"), pose=with_cov), t_ns)
        goal = candidates[best]
        heading = math.atan2(goal[1] - est[1], goal[0] - est[0])
        v.publish(
            "/goal_pose", POSE_STAMPED, T[POSE_STAMPED](header=b.header(t, "map"), pose=b.pose((goal[0], goal[1], heading))), t_ns
        )
        if v.has_subscriber("/explore/candidates", MARKER_ARRAY):
            v.publish("/explore/candidates", MARKER_ARRAY, self._markers(t, candidates, scores, best), t_ns)

    def _markers(self, t: float, candidates: NDArray[np.float64], scores: NDArray[np.float64], best: int) -> Any:
        """``crlam ros explore``'s markers: DELETEALL, then a sphere per candidate coloured by score."""
        T, b = self.view.types, self.msgs
        s = np.asarray(scores, dtype=np.float64)
        finite = s[np.isfinite(s)]
        lo, hi = (float(finite.min()), float(finite.max())) if finite.size else (0.0, 1.0)
        span = hi - lo if hi > lo else 1.0

        def marker(
            mid: int, action: int, kind: int = 2, pose: Any = None, size: float = 0.0, a: float = 0.0, text: str = ""
        ) -> Any:
            vec, col = T["geometry_msgs/msg/Vector3"], T["std_msgs/msg/ColorRGBA"]
            return T["visualization_msgs/msg/Marker"](
                header=b.header(t, "map"),
                ns="candidates",
                id=mid,
                type=kind,
                action=action,
                pose=pose if pose is not None else b.pose((0.0, 0.0, 0.0)),
                scale=vec(x=size, y=size, z=size),
                color=col(r=a, g=0.2, b=1.0 - a, a=1.0 if action == 0 else 0.0),
                lifetime=T["builtin_interfaces/msg/Duration"](sec=0, nanosec=0),
                frame_locked=False,
                points=[],
                colors=[],
                texture_resource="",
                texture=T["sensor_msgs/msg/CompressedImage"](
                    header=b.header(t, "map"), format="", data=np.zeros(0, dtype=np.uint8)
                ),
                uv_coordinates=[],
                text=text,
                mesh_resource="",
                mesh_file=T["visualization_msgs/msg/MeshFile"](filename="", data=np.zeros(0, dtype=np.uint8)),
                mesh_use_embedded_materials=False,
            )

        markers = [marker(0, 3)]  # DELETEALL first
        for i, (c, v) in enumerate(zip(candidates, s)):
            a = (float(v) - lo) / span if math.isfinite(float(v)) else 0.0
            size = 0.3 if i == best else 0.12
            markers.append(marker(i + 1, 0, pose=b.pose((c[0], c[1], 0.0)), size=size, a=a, text=f"{float(v):.4g}"))
        return T[MARKER_ARRAY](markers=markers)
