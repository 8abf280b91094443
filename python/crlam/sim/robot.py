"""Collision-free ground-truth trajectories for a simulated differential-drive robot.

:func:`plan_trajectory` repeats, until enough poses are emitted:

1. pick a goal: random reachable open places within ``max_goal_distance``, scored by how far
   they are from where the robot has already been (an exploration-like tour);
2. plan a path with A* on a coarse lattice with a clearance cost (:mod:`crlam.sim.planning`)
   and shorten it by string pulling;
3. follow it with a unicycle controller: pure pursuit along the polyline, stopping and turning
   on the spot at corners sharper than ``sharp_turn``, integrated exactly (constant ``v``,
   ``omega`` per control step) at ``control_rate``; a pose is emitted every scan period.

Every emitted pose is checked to keep at least ``radius`` from every occupied cell.
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass, field
from typing import Any

import numpy as np
from numpy.typing import NDArray

from crlam.errors import ConfigError
from crlam.sim.planning import PlanningError, PlanningGrid
from crlam.sim.world import World

__all__ = ["RobotParams", "Trajectory", "follow_path", "plan_trajectory"]

Array = NDArray[np.float64]


@dataclass(frozen=True)
class RobotParams:
    """Robot geometry, planner and controller settings (SI units: m, s, rad).

    Attributes
    ----------
    radius:
        Robot footprint radius (m); emitted poses keep at least this clearance.
    margin:
        Extra clearance (m) required of planning nodes.
    preferred_clearance:
        Clearance (m) the planner tries to keep (cost-free above it).
    clearance_weight:
        Weight of the clearance cost in A*.
    planning_cell:
        Spacing (m) of the planning lattice.
    heuristic_weight:
        Weighted-A* inflation of the heuristic (>= 1).
    max_speed:
        Maximum forward speed (m/s).
    max_accel:
        Maximum forward acceleration (m/s²).
    max_turn_rate:
        Maximum angular speed (rad/s).
    lookahead:
        Pure-pursuit lookahead distance (m).
    sharp_turn:
        Corners turning by more than this (rad) are taken by stopping and turning on the spot.
    control_rate:
        Minimum controller rate (Hz); rounded up to a multiple of the scan rate.
    min_goal_distance, max_goal_distance:
        Straight-line distance (m) from the robot to candidate goals.
    goal_clearance:
        Minimum clearance (m) of goal locations.
    """

    radius: float = 0.3
    margin: float = 0.1
    preferred_clearance: float = 1.0
    clearance_weight: float = 3.0
    planning_cell: float = 0.25
    heuristic_weight: float = 1.5
    max_speed: float = 0.6
    max_accel: float = 0.5
    max_turn_rate: float = 0.8
    lookahead: float = 0.6
    sharp_turn: float = math.radians(25.0)
    control_rate: float = 20.0
    min_goal_distance: float = 3.0
    max_goal_distance: float = 20.0
    goal_clearance: float = 0.8

    def __post_init__(self) -> None:
        positive = ("radius", "planning_cell", "max_speed", "max_accel", "max_turn_rate", "lookahead", "control_rate")
        for name in positive:
            if not getattr(self, name) > 0.0:
                raise ConfigError(f"RobotParams.{name} must be > 0")
        if self.heuristic_weight < 1.0 or self.margin < 0.0:
            raise ConfigError("RobotParams: heuristic_weight must be >= 1 and margin >= 0")
        if not 0.0 < self.min_goal_distance < self.max_goal_distance:
            raise ConfigError("RobotParams: need 0 < min_goal_distance < max_goal_distance")

    def to_dict(self) -> dict[str, Any]:
        return asdict(self)


@dataclass
class Trajectory:
    """Ground-truth poses at the scan times.

    Attributes
    ----------
    timestamps:
        ``(n,)`` seconds, uniformly spaced by the scan period.
    poses:
        ``(n, 3)`` robot poses ``(x, y, theta)`` (m, rad).
    path:
        ``(m, 2)`` waypoints of all planned (smoothed) paths, concatenated in order.
    goals:
        ``(k, 2)`` goals that were planned to, in order (the last one may not be reached).
    """

    timestamps: Array
    poses: Array
    path: Array = field(default_factory=lambda: np.zeros((0, 2)))
    goals: Array = field(default_factory=lambda: np.zeros((0, 2)))

    def __len__(self) -> int:
        return len(self.poses)

    @property
    def length(self) -> float:
        """Travelled distance (m) along the emitted poses."""
        return float(np.hypot(*np.diff(self.poses[:, :2], axis=0).T).sum()) if len(self.poses) > 1 else 0.0


def _wrap(a: float) -> float:
    a = math.remainder(a, 2.0 * math.pi)
    return math.pi if a == -math.pi else a


class _Unicycle:
    """Exact constant-twist integration of a unicycle, emitting a pose every ``substeps`` steps."""

    def __init__(self, pose: tuple[float, float, float], dt: float, substeps: int, out: list[tuple[float, ...]], limit: int):
        self.x, self.y, self.th = pose
        self.v = 0.0
        self.dt = dt
        self.substeps = substeps
        self.count = 0
        self.out = out
        self.limit = limit

    @property
    def done(self) -> bool:
        return len(self.out) >= self.limit

    def step(self, v: float, w: float) -> None:
        dt = self.dt
        # Exact arc: the chord has length v*dt*sinc(w*dt/2) along the mean heading. This form has
        # no cancellation for small w (unlike (v/w)*(sin(th1) - sin(th))).
        half = 0.5 * w * dt
        sinc = math.sin(half) / half if abs(half) > 1e-6 else 1.0 - half * half / 6.0
        mid = self.th + half
        self.x += v * dt * sinc * math.cos(mid)
        self.y += v * dt * sinc * math.sin(mid)
        self.th = _wrap(self.th + w * dt)
        self.v = v
        self.count += 1
        if self.count % self.substeps == 0:
            self.out.append((self.x, self.y, self.th))


def _turn_to(robot: _Unicycle, heading: float, p: RobotParams) -> None:
    """Turn on the spot until the heading is within 0.5 deg of ``heading``."""
    while not robot.done:
        err = _wrap(heading - robot.th)
        if abs(err) < math.radians(0.5):
            return
        w = math.copysign(min(p.max_turn_rate, max(2.0 * abs(err), 0.15)), err)
        # Do not overshoot within one step.
        if abs(w) * robot.dt > abs(err):
            w = err / robot.dt
        robot.step(0.0, w)


def follow_path(robot: _Unicycle, path: Array, p: RobotParams) -> None:
    """Drive along ``path`` ``(k, 2)`` (pure pursuit, on-the-spot turns at sharp corners)."""
    pts = [(float(a), float(b)) for a, b in path]
    n = len(pts)
    if n < 2:
        return
    # Corner i (0 < i < n-1) is sharp if the direction changes by more than sharp_turn there.
    sharp = [True] * n
    for i in range(1, n - 1):
        h0 = math.atan2(pts[i][1] - pts[i - 1][1], pts[i][0] - pts[i - 1][0])
        h1 = math.atan2(pts[i + 1][1] - pts[i][1], pts[i + 1][0] - pts[i][0])
        sharp[i] = abs(_wrap(h1 - h0)) > p.sharp_turn
    seg = 0
    while seg < n - 1 and not robot.done:
        stop = next(k for k in range(seg + 1, n) if sharp[k])
        ax, ay = pts[seg]
        bx, by = pts[seg + 1]
        if math.hypot(bx - ax, by - ay) < 1e-9:
            seg += 1
            continue
        _turn_to(robot, math.atan2(by - ay, bx - ax), p)
        # Drive through the (gentle) corners up to the next stop vertex.
        while not robot.done:
            # Project onto the current segment; advance while past its end.
            while True:
                ax, ay = pts[seg]
                bx, by = pts[seg + 1]
                sx, sy = bx - ax, by - ay
                L2 = sx * sx + sy * sy
                u = ((robot.x - ax) * sx + (robot.y - ay) * sy) / L2 if L2 > 0 else 1.0
                if u >= 1.0 and seg + 1 < stop:
                    seg += 1
                    continue
                break
            u = min(max(u, 0.0), 1.0)
            px, py = ax + u * sx, ay + u * sy
            # Remaining path length to the stop vertex, and the lookahead point before it.
            remaining = math.hypot(bx - px, by - py)
            # Walk ``lookahead`` metres along the path from the projection, never past the stop.
            ahead = p.lookahead
            cx, cy = px, py
            k = seg + 1
            while True:
                qx, qy = pts[k]
                d = math.hypot(qx - cx, qy - cy)
                if d >= ahead or k == stop:
                    f = min(1.0, ahead / d) if d > 0 else 1.0
                    tx, ty = cx + f * (qx - cx), cy + f * (qy - cy)
                    break
                ahead -= d
                cx, cy = qx, qy
                k += 1
            for q in range(seg + 1, stop):
                remaining += math.hypot(pts[q + 1][0] - pts[q][0], pts[q + 1][1] - pts[q][1])
            gx, gy = pts[stop]
            dist_stop = math.hypot(gx - robot.x, gy - robot.y)
            if dist_stop < 0.03 or (remaining < 0.03 and seg + 1 == stop):
                break
            dx, dy = tx - robot.x, ty - robot.y
            ld = math.hypot(dx, dy)
            alpha = _wrap(math.atan2(dy, dx) - robot.th)
            if abs(alpha) > math.radians(60.0):
                _turn_to(robot, math.atan2(dy, dx), p)
                continue
            kappa = 2.0 * math.sin(alpha) / max(ld, 1e-6)
            v = min(p.max_speed, 0.05 + 0.8 * min(remaining, dist_stop), robot.v + p.max_accel * robot.dt)
            w = v * kappa
            if abs(w) > p.max_turn_rate:
                w = math.copysign(p.max_turn_rate, w)
                v = p.max_turn_rate / abs(kappa)
            robot.step(v, w)
        seg = stop


def _choose_goal(rng: np.random.Generator, grid: PlanningGrid, cand: Array, here: Array, visited: Array, p: RobotParams) -> Array:
    """A goal among ``cand`` ``(c, 2)``: far from ``visited`` ``(v, 2)``, within reach of ``here``."""
    d = np.hypot(*(cand - here).T)
    ok = np.nonzero((d >= p.min_goal_distance) & (d <= p.max_goal_distance))[0]
    if len(ok) == 0:
        ok = np.arange(len(cand))
    pick = ok[rng.choice(len(ok), size=min(64, len(ok)), replace=False)]
    pts = cand[pick]
    novelty = np.sqrt(((pts[:, None, :] - visited[None, :, :]) ** 2).sum(-1)).min(axis=1)
    score = novelty + rng.uniform(0.0, 1.0, len(pts))
    return pts[int(np.argmax(score))]


def plan_trajectory(
    world: World,
    n_poses: int,
    seed: int | np.random.SeedSequence = 0,
    params: RobotParams | None = None,
    scan_rate: float = 10.0,
    start_time: float = 0.0,
    start_pose: tuple[float, float, float] | None = None,
) -> Trajectory:
    """A collision-free trajectory of ``n_poses`` ground-truth poses sampled at ``scan_rate`` (Hz).

    Parameters
    ----------
    world:
        The world to drive in.
    n_poses:
        Number of poses to emit (the first is the start pose).
    seed:
        Seed of the goal choices and start pose (``PCG64``). The first ``k`` poses do not depend
        on ``n_poses``.
    params:
        Robot and controller settings (:class:`RobotParams` defaults if ``None``).
    scan_rate:
        Pose emission rate (Hz).
    start_time:
        Timestamp (s) of the first pose.
    start_pose:
        Start ``(x, y, theta)``; default: a random open place in the largest free region.

    Raises
    ------
    ConfigError
        If the world has no room for the robot.
    RuntimeError
        If an emitted pose violates the clearance (a bug, never expected).
    """
    p = params or RobotParams()
    if n_poses < 1:
        raise ConfigError(f"n_poses must be >= 1, got {n_poses}")
    if not scan_rate > 0.0:
        raise ConfigError(f"scan_rate must be > 0, got {scan_rate}")
    rng = np.random.Generator(np.random.PCG64(seed))
    grid = PlanningGrid.build(world, p.radius, p.margin, p.preferred_clearance, p.clearance_weight, p.planning_cell)
    sizes = np.bincount(grid.component.ravel())
    if len(sizes) < 2:
        raise ConfigError(f"world {world.name!r} has no room for a robot of radius {p.radius} m")
    if start_pose is None:
        main = int(np.argmax(sizes[1:])) + 1
        rows, cols = np.nonzero(
            (grid.component == main) & (grid.clearance >= min(p.goal_clearance, grid.clearance[grid.component == main].max()))
        )
        k = int(rng.integers(len(rows)))
        x0, y0 = grid.node_xy(rows[k], cols[k])
        start = (float(x0), float(y0), float(rng.uniform(-math.pi, math.pi)))
    else:
        start = tuple(float(v) for v in start_pose)  # type: ignore[assignment]
    label = grid.component[grid.nearest_node(np.array(start[:2]))]
    comp = grid.component == label
    open_ = comp & (grid.clearance >= p.goal_clearance)
    if open_.sum() < 2:
        open_ = comp
    rows, cols = np.nonzero(open_)
    cand = grid.node_xy(rows, cols)

    substeps = max(1, math.ceil(p.control_rate / scan_rate))
    out: list[tuple[float, ...]] = [start]
    robot = _Unicycle(start, 1.0 / (scan_rate * substeps), substeps, out, n_poses)
    paths: list[Array] = []
    goals: list[Array] = []
    visited = [np.array(start[:2])]
    failures = 0
    while not robot.done:
        here = np.array([robot.x, robot.y])
        goal = _choose_goal(rng, grid, cand, here, np.array(visited), p)
        try:
            path = grid.plan(here, goal, p.radius + 0.05, p.heuristic_weight)
        except PlanningError:
            failures += 1
            if failures > 50:
                raise
            continue
        goals.append(goal)
        paths.append(path)
        before = len(out)
        follow_path(robot, path, p)
        visited.extend(np.asarray(out[before::10])[:, :2])
        visited.append(goal)
    poses = np.asarray(out[:n_poses], dtype=np.float64)
    clr = world.clearance(poses[:, :2], p.radius + world.resolution)
    if (clr < p.radius).any():
        k = int(np.argmin(clr))
        raise RuntimeError(f"pose {k} {poses[k]} is {clr[k]:.3f} m from an obstacle (radius {p.radius} m)")
    stamps = start_time + np.arange(n_poses, dtype=np.float64) / scan_rate
    return Trajectory(stamps, poses, np.vstack(paths) if paths else np.zeros((0, 2)), np.asarray(goals).reshape(-1, 2))
