"""Greedy information-driven exploration with known poses (the paper's Fig. 1).

A simulated robot in a world it does not know scans with a 360 deg range sensor, builds a CRM
(and a log-odds map beside it for OGMI), and repeats: generate candidates (reachable known-free
cells within a radius, plus every reachable frontier cell), evaluate them with the information
function in one batch, pick the best by gain (optionally per cost), plan the shortest path on the
known-free cells, and drive it while scanning. It stops when the best gain is below the threshold,
the travel budget is spent, no reachable candidate is left, or after ``max_decisions``; the reason
is recorded. The nearest-frontier baseline drives to the closest reachable frontier.

Paths only cross cells observed free (mean occupancy below ``free_threshold``) with at least
``robot_radius`` of clearance from cells believed occupied, so the robot never enters unknown
space.
"""

from __future__ import annotations

import csv
import json
import math
import os
import sys
import time
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray
from tqdm import tqdm

from crlam import _native
from crlam.errors import ConfigError
from crlam.experiments.explore_candidates import pick_candidates
from crlam.experiments.explore_window import decision_maps
from crlam.experiments.pool import write_atomic
from crlam.info import make_function
from crlam.mapping import ConfidenceRichMap, LogOddsConfig, LogOddsOccupancyMap, MappingConfig
from crlam.pose import between, compose
from crlam.sim.grid_ops import distance_map
from crlam.sim.sensor import RangeSensor
from crlam.sim.world import World

__all__ = ["ExploreConfig", "ExploreRun", "FUNCTIONS", "explore", "write_explore_folder"]

FUNCTIONS = ("crmi", "ucrmi", "fsmi", "frontier")


@dataclass(frozen=True)
class ExploreConfig:
    """Settings of an exploration run (units: m, rad; gains in the function's units)."""

    function: str = "crmi"
    alpha: float = 0.5
    budget_m: float = 150.0
    threshold: float = 0.1
    n_candidates: int = 200
    radius_m: float = 5.0
    cost_weight: float = 0.0
    resolution: float = 0.2
    sensor_range: float = 5.0
    n_beams: int = 360
    sigma_range: float = 0.01
    step_m: float = 0.25
    robot_radius: float = 0.3
    free_threshold: float = 0.35
    max_decisions: int = 400
    particles: int = 30
    seed: int = 0
    slam: bool = False
    slam_particles: int = 30
    odometry_sigma: tuple[float, float, float] = (0.02, 0.02, 0.01)

    def __post_init__(self) -> None:
        if self.function not in FUNCTIONS:
            raise ConfigError(f"function must be one of {', '.join(FUNCTIONS)}, got {self.function!r}")
        for name in ("budget_m", "radius_m", "resolution", "sensor_range", "step_m"):
            v = getattr(self, name)
            if not (math.isfinite(v) and v > 0):
                raise ConfigError(f"{name} must be finite and > 0, got {v}")
        if not (0.0 <= self.alpha <= 1.0):
            raise ConfigError(f"alpha must be in [0, 1], got {self.alpha}")
        if self.n_candidates < 1 or self.n_beams < 1 or self.max_decisions < 1:
            raise ConfigError("n_candidates, n_beams and max_decisions must be >= 1")
        if self.slam_particles < 1 or any(not (math.isfinite(v) and v >= 0) for v in self.odometry_sigma):
            raise ConfigError("slam_particles must be >= 1 and odometry_sigma finite and >= 0")
        if not (0.0 < self.free_threshold < 0.5) or self.robot_radius < 0 or self.cost_weight < 0:
            raise ConfigError("need 0 < free_threshold < 0.5, robot_radius >= 0, cost_weight >= 0")

    def to_dict(self) -> dict[str, Any]:
        return asdict(self)


@dataclass
class ExploreRun:
    """What an exploration produced.

    Attributes
    ----------
    poses : ndarray, shape (n, 3)
        True robot pose at every scan.
    estimates : ndarray, shape (n, 3)
        The robot's estimate at every scan (equal to ``poses`` with known poses; the RBPF-CLAM
        weighted mean with ``slam``).
    decisions : list of dict
        One row per decision (``progress.csv``).
    stop : str
        ``threshold`` | ``budget`` | ``no_candidates`` | ``max_decisions`` | ``blocked`` (with
        ``slam``: the path planned on the estimate kept bumping into obstacles).
    crm : ConfidenceRichMap
        The final map.
    """

    config: ExploreConfig
    world_name: str
    poses: NDArray[np.float64]
    decisions: list[dict[str, Any]]
    stop: str
    crm: ConfidenceRichMap
    truth: NDArray[np.bool_]
    estimates: NDArray[np.float64] = field(default_factory=lambda: np.zeros((0, 3)))
    bumps: int = 0
    goals: list[tuple[float, float]] = field(default_factory=list)
    frames: list[dict[str, Any]] = field(default_factory=list)
    """One snapshot per decision for the animation: ``decision``, ``poses`` (estimates so far),
    ``mean`` (expected occupancy as uint8, 0-255)."""

    @property
    def distance(self) -> float:
        return float(np.hypot(*np.diff(self.poses[:, :2], axis=0).T).sum()) if len(self.poses) > 1 else 0.0


def _filter_belief(slam_filter: Any) -> Any:
    """The filter's particle set as a UCRMI belief, with the Gaussian entropy of the weighted
    particle covariance as a first entropy (the filter carries no entropy estimate)."""
    parts = np.asarray(slam_filter.particle_poses())
    lw = np.asarray(slam_filter.log_weights())
    w = np.exp(lw - lw.max())
    w /= w.sum()
    mu = w @ parts
    d = parts - mu
    d[:, 2] = (d[:, 2] + math.pi) % (2 * math.pi) - math.pi
    cov = (d * w[:, None]).T @ d + np.diag([1e-6, 1e-6, 1e-8])
    h = 0.5 * math.log((2 * math.pi * math.e) ** 3 * max(float(np.linalg.det(cov)), 1e-300))
    return _native.ParticleBelief.from_particles(np.ascontiguousarray(parts), np.ascontiguousarray(lw), h)


def truth_grid(world: World, resolution: float) -> NDArray[np.bool_]:
    """The world's occupancy on the map grid: a map cell is occupied if any world cell in it is."""
    k = resolution / world.resolution
    if abs(k - round(k)) > 1e-6 or round(k) < 1:
        raise ConfigError(f"the map resolution {resolution} must be a multiple of the world's {world.resolution}")
    k = int(round(k))
    occ = world.occupied
    ny, nx = occ.shape[0] // k, occ.shape[1] // k
    return np.asarray(occ[: ny * k, : nx * k].reshape(ny, k, nx, k).any(axis=(1, 3)), dtype=bool)


def geodesic(traversable: NDArray[np.bool_], start: tuple[int, int], res: float) -> tuple[NDArray[np.float64], NDArray[np.int64]]:
    """8-connected shortest-path distances (m) over traversable cells from ``start`` (iy, ix) and
    the predecessor of every reached cell (flat index, -1 for none). Diagonal moves need both
    side cells traversable (no corner cutting)."""
    # The Dijkstra of crlam-core: same operations and pop order as a heapq of (d, u) tuples.
    mask = np.ascontiguousarray(traversable, dtype=bool)
    return _native.geodesic(mask, (int(start[0]), int(start[1])), float(res))


def _path(pred: NDArray[np.int64], goal: int, nx: int) -> list[tuple[int, int]]:
    cells = []
    u = goal
    while u >= 0:
        cells.append(divmod(int(u), nx))
        u = int(pred[u])
    return cells[::-1]


def _resample(points: NDArray[np.float64], step: float) -> NDArray[np.float64]:
    """Points every ``step`` metres along a polyline (the last point included)."""
    if len(points) < 2:
        return points
    seg = np.hypot(*np.diff(points, axis=0).T)
    s = np.concatenate([[0.0], np.cumsum(seg)])
    n = max(1, int(math.ceil(s[-1] / step)))
    t = np.linspace(0.0, s[-1], n + 1)[1:]
    return np.column_stack([np.interp(t, s, points[:, 0]), np.interp(t, s, points[:, 1])])


def explore(
    world: World,
    start: tuple[float, float, float],
    cfg: ExploreConfig,
    *,
    progress: bool = False,
    verbose: bool = False,
    on_event: Any = None,
) -> ExploreRun:
    """Runs an exploration of ``world`` from ``start`` (x, y, theta) with known poses. ``progress``
    shows a bar of the distance travelled against the budget (tqdm, on stderr); ``verbose`` prints
    a line per decision. Raises
    ``RuntimeError`` if the robot ever stands in an occupied cell of the world (a bug guard), and
    ``ConfigError`` if ``start`` is not finite or not in the world's free space. ``on_event``
    (e.g. :class:`crlam.experiments.explore_live_view.ExploreLiveFeed`) has ``scan(estimate,
    angles, ranges, max_range)`` called after every scan and ``decision(maps, origin, resolution,
    candidates, scores, best, estimates)`` after every decision."""
    res = cfg.resolution
    if len(start) != 3 or not all(math.isfinite(float(v)) for v in start):
        raise ConfigError(f"start must be three finite numbers (x, y, theta), got {tuple(start)!r}")
    if not bool(world.is_free(np.array([start[:2]], dtype=np.float64))[0]):
        raise ConfigError(f"start ({start[0]}, {start[1]}) is not in the free space of world {world.name!r}")
    truth = truth_grid(world, res)
    ny, nx = truth.shape
    origin = (float(world.origin[0]), float(world.origin[1]))
    extent = (origin[0], origin[1], origin[0] + nx * res, origin[1] + ny * res)
    crm = ConfidenceRichMap(MappingConfig(resolution=res, max_range=cfg.sensor_range, extent=extent, origin=origin))
    ogm = LogOddsOccupancyMap(LogOddsConfig(resolution=res, max_range=cfg.sensor_range, origin=origin))
    sensor = RangeSensor(
        n_beams=cfg.n_beams, fov=2 * math.pi, max_range=cfg.sensor_range, sigma_hit=cfg.sigma_range, endpoint=False
    )
    angles = sensor.angles
    rng = np.random.default_rng(cfg.seed)
    fn = (
        None
        if cfg.function == "frontier"
        else make_function(cfg.function, z_max=cfg.sensor_range, resolution=res, alpha=cfg.alpha, n_particles=cfg.particles)
    )
    map_fn = make_function("crmi", z_max=cfg.sensor_range, resolution=res) if cfg.function == "ucrmi" else None
    poses: list[NDArray[np.float64]] = []
    estimates: list[NDArray[np.float64]] = []
    bounds = extent
    rect = crm.region(bounds)
    fine = world.occupied
    fres = world.resolution

    def occupied_at(p: NDArray[np.float64]) -> bool:
        fy = int((p[1] - origin[1]) / fres)
        fx = int((p[0] - origin[0]) / fres)
        return not (0 <= fy < fine.shape[0] and 0 <= fx < fine.shape[1]) or bool(fine[fy, fx])

    slam_filter: Any = None
    odom = np.array(start, dtype=np.float64)
    if cfg.slam:
        from crlam.slam import SlamConfig, make_filter

        slam_cfg = SlamConfig(
            method="clam",
            particles=cfg.slam_particles,
            seed=cfg.seed,
            resolution=res,
            max_range=cfg.sensor_range,
            motion="gaussian",
            motion_params=tuple(cfg.odometry_sigma),
        )
        slam_filter = make_filter(slam_cfg, odom)

    def scan_at(p: NDArray[np.float64]) -> NDArray[np.float64]:
        """Scans at the true pose ``p``, updates the estimator and returns the estimate."""
        if occupied_at(p):
            raise RuntimeError(f"the robot entered an occupied cell of the world at {p[:2]}")
        z = sensor.simulate_ranges(world, p[None, :], rng)[0]
        poses.append(p.copy())
        if slam_filter is None:
            crm.update(p, angles, z)
            ogm.update(p, angles, z)
            est = p.copy()
        else:
            _, e, _, _ = slam_filter.process(odom, angles, np.ascontiguousarray(z), np.zeros(3))
            est = np.array(e)
        estimates.append(est)
        if on_event is not None:
            on_event.scan(est, angles, z, cfg.sensor_range)
        return est

    pose = np.array(start, dtype=np.float64)
    est = scan_at(pose)
    bumps = 0
    consecutive_bumps = 0
    decisions: list[dict[str, Any]] = []
    goals: list[tuple[float, float]] = []
    frames: list[dict[str, Any]] = []
    stop = "max_decisions"
    travelled = 0.0
    bar = tqdm(total=round(cfg.budget_m, 1), desc="explore", unit="m", disable=not progress, leave=False, mininterval=1.0)
    for k in range(cfg.max_decisions):
        t0 = time.perf_counter()
        if slam_filter is not None:
            # Decisions use the best particle's map and the estimated pose.
            crm.native = slam_filter.best_map()
        here = (
            min(max(int((est[1] - origin[1]) / res), 0), ny - 1),
            min(max(int((est[0] - origin[0]) / res), 0), nx - 1),
        )
        # The layers on a window around the written area (cells outside it are unknown, so never
        # free or frontier); identical to computing them on the whole map.
        dm = decision_maps(
            crm.native, rect, here, resolution=res, free_threshold=cfg.free_threshold, robot_radius=cfg.robot_radius
        )
        observed = dm.observed
        dist, pred = geodesic(dm.traversable, (here[0] - dm.iy0, here[1] - dm.ix0), res)
        reach = np.isfinite(dist) & (dist >= 2 * res)
        # Frontier: reachable cells as close to unknown space as the clearance allows.
        frontier = reach & (dm.to_unknown < cfg.robot_radius + 1.5 * res)
        # Up to n_candidates: half near the robot, half on the frontier (explore_candidates).
        idx, wy, wx, centres = pick_candidates(
            reach, frontier, (dm.iy0, dm.ix0), origin, res, est, cfg.radius_m, cfg.n_candidates, rng
        )
        # Animation frames keep the map as 8-bit levels (a 90 m map is 200 kB a frame).
        frame = {"decision": k, "poses": np.array(estimates), "mean": dm.mean_uint8()}
        if idx.size == 0:
            stop = "no_candidates"
            frames.append(frame)
            break
        cand = centres[idx]
        cost = dist[wy[idx], wx[idx]]
        if fn is None:
            is_fr = frontier[wy[idx], wx[idx]]
            if goals:
                # A frontier next to a goal already reached borders space the sensor cannot see
                # from there (the inside of furniture): do not go back to it.
                g = np.asarray(goals)
                seen = np.min(np.hypot(cand[:, None, 0] - g[None, :, 0], cand[:, None, 1] - g[None, :, 1]), axis=1) < 1.0
                is_fr &= ~seen
            if not is_fr.any():
                stop = "no_candidates"
                frames.append(frame)
                break
            score = np.where(is_fr, -cost, -np.inf)
            gains = score
        else:
            poses3 = np.column_stack([cand, np.zeros(len(cand))])
            if fn.name == "fsmi":
                prob = ogm.probability(bounds).values if slam_filter is None else dm.whole(dm.mean, dm.prior_mean)
                state: Any = _native.OccupancyLattice(np.ascontiguousarray(prob), res, origin)
                gains = fn.gains(state, poses3, seed=cfg.seed + k)
            elif fn.name == "ucrmi":
                if slam_filter is None:
                    root = fn.root_belief(est, seed=cfg.seed + k)
                else:
                    # The filter's particles, with the entropy the same estimator gives them after
                    # one edge that stays in place: I_p then compares candidates with staying.
                    placeholder = _filter_belief(slam_filter)
                    here_eval = fn.evaluate(crm.native, est, parent=est[:2], belief=placeholder, seed=cfg.seed + k)
                    root = _native.ParticleBelief.from_particles(
                        placeholder.particles, np.log(placeholder.weights), here_eval.belief.entropy_nats
                    )
                parents = np.tile(est[:2], (len(cand), 1))
                gains = fn.gains(crm.native, poses3, parents=parents, belief=root, seed=cfg.seed + k)
            else:
                gains = fn.gains(crm.native, poses3, seed=cfg.seed + k)
            score = gains / np.power(cost, cfg.cost_weight) if cfg.cost_weight > 0 else gains
        best = int(np.argmax(score))
        decision_ms = 1e3 * (time.perf_counter() - t0)
        if on_event is not None:
            on_event.decision(dm, origin, res, cand, score, best, np.array(estimates))
        row: dict[str, Any] = {
            "decision": k,
            "distance_m": round(travelled, 4),
            "explored_m2": round(float(observed.sum()) * res * res, 4),
            "map_entropy_bits": round(dm.entropy_sum(), 3),
            "map_error": round(float(((dm.mean > 0.5) != truth[dm.window])[observed].mean()) if observed.any() else 0.0, 5),
            "candidates": int(len(idx)),
            "best_gain": round(float(gains[best]), 6),
            "best_cost_m": round(float(cost[best]), 4),
            "decision_ms": round(decision_ms, 3),
            "pose_error_m": round(float(np.hypot(*(est[:2] - pose[:2]))), 5),
        }
        decisions.append(row)
        frames.append(frame)
        stop_value = float(gains[best]) if fn is not None else math.inf
        if fn is not None and fn.name == "ucrmi":
            # UCRMI's pose term can make every candidate look poor while there is still map to
            # gain: the stop rule looks at the largest map term (CRMI, bits) among the candidates.
            stop_value = float(np.max(map_fn.gains(crm.native, poses3))) if map_fn is not None else math.inf
        row["stop_value"] = round(stop_value, 6) if math.isfinite(stop_value) else None
        if stop_value < cfg.threshold:
            stop = "threshold"
            break
        if travelled >= cfg.budget_m:
            stop = "budget"
            break
        wnx = dm.mean.shape[1]
        cells = [(y + dm.iy0, x + dm.ix0) for y, x in _path(pred, int(wy[idx[best]] * wnx + wx[idx[best]]), wnx)]
        pts = np.array([[origin[0] + (x + 0.5) * res, origin[1] + (y + 0.5) * res] for y, x in cells])
        pts = np.vstack([est[:2], pts[1:]]) if len(pts) > 1 else np.vstack([est[:2], pts])
        goals.append((float(pts[-1, 0]), float(pts[-1, 1])))
        bumped = False
        for q in _resample(pts, cfg.step_m):
            # The robot drives toward the waypoint from where it believes it is; the motion it
            # makes is that command applied to its true pose (odometry measures it with noise).
            heading = math.atan2(q[1] - est[1], q[0] - est[0]) if np.hypot(*(q - est[:2])) > 0 else est[2]
            u = between(est, np.array([q[0], q[1], heading]))
            new_pose = compose(pose, u)
            n_check = max(2, int(np.hypot(*(new_pose[:2] - pose[:2])) / (0.5 * fres)) + 2)
            if any(occupied_at(x) for x in np.linspace(pose[:2], new_pose[:2], n_check)):
                bumps += 1
                bumped = True
                break
            if slam_filter is not None:
                odom = compose(odom, u + rng.normal(0.0, 1.0, 3) * np.asarray(cfg.odometry_sigma))
            travelled += float(np.hypot(*(new_pose[:2] - pose[:2])))
            pose = new_pose
            est = scan_at(pose)
            if travelled >= cfg.budget_m:
                break
        consecutive_bumps = consecutive_bumps + 1 if bumped else 0
        if consecutive_bumps >= 3:
            stop = "blocked"
            break
        bar.update(max(0.0, round(min(travelled, cfg.budget_m), 1) - bar.n))
        if verbose:
            line = f"decision {k}: gain {row['best_gain']:.3g}, {travelled:.1f} m, explored {row['explored_m2']:.0f} m^2"
            tqdm.write(line, file=sys.stderr)
    bar.close()
    return ExploreRun(
        config=cfg,
        world_name=world.name,
        poses=np.array(poses),
        estimates=np.array(estimates),
        bumps=bumps,
        decisions=decisions,
        stop=stop,
        crm=crm,
        truth=truth,
        goals=goals,
        frames=frames,
    )


def write_explore_folder(run: ExploreRun, out: str | os.PathLike[str], *, gif: bool = True) -> dict[str, Path]:
    """Writes an exploration run folder: ``trajectory.tum`` / ``groundtruth.tum`` (one pose per
    scan; identical with known poses), ``map.pgm`` + ``map.yaml``, ``belief.npz``,
    ``metrics.json``, ``progress.csv`` and the figures (``exploration.png``: the paper's Fig. 1
    pair; ``progress.png``: coverage and entropy against distance; ``exploration.gif``)."""
    from crlam.io.belief import save_belief
    from crlam.io.nav2 import write_nav2_map
    from crlam.io.tum import write_tum
    from crlam.viz.explore import save_animation, save_exploration_figure, save_progress_figure

    d = Path(out)
    d.mkdir(parents=True, exist_ok=True)
    cfg = run.config
    stamps = np.arange(len(run.poses), dtype=np.float64) * (cfg.step_m / 0.5)
    files = {
        "trajectory": d / "trajectory.tum",
        "groundtruth": d / "groundtruth.tum",
        "map": d / "map.pgm",
        "belief": d / "belief.npz",
        "progress": d / "progress.csv",
        "metrics": d / "metrics.json",
    }
    mode = "RBPF-CLAM" if cfg.slam else "known poses"
    write_tum(files["trajectory"], stamps, run.estimates, header=f"crlam explore: estimated poses ({mode})")
    write_tum(files["groundtruth"], stamps, run.poses, header="crlam explore: true poses")
    pose_err = np.hypot(*(run.estimates[:, :2] - run.poses[:, :2]).T)
    mean = run.crm.expected_occupancy(_bounds(run))
    ent = run.crm.entropy(_bounds(run)).values
    occ = np.where(ent < math.log2(10.0) - 1e-3, mean.values, np.nan)
    write_nav2_map(files["map"], occ, resolution=mean.resolution, origin=(mean.origin[0], mean.origin[1], 0.0))
    save_belief(files["belief"], run.crm.to_archive(_bounds(run)))
    keys = list(run.decisions[0]) if run.decisions else ["decision"]
    with files["progress"].open("w", newline="") as fh:
        w = csv.DictWriter(fh, fieldnames=keys)
        w.writeheader()
        w.writerows(run.decisions)
    last = run.decisions[-1] if run.decisions else {}
    free_truth = float((~run.truth).sum()) * cfg.resolution**2
    metrics = {
        "world": run.world_name,
        "config": cfg.to_dict(),
        "stop_reason": run.stop,
        "distance_m": run.distance,
        "n_scans": int(len(run.poses)),
        "n_decisions": len(run.decisions),
        "explored_m2": last.get("explored_m2", 0.0),
        "world_free_m2": free_truth,
        "map_entropy_bits": last.get("map_entropy_bits"),
        "map_error": last.get("map_error"),
        "decision_ms_mean": float(np.mean([r["decision_ms"] for r in run.decisions])) if run.decisions else None,
        "pose_error_mean_m": float(pose_err.mean()),
        "pose_error_max_m": float(pose_err.max()),
        "pose_error_final_m": float(pose_err[-1]),
        "bumps": run.bumps,
        "mode": mode,
    }
    write_atomic(files["metrics"], json.dumps(metrics, indent=2, sort_keys=True) + "\n")
    files["figure"] = save_exploration_figure(d / "exploration.png", run)
    files["progress_figure"] = save_progress_figure(d / "progress.png", run)
    if gif:
        files["animation"] = save_animation(d / "exploration.gif", run)
    return files


def _bounds(run: ExploreRun) -> tuple[float, float, float, float]:
    ny, nx = run.truth.shape
    ext = run.crm.config.extent
    assert ext is not None
    return (ext[0], ext[1], ext[0] + nx * run.config.resolution, ext[1] + ny * run.config.resolution)


def default_start(world: World, resolution: float = 0.2, clearance: float = 1.0) -> tuple[float, float, float]:
    """The free map cell nearest the world's lower-left corner with ``clearance`` metres around it."""
    truth = truth_grid(world, resolution)
    # Outside the map counts as occupied: a start needs room inside it.
    clear = distance_map(np.pad(truth, 1, constant_values=True), resolution, clearance + resolution)[1:-1, 1:-1]
    iy, ix = np.nonzero(clear >= clearance)
    if iy.size == 0:
        raise ConfigError(f"world {world.name!r} has no cell with {clearance} m of clearance to start from")
    k = int(np.argmin(ix + iy))
    return (float(world.origin[0]) + (ix[k] + 0.5) * resolution, float(world.origin[1]) + (iy[k] + 0.5) * resolution, 0.0)
