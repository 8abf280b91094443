"""``crlam ros localize --map MAP``: Monte Carlo localization on a known map as a live ROS 2 node.

The map is a Nav2 ``.yaml``, a crlam run folder or a ``belief.npz``
(:func:`crlam.localize.map.load_localization_map`); it is published once on ``/map``
(transient local, so RViz and Nav2 get it whenever they start). Without an initial pose the
localization is global; ``/initialpose`` (geometry_msgs/PoseWithCovarianceStamped, what RViz's
"2D Pose Estimate" sends) starts it again around the pose given, with its covariance, at the
next scan. Otherwise it behaves as ``crlam ros slam`` (:class:`crlam.ros.slam_node.SlamNode`):
the same inputs, ``/tf`` map -> odom, ``/pose``, ``/particles``, ``/path``, ``/diagnostics``
(with ``converged``), and a save writes ``trajectory.tum`` and ``metrics.json`` whole or not at all.
Parameters: the node's (:class:`crlam.ros.params.NodeParameters`), AMCL's names
(:data:`AMCL_NAMES`) and every :class:`crlam.localize.LocalizeConfig` field.
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from crlam.ros.odometry_buffer import PendingScan
from crlam.ros.params import NodeParameters
from crlam.ros.slam_node import SlamNode, ros_messages

__all__ = ["AMCL_NAMES", "LOCALIZE_TOPICS", "LocalizeNode", "split_localize_parameters"]

#: ``crlam ros localize``'s topics beyond those of ``crlam ros slam`` (less /map_confidence).
LOCALIZE_TOPICS = (
    ("/initialpose", "geometry_msgs/msg/PoseWithCovarianceStamped", "in", "reliable", "restart around this pose (RViz)"),
    ("/map", "nav_msgs/msg/OccupancyGrid", "out", "transient local", "the known map, once"),
)

#: AMCL's names of LocalizeConfig fields.
AMCL_NAMES = {
    "min_particles": "min_particles",
    "max_particles": "max_particles",
    "update_min_d": "linear_update",
    "update_min_a": "angular_update",
    "pf_err": "kld_err",
    "pf_z": "kld_z",
    "recovery_alpha_slow": "alpha_slow",
    "recovery_alpha_fast": "alpha_fast",
}


def split_localize_parameters(params: dict[str, Any], source: str) -> tuple[NodeParameters, dict[str, Any], dict[str, Any]]:
    """(node settings, LocalizeConfig fields, map options) of a parameter mapping; unknown names are errors."""
    import dataclasses

    from crlam.errors import ConfigError
    from crlam.localize import LocalizeConfig
    from crlam.ros.params import NODE_PARAMETERS

    fields = {f.name for f in dataclasses.fields(LocalizeConfig)}
    node: dict[str, Any] = {}
    loc: dict[str, Any] = {}
    map_options: dict[str, Any] = {}
    for name, value in params.items():
        if name in NODE_PARAMETERS and name != "preset":
            node[name] = value
        elif name in AMCL_NAMES:
            loc[AMCL_NAMES[name]] = value
        elif name in fields:
            loc[name] = tuple(value) if isinstance(value, list) else value
        elif name in ("nav2_free_thresh", "nav2_occupied", "nav2_free", "initial_pose", "initial_cov"):
            map_options[name] = value
        else:
            raise ConfigError(
                f"{source}: unknown parameter {name!r} (node parameters: {', '.join(NODE_PARAMETERS)}; AMCL names: "
                f"{', '.join(AMCL_NAMES)}; nav2_free_thresh, nav2_occupied, nav2_free, initial_pose, initial_cov; or any "
                "crlam localization setting)"
            )
    return NodeParameters(**node), loc, map_options


class LocalizeNode(SlamNode):
    """The localization node (see the module docstring)."""

    NODE_NAME = "crlam_localize"

    def __init__(
        self,
        node: NodeParameters,
        localize_overrides: dict[str, Any],
        map_path: str,
        *,
        map_options: dict[str, Any] | None = None,
        domain: int | None = None,
        dds_config: str = "loopback",
    ) -> None:
        from crlam.localize.map import Nav2Prior, load_localization_map

        opts = dict(map_options or {})
        prior_args: dict[str, Any] = {
            k: float(opts[f"nav2_{k2}"])
            for k, k2 in (("free_thresh", "free_thresh"), ("occupied_mean", "occupied"), ("free_mean", "free"))
            if f"nav2_{k2}" in opts
        }
        super().__init__(node, localize_overrides, domain=domain, dds_config=dds_config)
        self.map = load_localization_map(map_path, nav2_prior=Nav2Prior(**prior_args))
        self.map_path = map_path
        self.initial_pose = None if opts.get("initial_pose") is None else np.array(opts["initial_pose"], dtype=np.float64)
        self.initial_cov = None if opts.get("initial_cov") is None else np.array(opts["initial_cov"], dtype=np.float64)
        self.localizer: Any = None
        self.pending_initial: tuple[NDArray[np.float64], NDArray[np.float64]] | None = None

    def _make_config(self, overrides: dict[str, Any]) -> Any:
        from crlam.errors import ConfigError
        from crlam.localize import LocalizeConfig

        try:
            return LocalizeConfig(**overrides)
        except TypeError as exc:
            raise ConfigError(f"localization parameters: {exc}") from exc

    def start(self) -> None:
        m = ros_messages()
        from crlam.ros import qos

        super().start()
        self.dds.reader("/initialpose", m.PoseWithCovarianceStamped, qos.reliable(), self._on_initial_pose)
        self._publish_known_map()

    def _on_initial_pose(self, msg: Any) -> None:
        from crlam.io.rosbag_tf import yaw_of

        p = msg.pose.pose
        pose = np.array([float(p.position.x), float(p.position.y), yaw_of(p.orientation)])
        c = np.asarray(msg.pose.covariance, dtype=np.float64).reshape(6, 6)
        cov = c[np.ix_([0, 1, 5], [0, 1, 5])]
        if not np.any(cov):
            cov = np.diag([0.25, 0.25, 0.0685])  # AMCL's initial spread
        with self.lock:
            self.pending_initial = (pose, cov)
            self.counters["initial_poses"] = self.counters.get("initial_poses", 0) + 1
            self.wake.notify_all()

    def _filter_step(
        self, scan: PendingScan, angles: NDArray[np.float64], ranges: NDArray[np.float64], rmax: float
    ) -> tuple[bool, NDArray[np.float64], NDArray[np.float64] | None, tuple[float, float]]:
        from crlam.localize import Localizer

        assert scan.odom is not None and self.mount is not None
        with self.lock:
            initial, self.pending_initial = self.pending_initial, None
        if initial is not None:
            # RViz's pose is of the robot in the map: the filter starts again around it.
            self.localizer = Localizer(
                self.map, self.config, initial_pose=initial[0], initial_cov=initial[1], laser_max_range=rmax
            )
        elif self.localizer is None:
            self.localizer = Localizer(
                self.map, self.config, initial_pose=self.initial_pose, initial_cov=self.initial_cov, laser_max_range=rmax
            )
        step = self.localizer.step(scan.odom, angles, ranges, self.mount, scan.stamp)
        particles = None
        if step.processed:
            particles = np.asarray(self.localizer.particles()[0], dtype=np.float64)
        return step.processed, np.asarray(step.estimate, dtype=np.float64), particles, (step.spread_xy, step.spread_theta)

    def _publish_map(self, t: float) -> None:
        return  # the known map is published once, at the start

    def _publish_known_map(self) -> None:
        from crlam.experiments.slam_mcap import occupancy_grid_values

        layer = self.map.expected_occupancy()
        unknown = ~np.isfinite(layer.values)
        grid = self._grid(0.0, layer, occupancy_grid_values(layer.values, unknown))
        self._write(self.w_map, grid)
        self._write(self.w_meta, grid.info)

    def _extra_diagnostics(self) -> dict[str, object]:
        loc = self.localizer
        conv = None if loc is None else loc.convergence
        return {"converged": int(conv is not None), "converged_at_scan": -1 if conv is None else conv.scan_index}

    def _save(self, request: str) -> bool | None:
        from crlam.io.run_folder import staged_folder
        from crlam.io.tum import write_tum

        target = request or self.params.output_folder
        if not target or self.localizer is None or not self.localizer.steps:
            print(f"crlam ros localize: nothing to save to {target or '(no folder)'}", flush=True)
            return None if not target else False
        with self.lock:
            self._resolve(final=True)
            scans, self.ready = list(self.ready), type(self.ready)()
        for scan in scans:
            self._step(scan)
        stamps, poses = self.localizer.trajectory()
        order = np.argsort(stamps, kind="stable")
        conv = self.localizer.convergence
        metrics = {
            "map": str(self.map_path),
            "n_scans": self.localizer.n_scans,
            "converged_at_scan": None if conv is None else conv.scan_index,
            "distance_m": self.localizer.distance_travelled,
            "config": self.config.to_dict(),
            "counters": dict(self.counters),
        } | self.latency_summary()
        with staged_folder(target, replace=True, command="crlam ros localize") as stage:
            write_tum(stage / "trajectory.tum", np.asarray(stamps)[order], np.asarray(poses)[order], header="crlam ros localize")
            (stage / "metrics.json").write_text(json.dumps(metrics, indent=2, default=str) + "\n")
        self.saved.append(Path(target))
        print(f"crlam ros localize: saved {self.localizer.n_scans} scans to {target}", flush=True)
        return True
