"""Trajectories: collision free, dynamically plausible, following the planned waypoints, fast."""

from __future__ import annotations

import math

import numpy as np
import pytest

from crlam.errors import ConfigError
from crlam.pose import wrap_angle
from crlam.sim import (
    PlanningGrid,
    RobotParams,
    World,
    museum_world,
    office_world,
    plan_trajectory,
)


def _distance_to_polyline(points: np.ndarray, path: np.ndarray) -> np.ndarray:
    """Distance (m) from each point ``(n, 2)`` to the polyline ``(m, 2)``."""
    a, b = path[:-1], path[1:]
    ab = b - a
    L2 = np.maximum((ab**2).sum(1), 1e-18)
    u = np.clip(((points[:, None, :] - a[None]) * ab[None]).sum(-1) / L2[None], 0.0, 1.0)
    proj = a[None] + u[..., None] * ab[None]
    return np.sqrt(((points[:, None, :] - proj) ** 2).sum(-1)).min(axis=1)


def _check_trajectory(world: World, traj, params: RobotParams, scan_rate: float) -> None:
    poses = traj.poses
    dt = 1.0 / scan_rate
    np.testing.assert_allclose(np.diff(traj.timestamps), dt, atol=1e-9)
    # Collision free against the real (non-inflated) world, exactly.
    assert np.all(world.clearance(poses[:, :2], params.radius + 0.1) >= params.radius)
    # Speed and turn-rate limits between consecutive poses.
    step = np.hypot(*np.diff(poses[:, :2], axis=0).T)
    assert step.max() <= params.max_speed * dt + 1e-9
    turn = np.abs(wrap_angle(np.diff(poses[:, 2])))
    assert turn.max() <= params.max_turn_rate * dt + 1e-9
    # Following the waypoints: every pose stays close to the planned polyline.
    assert _distance_to_polyline(poses[:, :2], traj.path).max() < 0.12
    # Every goal but the last one was reached.
    for g in traj.goals[:-1]:
        assert np.hypot(*(poses[:, :2] - g).T).min() < 0.05


def test_office_trajectory() -> None:
    world = office_world(0)
    params = RobotParams()
    traj = plan_trajectory(world, 300, seed=3, params=params, scan_rate=10.0)
    assert traj.poses.shape == (300, 3) and traj.timestamps[0] == 0.0
    _check_trajectory(world, traj, params, 10.0)
    assert traj.length > 5.0  # it actually moves


def test_museum_trajectory_covers_ground() -> None:
    world = museum_world(0)
    params = RobotParams()
    traj = plan_trajectory(world, 5500, seed=0, params=params, scan_rate=10.0)
    _check_trajectory(world, traj, params, 10.0)
    assert traj.length > 150.0
    assert len(traj.goals) >= 5
    # It visits several distinct parts of the museum.
    cells = {(int(x // 15), int(y // 15)) for x, y in traj.poses[:, :2]}
    assert len(cells) >= 6


def test_trajectory_determinism_and_prefix() -> None:
    world = office_world(1)
    a = plan_trajectory(world, 200, seed=5)
    b = plan_trajectory(world, 200, seed=5)
    np.testing.assert_array_equal(a.poses, b.poses)
    c = plan_trajectory(world, 120, seed=5)
    np.testing.assert_array_equal(c.poses, a.poses[:120])  # more poses do not change the first ones
    d = plan_trajectory(world, 200, seed=6)
    assert not np.array_equal(d.poses, a.poses)


def test_given_start_pose_rate_and_speed() -> None:
    world = office_world(0)
    params = RobotParams(max_speed=0.9, max_turn_rate=1.2)
    grid = PlanningGrid.build(
        world, params.radius, params.margin, params.preferred_clearance, params.clearance_weight, params.planning_cell
    )
    i, j = np.unravel_index(int(np.argmax(grid.clearance)), grid.clearance.shape)
    start = (*grid.node_xy(i, j), 0.5)
    traj = plan_trajectory(world, 150, seed=1, params=params, scan_rate=5.0, start_time=100.0, start_pose=start)
    np.testing.assert_allclose(traj.poses[0], start)
    assert traj.timestamps[0] == 100.0 and traj.timestamps[1] == pytest.approx(100.2)
    _check_trajectory(world, traj, params, 5.0)


def test_planner_keeps_away_from_walls_in_open_space() -> None:
    world = office_world(0)
    params = RobotParams()
    traj = plan_trajectory(world, 400, seed=2, params=params)
    clr = world.clearance(traj.poses[:, :2], 2.0)
    # Mostly well clear of obstacles (doors and furniture gaps force the rest closer).
    assert np.median(clr) > 0.6


def test_no_room_for_the_robot() -> None:
    occ = np.ones((20, 20), dtype=bool)
    occ[5:8, 5:8] = False  # a 0.3 m pocket: too small for a 0.3 m-radius robot
    with pytest.raises(ConfigError):
        plan_trajectory(World(occ, 0.1), 10)
    with pytest.raises(ConfigError):
        plan_trajectory(office_world(0), 0)
    with pytest.raises(ConfigError):
        RobotParams(max_speed=0.0)
    assert math.isfinite(RobotParams().sharp_turn)
