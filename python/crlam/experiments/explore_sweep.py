"""``crlam experiment explore``: exploration runs over worlds, functions, UCRMI alphas and seeds.

Each run writes ``runs/<name>/progress.csv`` and then ``metrics.json`` (last, atomically), so a
rerun skips finished runs. The experiment folder gets ``runs.csv`` (one row per run),
``coverage.png`` (explored area, map error and pose error against distance, mean over seeds),
``pose_error.png`` and ``report.md``.
"""

from __future__ import annotations

import csv
import json
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from crlam.errors import ConfigError
from crlam.experiments.executor import Executor, RunLayout
from crlam.experiments.explore import FUNCTIONS, ExploreConfig, default_start, explore
from crlam.experiments.pool import run_jobs, write_atomic
from crlam.experiments.resume import close_experiment, input_digest, load_json_dict, open_experiment
from crlam.io.run_folder import staged_folder
from crlam.sim.worlds import WORLD_NAMES

__all__ = ["ExploreSweep", "run_explore_experiment", "run_one_exploration", "variant_label"]

#: An exploration reads its world's map file (none for a built-in world) and writes ``metrics.json`` last.
EXPLORE_RUN_LAYOUT = RunLayout(inputs=("world_file",))


def variant_label(function: str, alpha: float | None) -> str:
    return f"ucrmi a={alpha:g}" if function == "ucrmi" else function


def run_one_exploration(
    world: str,
    world_seed: int,
    function: str,
    alpha: float,
    seed: int,
    budget: float,
    slam: bool,
    particles: int,
    folder: str,
    world_file: str | None = None,
) -> dict[str, Any]:
    """One exploration; writes ``progress.csv`` and then ``metrics.json`` into ``folder``.
    ``world`` names the world in the results; it is read from ``world_file`` when given (a
    copy of the map file ``world`` names, e.g. on a remote worker)."""
    from crlam.sim.worlds import get_world

    w = get_world(world_file or world, seed=world_seed)
    cfg = ExploreConfig(
        function=function, alpha=alpha, budget_m=budget, threshold=0.05, seed=seed, slam=slam, slam_particles=particles
    )
    run = explore(w, default_start(w), cfg)
    err = np.hypot(*(run.estimates[:, :2] - run.poses[:, :2]).T)
    rows = run.decisions
    last = run.decisions[-1] if run.decisions else {}
    metrics = {
        "world": world,
        "function": function,
        "variant": variant_label(function, alpha),
        "alpha": alpha if function == "ucrmi" else None,
        "seed": seed,
        "slam": slam,
        "stop": run.stop,
        "distance_m": round(run.distance, 4),
        "explored_m2": last.get("explored_m2", 0.0),
        "map_error": last.get("map_error"),
        "pose_error_mean_m": round(float(err.mean()), 5),
        "pose_error_max_m": round(float(err.max()), 5),
        "decisions": len(run.decisions),
        "decision_ms_mean": round(float(np.mean([r["decision_ms"] for r in run.decisions])), 3) if run.decisions else None,
        "bumps": run.bumps,
    }
    # Staged: the run's folder appears (replacing an older, unfinished or corrupt one) only whole.
    with staged_folder(folder, command=f"crlam experiment explore ({world}, {function}, seed {seed})") as d:
        with (d / "progress.csv").open("w", newline="") as fh:
            wr = csv.DictWriter(fh, fieldnames=list(rows[0]) if rows else ["decision"])
            wr.writeheader()
            wr.writerows(rows)
        write_atomic(d / "metrics.json", json.dumps(metrics, indent=2, sort_keys=True) + "\n")
    return metrics


def _finished_exploration(folder: Path) -> dict[str, Any] | None:
    """The metrics of a finished run, or None when its files are missing or unreadable (the run is
    then done again)."""
    metrics = load_json_dict(folder / "metrics.json")
    if metrics is None or not {"world", "variant", "pose_error_mean_m"} <= set(metrics):
        return None
    try:
        with (folder / "progress.csv").open(newline="") as fh:
            for row in csv.DictReader(fh):
                for key in ("distance_m", "explored_m2", "map_error", "pose_error_m"):
                    float(row[key])
    except (OSError, ValueError, KeyError, TypeError, csv.Error, UnicodeDecodeError):
        return None
    return metrics


@dataclass(frozen=True)
class ExploreSweep:
    out: Path
    rows: list[dict[str, Any]]
    errors: dict[str, str]
    files: dict[str, Path]


def run_explore_experiment(
    out: str | Path,
    *,
    worlds: Sequence[str] = ("office",),
    functions: Sequence[str] = ("crmi", "ucrmi", "fsmi", "frontier"),
    alphas: Sequence[float] = (0.0, 0.25, 0.5, 0.75, 1.0),
    runs: int = 3,
    budget: float = 60.0,
    slam: bool = True,
    particles: int = 30,
    world_seed: int = 0,
    workers: int = 2,
    progress: bool = True,
    executor: Executor | None = None,
    resume: bool = True,
    force: bool = False,
    verbose: bool = False,
) -> ExploreSweep:
    """Runs (resuming) every combination and writes ``runs.csv``, the figures and ``report.md``.
    ``executor``: where the runs go (default: ``workers`` local processes).

    An existing ``out`` is resumed (``resume``; its runs must have the same budget, pose source,
    particles and world seed, and a world file it already has runs of must be the same file, by
    content) or replaced (``force``); see :mod:`crlam.experiments.resume`. A run whose files
    cannot be read is run again."""
    if not functions or not worlds:
        raise ConfigError("no function or no world given: the sweep would run nothing")
    if "ucrmi" in functions and not alphas:
        raise ConfigError("UCRMI needs at least one alpha (--alphas)")
    for f in functions:
        if f not in FUNCTIONS:
            raise ConfigError(f"unknown function {f!r}; expected one of {', '.join(FUNCTIONS)}")
    if any(not (0.0 <= a <= 1.0) for a in alphas):
        raise ConfigError(f"alphas must be in [0, 1], got {list(alphas)}")
    inputs = {f"world:{Path(w).stem}": (input_digest(w) if Path(w).is_file() else w) for w in worlds}
    root = open_experiment(
        out,
        "explore",
        {"budget": budget, "slam": slam, "particles": particles, "world_seed": world_seed},
        inputs=inputs,
        resume=resume,
        force=force,
    )
    jobs = []
    for world in worlds:
        for f in functions:
            for a in alphas if f == "ucrmi" else (0.5,):
                for seed in range(runs):
                    tag = f"{Path(world).stem}-{f}" + (f"-a{a:g}" if f == "ucrmi" else "") + f"-s{seed:02d}"
                    jobs.append(
                        (
                            tag,
                            {
                                "world": world,
                                "world_seed": world_seed,
                                "function": f,
                                "alpha": float(a),
                                "seed": seed,
                                "budget": budget,
                                "slam": slam,
                                "particles": particles,
                                "folder": str(root / "runs" / tag),
                                "world_file": None if world in WORLD_NAMES else world,
                            },
                        )
                    )
    done, errors = run_jobs(
        jobs,
        run_one_exploration,
        lambda n: _finished_exploration(root / "runs" / n) is not None,
        lambda n: _finished_exploration(root / "runs" / n) or {},
        workers=workers,
        progress=progress,
        verbose=verbose,
        desc="explorations",
        executor=executor,
        layout=EXPLORE_RUN_LAYOUT,
    )
    rows = [{**done[n], "name": n} for n, _ in jobs if n in done]
    files = {"runs": root / "runs.csv", "report": root / "report.md"}
    keys = list(rows[0]) if rows else ["name"]
    with files["runs"].open("w", newline="") as fh:
        wr = csv.DictWriter(fh, fieldnames=keys)
        wr.writeheader()
        wr.writerows(rows)
    if rows:
        from crlam.viz.explore import save_sweep_figures

        files.update(save_sweep_figures(root, rows))
    files["report"].write_text(_report(rows, errors, budget=budget, slam=slam))
    close_experiment(root, n_runs=len(jobs), failed=errors)
    return ExploreSweep(out=root, rows=rows, errors=errors, files=files)


def _report(rows: Sequence[dict[str, Any]], errors: dict[str, str], *, budget: float, slam: bool) -> str:
    lines = [
        "# Exploration comparison",
        "",
        f"Budget {budget:g} m per run; poses {'estimated by RBPF-CLAM from noisy odometry' if slam else 'known'}; "
        "mean ± std over seeds.",
        "",
        "| world | variant | runs | explored [m²] | map error | pose error mean [m] | pose error max [m] | distance [m] "
        "| stops |",
        "|---|---|---|---|---|---|---|---|---|",
    ]
    groups: dict[tuple[str, str], list[dict[str, Any]]] = {}
    for r in rows:
        groups.setdefault((str(r["world"]), str(r["variant"])), []).append(r)

    def ms(rs: list[dict[str, Any]], key: str, fmt: str) -> str:
        v = np.array([float(r[key]) for r in rs if r.get(key) is not None])
        if v.size == 0:
            return "-"
        return f"{v.mean():{fmt}} ± {v.std(ddof=1) if v.size > 1 else 0.0:{fmt}}"

    for (world, variant), rs in sorted(groups.items()):
        stops = ", ".join(f"{s} {sum(1 for r in rs if r['stop'] == s)}" for s in sorted({str(r["stop"]) for r in rs}))
        lines.append(
            f"| {world} | {variant} | {len(rs)} | {ms(rs, 'explored_m2', '.0f')} | {ms(rs, 'map_error', '.3f')} | "
            f"{ms(rs, 'pose_error_mean_m', '.3f')} | {ms(rs, 'pose_error_max_m', '.3f')} | "
            f"{ms(rs, 'distance_m', '.0f')} | {stops} |"
        )
    uc = {v: rs for (w, v), rs in groups.items() if v.startswith("ucrmi")}
    if slam and len(uc) > 1:
        best = min(uc, key=lambda v: float(np.mean([r["pose_error_mean_m"] for r in uc[v]])))
        lines += ["", f"Lowest mean pose error among the UCRMI weights: **{best}**."]
    if errors:
        lines += ["", "## Failed runs", ""] + [f"- `{n}`: {e.splitlines()[0]}" for n, e in sorted(errors.items())]
    lines += ["", "Figures: `coverage.png` (explored area, map error and pose error against distance), `pose_error.png`.", ""]
    return "\n".join(lines)
