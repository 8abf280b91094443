"""The paper's Table I protocol on the simulated museum world (``crlam experiment table1``).

One simulated log (the museum-like world, the paper's LIDAR: 1079 beams over 270 deg, 8 m,
0.2 m grid), ``runs`` Monte Carlo runs per method with different seeds, exact ground truth. The
folder gets ``table.md`` / ``table.csv`` / ``results.json`` (MAE x, y, theta and average RMSE of
position, mean ± std over runs), ``fig2_trajectories.png`` (trajectories on the CRM) and
``fig2_errors.png`` (error against time), plus ``runs/<name>/`` for every run.
"""

from __future__ import annotations

import csv
import json
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from crlam.errors import ConfigError
from crlam.eval.trajectory import ReferenceErrors, aggregate_runs, reference_errors
from crlam.experiments.executor import Executor
from crlam.experiments.resume import close_experiment, load_json_dict, open_experiment
from crlam.experiments.sweep import RunSpec, run_sweep
from crlam.io.belief import load_belief
from crlam.io.tum import read_tum
from crlam.mapping import ConfidenceRichMap
from crlam.sim.simulate import SimulationConfig, simulate, write_simulation
from crlam.slam import SlamConfig
from crlam.slam.grid_alignment import frame_from_record, from_map_frame, into_map_frame

__all__ = ["run_table1", "PAPER_TABLE1"]

METRICS = ("mae_x_m", "mae_y_m", "mae_theta_deg", "rmse_position_m")
LABELS = {"mae_x_m": "MAE x [m]", "mae_y_m": "MAE y [m]", "mae_theta_deg": "MAE theta [deg]", "rmse_position_m": "avg RMSE [m]"}
METHOD_NAMES = {"ogm": "RBPF-OGM", "clam": "RBPF-CLAM"}
#: The other trajectories a run folder can hold (metrics.json keys), reported below the table.
OTHER_ESTIMATES = {
    "reference_best_path": "final best particle's path",
    "reference_max_weight": "highest-weight particle",
    "reference_mode": "mode-seeking estimate",
    "reference_smoothed": "lineage smoother",
}
#: The protocol's LIDAR range (m): the simulated sensor's, whatever the preset.
PROTOCOL_MAX_RANGE = 8.0

#: Reported in the paper's Table I is only the ordering (CLAM below OGM); no numbers are copied.
PAPER_TABLE1 = "the paper reports RBPF-CLAM with lower errors than RBPF-OGM on every metric"


def ensure_simulation(sim_dir: Path, n_scans: int, sim_seed: int, world_seed: int) -> None:
    """Simulates the museum log once (skipped when it is already there: resume). A simulation of
    other settings is an error; one that cannot be read is made again."""
    stored = load_json_dict(sim_dir / "simulation.json")
    if stored is not None and (sim_dir / "log.clf").is_file() and (sim_dir / "groundtruth.tum").is_file():
        have = {k: stored.get("config", {}).get(k) for k in ("n_scans", "seed", "world_seed")}
        want = {"n_scans": n_scans, "seed": sim_seed, "world_seed": world_seed}
        if have != want:
            raise ConfigError(
                f"{sim_dir} holds a simulation of {have}, this command asks for {want} (use --force to redo every run, "
                "or another --out)"
            )
        return
    log = simulate(SimulationConfig(world="museum", n_scans=n_scans, seed=sim_seed, world_seed=world_seed, sensor="paper_lidar"))
    write_simulation(log, sim_dir)


def _fmt(mean: float, std: float) -> str:
    return f"{mean:.4f} ± {std:.4f}"


def run_table1(
    out: Path,
    *,
    runs: int = 15,
    scans: int = 5500,
    particles: int = 100,
    methods: Sequence[str] = ("ogm", "clam"),
    workers: int = 2,
    threads: int = 1,
    sim_seed: int = 0,
    world_seed: int = 0,
    base: SlamConfig | None = None,
    progress: bool = True,
    report_only: bool = False,
    executor: Executor | None = None,
    resume: bool = True,
    force: bool = False,
    verbose: bool = False,
) -> dict[str, Any]:
    """Runs (or resumes) the protocol and writes the table and figures; returns the results.

    An existing ``out`` is resumed (``resume``: same simulation, and every finished run's settings
    those asked for) or replaced (``force``); see :mod:`crlam.experiments.resume`.

    ``base`` holds the settings of every run (each sets its method, ``particles`` and seed); without
    one the runs use the ``paper`` preset at the protocol's 8 m.

    ``report_only`` runs nothing: the table and figures cover the runs finished so far.
    ``threads``: rayon threads of each run (the results do not depend on it; the wall times do).
    ``executor``: where the runs go (default: ``workers`` local processes; the results do not
    depend on it). Run 0's ``fig2_trajectories.png`` needs its map, which a Dask executor sends
    back only with ``keep_maps``. ``resume``: keep the finished runs of an earlier call with the
    same settings (a mismatch is an error); ``force``: empty the folder first."""
    out = open_experiment(
        out,
        "table1",
        {"scans": scans, "sim_seed": sim_seed, "world_seed": world_seed},
        resume=resume,
        force=force,
        report_only=report_only,
        runs_check_themselves=True,
    )
    sim_dir = out / "simulation"
    ensure_simulation(sim_dir, scans, sim_seed, world_seed)
    base = base or SlamConfig.from_preset("paper", particles=particles, max_range=PROTOCOL_MAX_RANGE)
    specs = []
    # Run-major order: a sweep stopped early leaves as many finished runs of each method.
    for k in range(runs):
        for m in methods:
            cfg = SlamConfig(**{**base.to_dict(), "method": m, "particles": particles, "seed": k})
            specs.append(
                RunSpec(
                    f"{m}_run{k:02d}", str(sim_dir / "log.clf"), cfg, reference=str(sim_dir / "groundtruth.tum"), threads=threads
                )
            )
    done, errors = run_sweep(
        specs, out, workers=workers, progress=progress, report_only=report_only, executor=executor, verbose=verbose
    )
    rows: dict[str, dict[str, Any]] = {}
    for m in methods:
        finished = [done[s.name] | {"name": s.name} for s in specs if s.config.method == m and s.name in done]
        summaries = [r["reference"] for r in finished]
        agg = aggregate_runs(summaries) if summaries else {}
        walls = [r["wall_time_s"] for r in finished]
        rss = [r["peak_rss_mb"] for r in finished]
        # Other trajectories of the same runs (runs made before an estimate existed lack it; its row
        # then covers only the runs that have it).
        others = {}
        for key in OTHER_ESTIMATES:
            have = [r[key] for r in finished if key in r]
            if have:
                rmse = [h["rmse_position_m"] for h in have]
                others[key] = {
                    "n_runs": len(have),
                    "rmse_position_m": {
                        "mean": float(np.mean(rmse)),
                        "std": float(np.std(rmse, ddof=1)) if len(rmse) > 1 else 0.0,
                    },
                }
        rows[m] = {
            "n_runs": len(finished),
            "runs": [r["name"] for r in finished],
            "metrics": agg,
            "other_estimates": others,
            "wall_time_s_mean": float(np.mean(walls)) if walls else None,
            "peak_rss_mb_max": float(np.max(rss)) if rss else None,
        }
    results = {
        "protocol": {
            "world": "museum",
            "scans": scans,
            "particles": particles,
            "runs": runs,
            "sim_seed": sim_seed,
            "world_seed": world_seed,
            "lidar": "1079 beams / 270 deg / 8 m",
            "resolution": base.resolution,
        },
        "config": base.to_dict(),
        "preset": base.preset,
        "deviations_from_paper": protocol_deviations(base),
        "rows": rows,
        "errors": errors,
        "paper": PAPER_TABLE1,
    }
    (out / "results.json").write_text(json.dumps(results, indent=2, sort_keys=True) + "\n")
    _write_tables(out, methods, rows, protocol_deviations(base))
    _write_figures(out, sim_dir, specs, done)
    if not report_only:
        close_experiment(out, n_runs=len(specs), failed=errors)
    return results


def protocol_deviations(base: SlamConfig) -> list[str]:
    """Settings that differ from the paper's (``SlamConfig.deviations``: every field against the
    ``paper`` preset, the grid included)."""
    return base.deviations()


def _write_tables(out: Path, methods: Sequence[str], rows: dict[str, dict[str, Any]], deviations: Sequence[str]) -> None:
    head = "| method | runs | " + " | ".join(LABELS[k] for k in METRICS) + " | wall time / run [s] |"
    lines = ["# Table I protocol (simulated museum world)", "", head, "|" + "---|" * (len(METRICS) + 3)]
    with open(out / "table.csv", "w", newline="") as fh:
        w = csv.writer(fh)
        w.writerow(["method", "runs", *[f"{k}_{s}" for k in METRICS for s in ("mean", "std")], "wall_time_s_mean"])
        for m in methods:
            r = rows[m]
            agg = r["metrics"]
            cells = [_fmt(agg[k]["mean"], agg[k]["std"]) if k in agg else "n/a" for k in METRICS]
            wall = f"{r['wall_time_s_mean']:.0f}" if r["wall_time_s_mean"] is not None else "n/a"
            lines.append(f"| {METHOD_NAMES.get(m, m)} | {r['n_runs']} | " + " | ".join(cells) + f" | {wall} |")
            w.writerow(
                [
                    m,
                    r["n_runs"],
                    *[agg[k][s] if k in agg else "" for k in METRICS for s in ("mean", "std")],
                    r["wall_time_s_mean"],
                ]
            )
    lines += [
        "",
        "Mean ± sample std over runs; errors against the exact ground truth at every scan (weighted-mean trajectory).",
        "",
    ]
    other_lines = []
    for m in methods:
        for key, label in OTHER_ESTIMATES.items():
            o = rows[m].get("other_estimates", {}).get(key)
            if o:
                rmse = o["rmse_position_m"]
                other_lines.append(f"| {METHOD_NAMES.get(m, m)} | {label} | {o['n_runs']} | {_fmt(rmse['mean'], rmse['std'])} |")
    if other_lines:
        lines += [
            "Other trajectories of the same runs:",
            "",
            "| method | trajectory | runs | avg RMSE [m] |",
            "|---|---|---|---|",
        ]
        lines += [*other_lines, ""]
    if deviations:
        lines += ["Settings that differ from the paper's: " + "; ".join(deviations) + ".", ""]
    for m in methods:
        seeds = [name.rsplit("run", 1)[1] for name in rows[m].get("runs", [])]
        lines.append(f"- {METHOD_NAMES.get(m, m)} runs (seeds): {', '.join(seeds) or 'none'}")
    lines.append("")
    (out / "table.md").write_text("\n".join(lines))


def _write_figures(out: Path, sim_dir: Path, specs: Sequence[RunSpec], done: dict[str, Any]) -> None:
    from crlam.experiments.known_poses import unknown_mask
    from crlam.viz.trajectories import save_error_figure, save_error_spread_figure, save_trajectories_on_map

    gt = read_tum(sim_dir / "groundtruth.tum")
    odo = read_tum(sim_dir / "odometry.tum")
    firsts = {s.config.method: s for s in specs if s.name in done and s.name.endswith("run00")}
    trajs = {"ground truth": gt.poses, "odometry": odo.poses}
    errs = [("odometry", reference_errors(odo.timestamps, odo.poses, gt.timestamps, gt.poses))]
    crm_run = firsts.get("clam")
    if crm_run is not None and not (crm_run.folder(out) / "belief.npz").is_file():
        # A run folder kept without its map (e.g. committed results): keep the figure there is.
        crm_run = None

    # Each run writes its poses in its map's frame; the ground truth is in the odometry's frame.
    def odometry_frame_poses(s: RunSpec, poses: NDArray[np.float64]) -> NDArray[np.float64]:
        return from_map_frame(frame_from_record(done[s.name].get("map_frame")), poses)

    for m, s in firsts.items():
        t = read_tum(s.folder(out) / "trajectory.tum")
        poses = odometry_frame_poses(s, t.poses)
        trajs[METHOD_NAMES.get(m, m)] = poses
        errs.append((METHOD_NAMES.get(m, m), reference_errors(t.timestamps, poses, gt.timestamps, gt.poses)))
    if crm_run is not None:
        # Drawn on run 0's RBPF-CLAM map: every trajectory in that map's frame.
        frame = frame_from_record(done[crm_run.name].get("map_frame"))
        trajs = {k: into_map_frame(frame, v) for k, v in trajs.items()}
        crm = ConfidenceRichMap.from_archive(load_belief(crm_run.folder(out) / "belief.npz"))
        mean, _, ent = crm.layers()
        save_trajectories_on_map(
            out / "fig2_trajectories.png",
            mean,
            unknown_mask(crm, ent),
            trajs,
            title="Museum world: trajectories on the RBPF-CLAM map (run 0)",
        )
    save_error_figure(out / "fig2_errors.png", errs, title="Museum world: error against time (run 0)")
    # Every finished run whose trajectory is still there (committed results keep run 0's only).
    spread: dict[str, list[ReferenceErrors]] = {}
    for s in specs:
        traj = s.folder(out) / "trajectory.tum"
        if s.name in done and traj.is_file():
            t = read_tum(traj)
            spread.setdefault(METHOD_NAMES.get(s.config.method, s.config.method), []).append(
                reference_errors(t.timestamps, odometry_frame_poses(s, t.poses), gt.timestamps, gt.poses)
            )
    if sum(len(v) for v in spread.values()) > len(firsts):
        save_error_spread_figure(
            out / "errors_all_runs.png", spread, title="Museum world: error against time, every run whose trajectory is on disk"
        )
