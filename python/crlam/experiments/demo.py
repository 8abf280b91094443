"""``crlam demo``: the main job on built-in data.

Simulates the 90 m x 90 m museum-like world with the paper's LIDAR (1079 beams over 270°, 8 m),
writes the log, builds the confidence-rich map and the log-odds baseline with the ground-truth
poses and with raw odometry, scores both maps against the world and writes figures and
``report.md``.
"""

from __future__ import annotations

import json
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from numpy.typing import NDArray
from tqdm import tqdm

from crlam.eval.maps import MapScores, score_map, world_coverage
from crlam.experiments.known_poses import KnownPoseScan, MappingRun, map_scans, write_map_folder
from crlam.mapping import ConfidenceRichMap, MapLayer, MappingConfig
from crlam.sim.simulate import SimulatedLog, SimulationConfig, simulate, write_simulation
from crlam.slam import SlamConfig, SlamRun
from crlam.slam.grid_alignment import from_map_frame, into_map_frame

__all__ = ["DEMO_PRESET", "run_demo"]

DEMO_PRESET = "robust"
"""The preset of the demo's whole-run SLAM: the default of ``crlam slam``."""

#: Entropy drop (bits) from the prior for a CRM cell to count as observed when scoring.
OBSERVED_BITS = 0.1


def _scans(log: SimulatedLog, poses: np.ndarray) -> list[KnownPoseScan]:
    s = log.sensor
    angles = s.angles
    out = []
    for k in range(log.n_scans):
        r = np.where(log.ranges[k] >= s.max_range, np.inf, log.ranges[k])
        out.append(KnownPoseScan(poses[k], angles, r, float(log.timestamps[k])))
    return out


def _scores(run: MappingRun, log: SimulatedLog) -> tuple[MapScores, MapScores]:
    """(CRM, log-odds) scores over the CRM's written area."""
    rect = run.crm.region()
    mean, _, ent = run.crm.layers()
    cov = world_coverage(mean, log.world.occupied, log.world.origin, log.world.resolution)
    lo = run.ogm.native.log_odds(rect)
    prob = MapLayer(1.0 / (1.0 + np.power(run.ogm.config.base, -lo)), mean.origin, mean.resolution)
    p = run.crm.native.prior
    h_prior = float(-(p * np.log2(p)).sum())
    # Observed: at least a tenth of a bit learned (CRM), or at least one update (log-odds).
    observed_crm = ent.values < h_prior - OBSERVED_BITS
    observed_ogm = np.abs(lo) >= min(abs(run.ogm.config.l_free), run.ogm.config.l_occ) - 1e-6
    return score_map(mean, observed_crm, cov), score_map(prob, observed_ogm, cov)


@dataclass(eq=False)
class _WholeRun:
    """RBPF-CLAM over a whole simulated log: its estimate (n, 3) in the map's frame, best map,
    wall time (s), and the map frame's pose F (``compose(F, q)``: odometry-frame pose q in it)."""

    config: SlamConfig
    poses: NDArray[np.float64]
    map: ConfidenceRichMap
    wall_time_s: float
    map_frame: NDArray[np.float64]

    def in_map_frame(self, poses: NDArray[np.float64]) -> NDArray[np.float64]:
        """Odometry-frame poses (the simulation's ground truth) in the map's frame."""
        return into_map_frame(self.map_frame, poses)

    def in_odometry_frame(self) -> NDArray[np.float64]:
        """The estimate in the odometry's (the simulation's) frame."""
        return from_map_frame(self.map_frame, self.poses)


def _slam_whole_run(log: SimulatedLog, *, seed: int, progress: bool, particles: int | None = None) -> _WholeRun:
    extra = {} if particles is None else {"particles": particles}
    cfg = SlamConfig.from_preset(DEMO_PRESET, seed=seed, **extra)
    run = SlamRun(cfg)
    ranges = np.where(log.ranges >= log.sensor.max_range, np.inf, log.ranges)
    t0 = time.perf_counter()
    for k in tqdm(range(log.n_scans), desc="RBPF-CLAM", unit="scan", disable=not progress, leave=False, mininterval=1.0):
        run.step(log.odometry[k], log.sensor.angles, ranges[k], np.zeros(3), float(log.timestamps[k]))
    wall = time.perf_counter() - t0
    best = run.best_map()
    assert isinstance(best, ConfidenceRichMap)
    assert run.map_frame is not None
    return _WholeRun(cfg, run.trajectory()[1], best, wall, run.map_frame)


def _save_slam_figure(slam: _WholeRun, log: SimulatedLog, path: Path) -> Path:
    from crlam.experiments.known_poses import unknown_mask
    from crlam.viz.maps import save_slam_beside_world

    mean, _, ent = slam.map.layers()
    return save_slam_beside_world(
        path,
        log.world.occupied,
        log.world.origin,
        log.world.resolution,
        mean,
        unknown_mask(slam.map, ent),
        truth=slam.in_map_frame(log.poses),
        estimate=slam.poses,
        title=f"RBPF-CLAM ({DEMO_PRESET} preset, {slam.config.particles} particles) over {log.n_scans} scans",
    )


def _row(name: str, s: MapScores) -> str:
    return (
        f"| {name} | {s.n_observed} | {s.accuracy:.3f} | {s.occupied_precision:.3f} | {s.occupied_recall:.3f} | "
        f"{s.free_accuracy:.3f} | {s.mean_occupied:.3f} | {s.mean_free:.3f} |"
    )


#: What ``quick=True`` (``crlam demo --quick``) shrinks: every step still runs and writes its
#: figures and its section of the report, on a short log with few particles.
QUICK = {"n_scans": 300, "loc_scans": 60, "loc_particles": 10, "slam_particles": 8, "iig_particles": 10, "explore_m": 10.0}


QUICK_NOTE = (
    "A quick run (`--quick`): a short log and few particles, to check an installation; the full demo runs without it.\n\n"  # noqa: E501
)


def run_demo(
    out: Path,
    *,
    n_scans: int | None = None,
    seed: int = 0,
    progress: bool = True,
    loc_scans: int | None = None,
    loc_particles: int | None = None,
    quick: bool = False,
) -> Path:
    """Runs the demo into ``out`` and returns the path of ``report.md``.

    ``n_scans`` (default 4000), ``loc_scans`` (300) and ``loc_particles`` (30) size the run;
    ``quick`` gives the short run of :data:`QUICK` (the same steps, figures and report in
    seconds, for checking an installation) for what is not given."""
    n_scans = n_scans if n_scans is not None else (int(QUICK["n_scans"]) if quick else 4000)
    loc_scans = min(n_scans, loc_scans if loc_scans is not None else (int(QUICK["loc_scans"]) if quick else 300))
    loc_particles = loc_particles if loc_particles is not None else (int(QUICK["loc_particles"]) if quick else 30)
    t_start = time.perf_counter()
    out.mkdir(parents=True, exist_ok=True)
    say = print if progress else (lambda *a, **k: None)
    say(f"[1/8] simulating {n_scans} scans of the museum world (seed {seed}) ...", flush=True)
    t0 = time.perf_counter()
    log = simulate(SimulationConfig(world="museum", n_scans=n_scans, seed=seed, sensor="paper_lidar"))
    write_simulation(log, out / "simulation")
    from crlam.viz.maps import save_world_figure

    save_world_figure(
        out / "world.png",
        log.world.occupied,
        log.world.origin,
        log.world.resolution,
        trajectory=log.poses,
        title=f"museum world (90 m x 90 m): {n_scans} scans, {log.trajectory.length:.0f} m",
    )
    t_sim = time.perf_counter() - t0

    cfg = MappingConfig(resolution=0.2, max_range=log.sensor.max_range)
    say("[2/8] mapping with the ground-truth poses ...", flush=True)
    truth = map_scans(_scans(log, log.poses), cfg, progress=progress, desc="CRM, true poses")
    write_map_folder(truth, out / "map_groundtruth_poses", title="Museum: CRM with ground-truth poses (ijrr, 0.2 m)")
    say("[3/8] mapping with raw odometry (what SLAM must fix) ...", flush=True)
    odo = map_scans(_scans(log, log.odometry), cfg, progress=progress, desc="CRM, odometry")
    write_map_folder(odo, out / "map_odometry_poses", title="Museum: CRM with raw odometry poses (ijrr, 0.2 m)")

    say("[4/8] scoring the maps against the world ...", flush=True)
    crm_t, ogm_t = _scores(truth, log)
    crm_o, ogm_o = _scores(odo, log)
    drift = np.hypot(*(log.odometry[:, :2] - log.poses[:, :2]).T)
    say(f"[5/8] localization: particle filters on the first {loc_scans} scans ...", flush=True)
    from crlam.experiments.localization import compare_localization, save_localization_figures

    loc = compare_localization(log, n_scans=loc_scans, particles=loc_particles, seed=seed, progress=progress)
    save_localization_figures(loc, log.poses, out)
    loc_rows = loc.table()
    say(f"[6/8] SLAM: RBPF-CLAM ({DEMO_PRESET} preset) over all {n_scans} scans ...", flush=True)
    slam = _slam_whole_run(log, seed=seed, progress=progress, particles=int(QUICK["slam_particles"]) if quick else None)
    slam_rmse = float(np.sqrt(np.mean(np.sum((slam.in_odometry_frame()[:, :2] - log.poses[:, :2]) ** 2, axis=1))))
    odo_rmse = float(np.sqrt(np.mean(np.sum((log.odometry[:, :2] - log.poses[:, :2]) ** 2, axis=1))))
    _save_slam_figure(slam, log, out / "slam_map.png")
    say("[7/8] planning: IIG with five information functions on the office world ...", flush=True)
    from crlam.experiments.iig_demo import run_iig_demo

    iig_particles = int(QUICK["iig_particles"]) if quick else 30
    iig = run_iig_demo(out, seed=seed, particles=iig_particles)
    say("[8/8] exploring the museum world greedily by CRMI (known poses) ...", flush=True)
    from crlam.experiments.explore import ExploreConfig, default_start, explore, write_explore_folder
    from crlam.sim.worlds import get_world

    museum = get_world("museum", seed=seed)
    exp_cfg = ExploreConfig(function="crmi", budget_m=QUICK["explore_m"] if quick else 80.0, threshold=0.1, seed=seed)
    exp_run = explore(museum, default_start(museum), exp_cfg)
    write_explore_folder(exp_run, out / "exploration")
    exp_last = exp_run.decisions[-1] if exp_run.decisions else {}
    speed = truth.n_scans / truth.wall_time_s
    total = time.perf_counter() - t_start
    results = {
        "n_scans": n_scans,
        "seed": seed,
        "quick": quick,
        "path_length_m": log.trajectory.length,
        "odometry_final_drift_m": float(drift[-1]),
        "odometry_max_drift_m": float(drift.max()),
        "scores": {
            "crm_true_poses": crm_t.as_dict(),
            "ogm_true_poses": ogm_t.as_dict(),
            "crm_odometry": crm_o.as_dict(),
            "ogm_odometry": ogm_o.as_dict(),
        },
        "timing_s": {
            "simulate": t_sim,
            "map_true_poses": truth.wall_time_s,
            "map_odometry": odo.wall_time_s,
            "slam": slam.wall_time_s,
            "total": total,
        },
        "mapping_scans_per_s": speed,
        "config": cfg.to_dict(),
        "localization": {"n_scans": loc.n_scans, "particles": loc.particles, "rows": loc_rows},
        "slam": {
            "preset": DEMO_PRESET,
            "n_scans": n_scans,
            "rmse_position_m": slam_rmse,
            "odometry_rmse_position_m": odo_rmse,
            "wall_time_s": slam.wall_time_s,
        },
        "iig": iig.rows,
        "exploration": {"stop": exp_run.stop, "distance_m": exp_run.distance, **exp_last},
    }
    (out / "results.json").write_text(json.dumps(results, indent=2, sort_keys=True) + "\n")
    header = (
        "| map | observed cells | accuracy | occupied precision | occupied recall | free accuracy "
        "| mean m̂ on occupied | mean m̂ on free |"
    )
    loc_table = "\n".join(
        f"| {r['method']} | {r['mae_x_m']:.3f} | {r['mae_y_m']:.3f} | {r['mae_theta_deg']:.2f} | {r['rmse_position_m']:.3f} | "
        f"{r['wall_time_s']:.1f} |"
        for r in loc_rows
    )
    from crlam.experiments.iig import LABELS

    iig_table = "\n".join(
        f"| {LABELS[r['function']]} | {r['units']} | {r['samples']} | {r['nodes']} | {r['total_cost_m']:.1f} | "
        f"{r['total_info']:.1f} | {r['mean_ric']:.4f} | {r['stop']} | {r['planning_time_s']:.2f} |"
        for r in iig.rows
    )
    iig_claims = "\n".join(
        f"- {text}: {'not checked' if ok is None else ('holds' if ok else 'does not hold')} ({nums})."
        for text, ok, nums in iig.claims
    )
    report = f"""# crlam demo: confidence-rich mapping of the museum world

{QUICK_NOTE if quick else ""}Built-in data only: a procedural 90 m x 90 m museum-like world (halls, rooms, doors, pillars,
exhibits and clutter), the paper's LIDAR (1079 beams over 270 deg, 8 m max range, beam-mixture
noise) and odometry with Gaussian increment noise (sigma 0.01 m, 0.01 m, 0.01 rad per scan).

- scans: {n_scans} (seed {seed}), path length {log.trajectory.length:.1f} m
- odometry drift: {drift[-1]:.2f} m at the end, {drift.max():.2f} m at worst
- CRM settings: {cfg.model} model, {cfg.n_levels} {cfg.levels} levels, {cfg.scan_update} scan update,
  {cfg.resolution} m cells, sigma_hit {cfg.hit_sigma:.4f} m
- mapping speed: {speed:.0f} scans/s ({speed * log.sensor.n_beams:.0f} beam updates/s, one thread)
- wall time: simulate {t_sim:.1f} s, map {truth.wall_time_s:.1f} s + {odo.wall_time_s:.1f} s, total {total:.1f} s

The simulated log is in `simulation/` (`log.clf` in CARMEN format, whose pose fields are the noisy
odometry; `groundtruth.tum`; `world.pgm`/`world.yaml`).

![world and trajectory](world.png)

## Map with the ground-truth poses

![CRM with true poses](map_groundtruth_poses/map.png)

## Map with raw odometry

The same scans placed with the drifting odometry: the blur is what the particle filter
(RBPF-CLAM) removes.

![CRM with odometry](map_odometry_poses/map.png)

## Scores against the world

Observed cells only (CRM: at least 0.1 bit learned; log-odds: at least one update). A cell is
truly occupied when obstacles cover at least a quarter of it and truly free when nothing covers
it (cells with a sliver of obstacle are not scored); the map calls it occupied when its value
exceeds 0.5 (m̂ for the CRM, p for the log-odds map).

{header}
|---|---|---|---|---|---|---|---|
{_row("CRM, true poses", crm_t)}
{_row("log-odds, true poses", ogm_t)}
{_row("CRM, odometry", crm_o)}
{_row("log-odds, odometry", ogm_o)}

Precision is high and free space is almost always right. Recall on occupied cells is modest for
both maps at 0.2 m: a wall that covers only part of a cell is crossed, through the cell's free
part, by the many beams that graze along it, and under the pure-hit cause model (as under the
log-odds update) those passes count as evidence of free space. With the drifting odometry every
score collapses: the scans no longer agree on where the walls are.

## Localization

The particle filters on the first {loc.n_scans} scans ({loc.particles} particles, the paper's settings
otherwise: odometry proposal, every beam, no tempering), against the exact ground truth:

| trajectory | MAE x [m] | MAE y [m] | MAE theta [deg] | RMSE position [m] | wall time [s] |
|---|---|---|---|---|---|
{loc_table}

![trajectories](localization_trajectories.png)

![errors](localization_errors.png)

## SLAM over the whole run

RBPF-CLAM with the `{DEMO_PRESET}` preset (the default of `crlam slam`: {slam.config.particles} particles,
{slam.config.resolution} m cells, the scan-match proposal) over all {n_scans} scans, from the noisy odometry
alone. Left: the world; right: the best particle's map, with the estimate (blue) and the ground
truth (black, dashed). Position RMSE {slam_rmse:.3f} m over the run (odometry: {odo_rmse:.2f} m),
{slam.wall_time_s:.0f} s.

![SLAM map beside the world](slam_map.png)

## Planning with information functions

The IIG planner (reference settings, one seed) from a corner of the procedural office world, with
each information function on the same prior map (occupied 0.85, free 0.3; OGMI by exact FSMI,
UCRMI with {iig_particles} particles). `crlam experiment iig` runs the full comparison (20 seeds, the Cave map).

| function | units | samples | nodes | total cost [m] | total info | mean I_RIC | stop | time [s] |
|---|---|---|---|---|---|---|---|---|
{iig_table}

The paper's claims, on this single run (see `crlam experiment iig` for the statistics):

{iig_claims}

![IIG trees](iig_trees.png)

## Exploration

Greedy CRMI exploration of the museum world with known poses (360 deg, 5 m sensor; up to 200
candidates per decision; `crlam explore` for other worlds, functions and budgets): it stopped
({exp_run.stop}) after {len(exp_run.decisions)} decisions and {exp_run.distance:.0f} m, having observed
{exp_last.get("explored_m2", 0):.0f} m² with a map error of {100 * exp_last.get("map_error", 0):.1f} % on the
observed cells. Run folder: `exploration/` (trajectory, map, belief, progress.csv, animation).

![exploration](exploration/exploration.png)

Each map folder also holds `map.pgm`/`map.yaml` (Nav2), `belief.npz` (lossless beliefs),
`ogm.pgm`/`ogm.yaml` and `mapping.json`.
"""
    path = out / "report.md"
    path.write_text(report)
    say(f"done in {total:.1f} s", flush=True)
    return path
