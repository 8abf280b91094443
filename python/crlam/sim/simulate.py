"""End-to-end simulation: world + trajectory + odometry + laser scans, and writing them out.

Randomness: one ``np.random.SeedSequence(seed)`` is split with ``spawn(3)`` into independent
streams for the trajectory (goal choices, start pose), the odometry noise and the sensor noise,
each driving a ``np.random.Generator(np.random.PCG64(...))``. Every stream is consumed scan by
scan, so the first ``k`` scans of a run do not depend on ``n_scans``. The same configuration
always produces the same bytes in every file :func:`write_simulation` writes.

Written files (:func:`write_simulation`):

- ``log.clf``: CARMEN log; per scan an ``ODOM`` line (the noisy odometry pose) then the scan,
  whose pose fields also hold the odometry pose, as in a raw log. 180-beam SICK-layout scans with
  the FLASER maximum range (81 m) are ``FLASER``; any other sensor is ``ROBOTLASER1``.
- ``groundtruth.tum`` and ``odometry.tum``: ground-truth and odometry poses at the scan times.
- ``world.pgm`` + ``world.yaml``: the ground-truth world as a Nav2 map.
- ``simulation.json``: the configuration and a summary.
"""

from __future__ import annotations

import json
import math
import os
from collections.abc import Callable
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from crlam.errors import ConfigError
from crlam.limits import check_limit
from crlam.sim.odometry import (
    GaussianIncrementNoise,
    OdometryNoise,
    increments_from_poses,
    integrate_odometry,
)
from crlam.sim.robot import RobotParams, Trajectory, plan_trajectory
from crlam.sim.sensor import RangeSensor, noiseless, paper_lidar, sick_lms200
from crlam.sim.world import World
from crlam.sim.worlds import get_world

__all__ = ["SENSOR_PRESETS", "SimulatedLog", "SimulationConfig", "make_sensor", "simulate", "write_simulation"]

Array = NDArray[np.float64]

SENSOR_PRESETS: dict[str, Callable[[], RangeSensor]] = {
    "paper_lidar": paper_lidar,
    "sick_lms200": sick_lms200,
    "noiseless": noiseless,
}
_ALIASES = {"paper": "paper_lidar", "sick": "sick_lms200"}
FORMAT = "crlam-sim/1"


def make_sensor(sensor: str | RangeSensor) -> RangeSensor:
    """A :class:`RangeSensor` from a preset name (``paper_lidar``, ``sick_lms200``, ``noiseless``)."""
    if isinstance(sensor, RangeSensor):
        return sensor
    name = _ALIASES.get(sensor, sensor)
    if name not in SENSOR_PRESETS:
        raise ConfigError(f"unknown sensor preset {sensor!r}; choose one of {sorted(SENSOR_PRESETS)}")
    return SENSOR_PRESETS[name]()


@dataclass(frozen=True)
class SimulationConfig:
    """What to simulate.

    Attributes
    ----------
    world:
        ``"museum"``, ``"office"`` or a path to a Nav2 YAML / PGM / PNG map.
    n_scans:
        Number of scans (= ground-truth poses).
    seed:
        Seed of the trajectory, odometry noise and sensor noise streams.
    world_seed:
        Seed of a procedural world (independent of ``seed``, so the same building is reused).
    world_resolution:
        Cell size (m) of a procedural world (default 0.05), or of a bare image (required then).
    sensor:
        A preset name (see :data:`SENSOR_PRESETS`) or a :class:`RangeSensor`.
    odometry:
        Odometry noise model (per scan step).
    scan_rate:
        Scans per second (Hz).
    speed:
        Maximum forward speed (m/s); overrides ``robot.max_speed`` when given.
    robot:
        Robot geometry and controller settings.
    start_time:
        Timestamp (s) of the first scan.
    odometry_at_origin:
        Start the odometry frame at ``(0, 0, 0)`` instead of the true start pose.
    host:
        Host name written in the CARMEN log.
    """

    world: str = "museum"
    n_scans: int = 5500
    seed: int = 0
    world_seed: int = 0
    world_resolution: float | None = None
    sensor: str | RangeSensor = "paper_lidar"
    odometry: OdometryNoise = field(default_factory=GaussianIncrementNoise)
    scan_rate: float = 10.0
    speed: float | None = None
    robot: RobotParams = field(default_factory=RobotParams)
    start_time: float = 0.0
    odometry_at_origin: bool = False
    host: str = "crlam-sim"

    def __post_init__(self) -> None:
        if self.n_scans < 1:
            raise ConfigError(f"n_scans must be >= 1, got {self.n_scans}")
        if self.seed < 0 or self.world_seed < 0:
            raise ConfigError("seeds must be >= 0")
        if not (self.scan_rate > 0.0 and math.isfinite(self.scan_rate)):
            raise ConfigError(f"scan_rate must be positive, got {self.scan_rate}")
        if not self.host or any(c.isspace() for c in self.host):
            raise ConfigError(f"host must be one word, got {self.host!r}")
        make_sensor(self.sensor)  # validates the preset name

    @property
    def robot_params(self) -> RobotParams:
        """``robot`` with ``speed`` applied."""
        return self.robot if self.speed is None else replace(self.robot, max_speed=float(self.speed))

    def to_dict(self) -> dict[str, Any]:
        """Plain-data description (JSON-serialisable, deterministic)."""
        return {
            "world": str(self.world),
            "world_seed": self.world_seed,
            "world_resolution": self.world_resolution,
            "n_scans": self.n_scans,
            "seed": self.seed,
            "sensor": make_sensor(self.sensor).to_dict(),
            "odometry": self.odometry.to_dict(),
            "scan_rate": self.scan_rate,
            "robot": self.robot_params.to_dict(),
            "start_time": self.start_time,
            "odometry_at_origin": self.odometry_at_origin,
            "host": self.host,
        }


@dataclass
class SimulatedLog:
    """The result of :func:`simulate`.

    Attributes
    ----------
    config:
        The configuration used.
    world:
        Ground-truth world.
    sensor:
        The sensor (geometry and noise).
    timestamps:
        ``(n,)`` scan times (s).
    poses:
        ``(n, 3)`` ground-truth robot (= sensor) poses (m, rad).
    odometry:
        ``(n, 3)`` reported odometry poses (m, rad), in the odometry frame.
    ranges:
        ``(n, n_beams)`` readings (m); ``== sensor.max_range`` means no return.
    trajectory:
        The planned trajectory (with its paths and goals).
    """

    config: SimulationConfig
    world: World
    sensor: RangeSensor
    timestamps: Array
    poses: Array
    odometry: Array
    ranges: Array
    trajectory: Trajectory

    @property
    def n_scans(self) -> int:
        return len(self.timestamps)

    @property
    def odometry_increments(self) -> Array:
        """``(n - 1, 3)`` reported increments between consecutive scans."""
        return increments_from_poses(self.odometry)


def simulate(config: SimulationConfig) -> SimulatedLog:
    """Run the simulation described by ``config`` (see the module docstring)."""
    sensor = make_sensor(config.sensor)
    # The whole log is held in memory (float64 ranges): bounded before anything is simulated.
    check_limit(
        "readings",
        float(config.n_scans) * sensor.n_beams,
        f"a simulated log of {config.n_scans} scans x {sensor.n_beams} beams",
    )
    world = get_world(config.world, config.world_seed, config.world_resolution)
    traj_seq, odom_seq, sensor_seq = np.random.SeedSequence(config.seed).spawn(3)
    traj = plan_trajectory(world, config.n_scans, traj_seq, config.robot_params, config.scan_rate, config.start_time)
    true_inc = increments_from_poses(traj.poses)
    noisy_inc = config.odometry.sample_increments(true_inc, np.random.Generator(np.random.PCG64(odom_seq)))
    start = np.zeros(3) if config.odometry_at_origin else traj.poses[0]
    odom = integrate_odometry(start, noisy_inc)
    ranges = sensor.simulate_ranges(world, traj.poses, np.random.Generator(np.random.PCG64(sensor_seq)))
    return SimulatedLog(config, world, sensor, traj.timestamps, traj.poses, odom, ranges, traj)


def _summary(log: SimulatedLog) -> dict[str, Any]:
    zmax = log.sensor.max_range
    return {
        "format": FORMAT,
        "config": log.config.to_dict(),
        "world": {
            "name": log.world.name,
            "shape": list(log.world.shape),
            "resolution": log.world.resolution,
            "origin": [float(v) for v in log.world.origin],
            "occupied_fraction": round(float(log.world.occupied.mean()), 6),
        },
        "n_scans": log.n_scans,
        "duration_s": round(float(log.timestamps[-1] - log.timestamps[0]), 6),
        "path_length_m": round(log.trajectory.length, 4),
        "no_return_fraction": round(float((log.ranges >= zmax).mean()), 6),
        "files": {
            "carmen": "log.clf",
            "groundtruth": "groundtruth.tum",
            "odometry": "odometry.tum",
            "world_yaml": "world.yaml",
            "world_image": "world.pgm",
        },
    }


def write_simulation(log: SimulatedLog, out_dir: str | os.PathLike[str]) -> dict[str, Path]:
    """Write the files listed in the module docstring into ``out_dir`` (created if needed).

    Hit readings are capped at ``max_range - 1e-4`` m so that, after the CARMEN writer rounds
    to 0.1 mm, they stay below ``max_range`` and read back as hits rather than no-returns.

    Returns
    -------
    dict
        File role -> path.
    """
    from crlam.io.carmen_types import LaserScan, OdometryReading
    from crlam.io.carmen_writer import CarmenWriter
    from crlam.io.tum import write_tum

    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    s = log.sensor
    zmax = s.max_range
    ranges = np.where(log.ranges < zmax, np.minimum(log.ranges, zmax - 1e-4), zmax)
    dt = 1.0 / log.config.scan_rate
    inc = log.odometry_increments
    # Reported velocities: the odometry increment over the scan period (0 for the first scan).
    tv = np.concatenate([[0.0], np.sign(inc[:, 0]) * np.hypot(inc[:, 0], inc[:, 1]) / dt])
    rv = np.concatenate([[0.0], inc[:, 2] / dt])
    header = (
        f"crlam simulated log ({FORMAT}): world {log.world.name}, {log.n_scans} scans, seed {log.config.seed}\n"
        f"sensor {s.name}: {s.n_beams} beams, fov {math.degrees(s.fov):.3f} deg, max range {zmax} m\n"
        "scan and ODOM poses are the noisy odometry; ground truth is in groundtruth.tum"
    )
    t0 = float(log.timestamps[0])
    paths = {"carmen": out / "log.clf"}
    with CarmenWriter(paths["carmen"], header=header) as writer:
        for k in range(log.n_scans):
            t = float(log.timestamps[k])
            pose = log.odometry[k]
            writer.write_odom(
                OdometryReading(
                    pose=pose, tv=float(tv[k]), rv=float(rv[k]), timestamp=t, host=log.config.host, logger_timestamp=t - t0
                )
            )
            writer.write_scan(
                LaserScan(
                    ranges=ranges[k],
                    angle_min=s.angle_min,
                    angle_increment=s.angle_increment,
                    max_range=zmax,
                    pose=pose,
                    odom=pose,
                    timestamp=t,
                    host=log.config.host,
                    logger_timestamp=t - t0,
                )
            )
    paths["groundtruth"] = out / "groundtruth.tum"
    write_tum(paths["groundtruth"], log.timestamps, log.poses, header="crlam simulation ground truth")
    paths["odometry"] = out / "odometry.tum"
    write_tum(paths["odometry"], log.timestamps, log.odometry, header="crlam simulation odometry")
    paths["world_yaml"] = log.world.to_nav2_yaml(out / "world.yaml")
    paths["world_image"] = out / "world.pgm"
    paths["json"] = out / "simulation.json"
    paths["json"].write_text(json.dumps(_summary(log), indent=2, sort_keys=True) + "\n", encoding="utf-8")
    return paths
