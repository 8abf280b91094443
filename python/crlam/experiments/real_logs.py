"""RBPF-CLAM and RBPF-OGM on the Intel and ACES raw logs with their relations
(``crlam experiment real-logs``).

Every (dataset, method, particles, range, seed) is one resumable run. The folder gets
``table.md`` / ``table.csv`` / ``results.json``: the relations metric (absolute translational and
rotational error, mean ± std over the relations, then mean ± std over seeds), wall time and peak
memory, next to the published numbers of the data README.
"""

from __future__ import annotations

import csv
import json
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np

from crlam.experiments.executor import Executor
from crlam.experiments.resume import close_experiment, open_experiment
from crlam.experiments.sweep import RunSpec, run_sweep
from crlam.io.fetch import find_dataset
from crlam.slam import SlamConfig

__all__ = ["run_real_logs", "PUBLISHED", "FULL_RANGE"]

#: Published absolute translational errors (m) on the relations metric (data README).
PUBLISHED: dict[str, dict[str, str]] = {
    "intel": {
        "scan matching (2009)": "0.220 ± 0.296",
        "RBPF/GMapping 50 particles (2009)": "0.070 ± 0.083",
        "graph mapping (2009)": "0.031 ± 0.026",
        "Cartographer (2016)": "0.0229 ± 0.0239",
    },
    "aces": {
        "scan matching (2009)": "0.173 ± 0.614",
        "RBPF/GMapping 50 particles (2009)": "0.060 ± 0.049",
        "graph mapping (2009)": "0.044 ± 0.044",
        "Cartographer (2016)": "0.0375 ± 0.0426",
    },
}

#: z_max used for "full range": just below each sensor's no-return value.
FULL_RANGE = {"intel": 80.0, "aces": 49.0}

LOGS = {"intel": ("intel", "intel-relations"), "aces": ("aces", "aces-relations")}


def run_real_logs(
    out: Path,
    *,
    datasets: Sequence[str] = ("intel", "aces"),
    methods: Sequence[str] = ("ogm", "clam"),
    particles: Sequence[int] = (30, 100),
    seeds: int = 3,
    ranges: Sequence[str] = ("full", "8"),
    base: SlamConfig | None = None,
    workers: int = 2,
    threads: int = 1,
    max_scans: int | None = None,
    progress: bool = True,
    report_only: bool = False,
    executor: Executor | None = None,
    resume: bool = True,
    force: bool = False,
    verbose: bool = False,
) -> dict[str, Any]:
    """Runs (or resumes) the grid of runs and writes the table; returns the results.

    ``threads``: rayon threads of each run (the results do not depend on it; the wall times do).
    ``executor``: where the runs go (default: ``workers`` local processes; the results do not
    depend on it).

    ``base`` holds every setting but the grid's (method, particles, seed, max_range, which each
    run sets); without one the sweep uses the default preset (``SlamConfig.from_preset()``,
    ``robust``).

    ``report_only`` runs nothing: the table covers the runs finished so far.

    An existing ``out`` is resumed (``resume``: every finished run's ``config.toml`` must hold the
    settings asked for) or replaced (``force``); see :mod:`crlam.experiments.resume`."""
    base = base or SlamConfig.from_preset()
    out = open_experiment(out, "real-logs", {}, resume=resume, force=force, report_only=report_only, runs_check_themselves=True)
    specs: list[RunSpec] = []
    for ds in datasets:
        if ds not in LOGS:
            raise ValueError(f"unknown dataset {ds!r}; expected one of {sorted(LOGS)}")
        log, rel = (str(find_dataset(n)) for n in LOGS[ds])
        for m in methods:
            for n in particles:
                for rg in ranges:
                    zmax = FULL_RANGE[ds] if rg == "full" else float(rg)
                    for k in range(seeds):
                        # The grid over the base as over a preset: an RBPF-OGM run drops the base's
                        # loop closing (re-anchoring needs RBPF-CLAM's CRMs).
                        grid = {"method": m, "particles": n, "seed": k, "max_range": zmax}
                        cfg = SlamConfig(**SlamConfig.settle_preset_settings(base.to_dict(), grid))
                        specs.append(
                            RunSpec(f"{ds}_{m}_{n}p_{rg}m_seed{k}", log, cfg, relations=rel, max_scans=max_scans, threads=threads)
                        )
    done, errors = run_sweep(
        specs, out, workers=workers, progress=progress, report_only=report_only, executor=executor, verbose=verbose
    )
    rows = []
    for ds in datasets:
        for m in methods:
            for n in particles:
                for rg in ranges:
                    group = [done[s.name] for s in specs if s.name.startswith(f"{ds}_{m}_{n}p_{rg}m_") and s.name in done]
                    if not group:
                        continue
                    trans = np.array([g["relations"]["trans_mean_m"] for g in group])
                    rot = np.array([g["relations"]["rot_mean_deg"] for g in group])
                    # Runs from before 2026-11-25 did not record the best particle's path.
                    paths = [g["relations_best_path"]["trans_mean_m"] for g in group if "relations_best_path" in g]
                    # Only filters that draw from a fitted proposal record the proposal means (and runs
                    # from before 2026-11-26 never did).
                    means = [g["relations_best_path_means"]["trans_mean_m"] for g in group if "relations_best_path_means" in g]
                    # The online highest-weight particle and the particle-set spread: runs from 2026-11-26 on.
                    max_weight = [g["relations_max_weight"]["trans_mean_m"] for g in group if "relations_max_weight" in g]
                    # The mode-seeking estimate: runs from 2026-11-26 16:00 UTC on.
                    mode = [g["relations_mode"]["trans_mean_m"] for g in group if "relations_mode" in g]
                    smoothed = [g["relations_smoothed"]["trans_mean_m"] for g in group if "relations_smoothed" in g]
                    spread = [g["particle_set"]["spread_xy_mean_m"] for g in group if g.get("particle_set")]
                    rows.append(
                        {
                            "dataset": ds,
                            "method": m,
                            "particles": n,
                            "range": rg,
                            "seeds": len(group),
                            "trans_mean_m": float(trans.mean()),
                            "trans_std_over_seeds_m": float(trans.std(ddof=1)) if len(group) > 1 else 0.0,
                            "trans_within_run_std_m": float(np.mean([g["relations"]["trans_std_m"] for g in group])),
                            "rot_mean_deg": float(rot.mean()),
                            "trans_best_path_m": float(np.mean(paths)) if len(paths) == len(group) else float("nan"),
                            "trans_best_path_means_m": float(np.mean(means)) if len(means) == len(group) else float("nan"),
                            "trans_max_weight_m": float(np.mean(max_weight)) if len(max_weight) == len(group) else float("nan"),
                            "trans_mode_m": float(np.mean(mode)) if len(mode) == len(group) else float("nan"),
                            "trans_smoothed_m": float(np.mean(smoothed)) if len(smoothed) == len(group) else float("nan"),
                            "spread_xy_mean_m": float(np.mean(spread)) if len(spread) == len(group) else float("nan"),
                            "wall_time_s": float(np.mean([g["wall_time_s"] for g in group])),
                            "peak_rss_mb": float(np.max([g["peak_rss_mb"] for g in group])),
                            "n_missing_relations": int(max(g["relations"].get("n_missing", 0) for g in group)),
                        }
                    )
    results = {
        "config": base.to_dict(),
        "preset": base.preset,
        "deviations_from_paper": base.deviations(),
        "rows": rows,
        "errors": errors,
        "published": PUBLISHED,
        "max_scans": max_scans,
    }
    out.mkdir(parents=True, exist_ok=True)
    (out / "results.json").write_text(json.dumps(results, indent=2, sort_keys=True) + "\n")
    _write_table(out, rows, datasets)
    if not report_only:
        close_experiment(out, n_runs=len(specs), failed=errors)
    return results


def _or_dash(x: float, fmt: str) -> str:
    return "-" if np.isnan(x) else format(x, fmt)


def _write_table(out: Path, rows: list[dict[str, Any]], datasets: Sequence[str]) -> None:
    lines = [
        "# Real logs: relations metric",
        "",
        "| dataset | method | particles | z_max | seeds | trans. error [m] | rot. error [deg] | best path trans. [m] "
        "| best path means trans. [m] | max-weight trans. [m] | mode trans. [m] | smoothed trans. [m] | particle spread [m] "
        "| wall time [s] | peak RSS [MB] |",
        "|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|",
    ]
    for r in rows:
        lines.append(
            f"| {r['dataset']} | RBPF-{r['method'].upper()} | {r['particles']} | {r['range']} | {r['seeds']} | "
            f"{r['trans_mean_m']:.4f} ± {r['trans_within_run_std_m']:.4f} (seeds ± {r['trans_std_over_seeds_m']:.4f}) | "
            f"{r['rot_mean_deg']:.2f} | {_or_dash(r['trans_best_path_m'], '.4f')} | "
            f"{_or_dash(r['trans_best_path_means_m'], '.4f')} | {_or_dash(r['trans_max_weight_m'], '.4f')} | "
            f"{_or_dash(r['trans_mode_m'], '.4f')} | {_or_dash(r['trans_smoothed_m'], '.4f')} | "
            f"{_or_dash(r['spread_xy_mean_m'], '.3f')} | {r['wall_time_s']:.0f} | "
            f"{r['peak_rss_mb']:.0f} |"
        )
    lines += [
        "",
        "Translational error: mean ± std over relations, averaged over seeds; in brackets the std of the mean over seeds. "
        "Both errors are of the weighted-mean trajectory (`trajectory.tum`); 'best path' is the mean translational error "
        "of the final best particle's path (`estimates/best_path.tum`, GMapping's trajectory; '-' for runs that did "
        "not record it); 'best path means' is the same lineage with each pose replaced by the mean of the proposal it "
        "was drawn from (`estimates/best_path_means.tum`; '-' where the poses are not drawn from a fitted proposal or "
        "the run did not record it); 'max-weight' is the highest-weight particle chosen at each processed scan "
        "(`estimates/max_weight.tum`), 'mode' the mode-seeking estimate (`estimates/mode.tum`, the weighted mean "
        "of the densest group of particles), 'smoothed' the lineage smoother (`estimates/smoothed.tum`, each scan's "
        "ancestors of the final particles under the final weights, or those of the particles L scans later with "
        "`--smoothing-lag L`; '-' where the run did not record them), and 'particle spread' the weighted "
        "RMS distance of the particles from their mean, averaged over the processed scans (`steps.csv`; '-' where "
        "the run did not record it).",
        "",
        "## Published (absolute translational error, m)",
        "",
    ]
    for ds in datasets:
        lines.append(f"- {ds}: " + "; ".join(f"{k} {v}" for k, v in PUBLISHED[ds].items()))
    (out / "table.md").write_text("\n".join(lines) + "\n")
    with open(out / "table.csv", "w", newline="") as fh:
        if rows:
            w = csv.DictWriter(fh, fieldnames=list(rows[0]))
            w.writeheader()
            w.writerows(rows)
