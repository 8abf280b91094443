"""2D laser SLAM simulator: worlds, trajectories, odometry noise, range sensor, log writing.

Typical use::

    from crlam.sim import SimulationConfig, simulate, write_simulation

    log = simulate(SimulationConfig(world="museum", n_scans=5500, seed=0))
    write_simulation(log, "out/museum")

Modules: :mod:`~crlam.sim.world` (occupancy-grid worlds, image/Nav2 loading),
:mod:`~crlam.sim.worlds` (procedural museum and office), :mod:`~crlam.sim.sensor` (ray casting
and beam-mixture noise), :mod:`~crlam.sim.robot` (A* + pure-pursuit trajectories),
:mod:`~crlam.sim.odometry` (odometry noise models and densities),
:mod:`~crlam.sim.simulate` (end-to-end runs and output files).
"""

from __future__ import annotations

from crlam.sim.odometry import (
    GaussianIncrementNoise,
    OdometryNoise,
    ThrunOdometryNoise,
    increments_from_poses,
    integrate_odometry,
    odometry_noise_from_dict,
)
from crlam.sim.planning import PlanningError, PlanningGrid
from crlam.sim.raycast import cast_ranges_numpy
from crlam.sim.robot import RobotParams, Trajectory, plan_trajectory
from crlam.sim.sensor import (
    RangeSensor,
    native_cast_available,
    noiseless,
    paper_lidar,
    sick_lms200,
    true_ranges,
)
from crlam.sim.simulate import (
    SENSOR_PRESETS,
    SimulatedLog,
    SimulationConfig,
    make_sensor,
    simulate,
    write_simulation,
)
from crlam.sim.world import World, read_pgm, write_pgm
from crlam.sim.worlds import (
    WORLD_NAMES,
    get_world,
    museum_layout,
    museum_world,
    office_layout,
    office_world,
)

__all__ = [
    "SENSOR_PRESETS",
    "WORLD_NAMES",
    "GaussianIncrementNoise",
    "OdometryNoise",
    "PlanningError",
    "PlanningGrid",
    "RangeSensor",
    "RobotParams",
    "SimulatedLog",
    "SimulationConfig",
    "ThrunOdometryNoise",
    "Trajectory",
    "World",
    "cast_ranges_numpy",
    "get_world",
    "increments_from_poses",
    "integrate_odometry",
    "make_sensor",
    "museum_layout",
    "museum_world",
    "native_cast_available",
    "noiseless",
    "odometry_noise_from_dict",
    "office_layout",
    "office_world",
    "paper_lidar",
    "plan_trajectory",
    "read_pgm",
    "sick_lms200",
    "simulate",
    "true_ranges",
    "write_pgm",
    "write_simulation",
]
