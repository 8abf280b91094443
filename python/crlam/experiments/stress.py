"""The default SLAM on stress variants of a CARMEN log (``crlam experiment stress``).

For a log (and its relations file or ground-truth TUM), the experiment writes the stress variants
of :mod:`crlam.experiments.stress_variants` (and ``none``, the log itself with one ODOM line per
scan: the unstressed run) into ``logs/``, runs the SLAM configuration on each with ``seeds``
seeds as one resumable sweep (``runs/<variant>_seed<k>``), and writes ``table.md``,
``table.csv`` and ``results.json``.

The error of a run is the relations metric's mean translational error (m) when a relations file
is given, else the position RMSE (m) against the ground-truth TUM. A variant **passes** when every
seed's error is at most ``tolerance`` (1.5) times the unstressed runs' mean error; the table
gives each seed's error, the variant's mean, and the ratio of its worst seed to the unstressed
mean.

Resuming: ``experiment.json`` holds the log's digest, the stress settings, the SLAM settings and
the scan limit; a resumed folder must agree. The variant logs are written whole or not at all
(written to a temporary name, then renamed), and reused when present.
"""

from __future__ import annotations

import csv
import json
import os
from collections.abc import Sequence
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Any

import numpy as np

from crlam.errors import ConfigError
from crlam.experiments.executor import Executor
from crlam.experiments.resume import close_experiment, input_digest, open_experiment
from crlam.experiments.stress_variants import STRESS_VARIANTS, StressSettings, build_variant, load_records, write_variant
from crlam.experiments.sweep import RunSpec, run_sweep
from crlam.slam import SlamConfig

__all__ = ["BASELINE", "StressResult", "run_stress"]

#: The unstressed variant every stress is compared with.
BASELINE = "none"


@dataclass
class StressResult:
    """What :func:`run_stress` produced: the table's rows, failed runs, and the files written."""

    rows: list[dict[str, Any]]
    errors: dict[str, str]
    files: dict[str, Path]


def _error_of(metrics: dict[str, Any]) -> float:
    """A run's error (m): relations mean translational error, else the reference position RMSE."""
    if "relations" in metrics:
        return float(metrics["relations"]["trans_mean_m"])
    if "reference" in metrics:
        return float(metrics["reference"]["rmse_position_m"])
    raise ConfigError("a stress run has neither relations nor a reference to measure its error against")


def _variant_logs(
    log: Path, out: Path, variants: Sequence[str], settings: StressSettings, max_scans: int | None, progress: bool
) -> dict[str, Path]:
    """Write (or reuse) every variant's log under ``out/logs``."""
    logs = out / "logs"
    logs.mkdir(parents=True, exist_ok=True)
    paths = {v: logs / f"{v}.clf.gz" for v in variants}
    missing = [v for v in variants if not paths[v].is_file()]
    if not missing:
        return paths
    records = load_records(log, max_scans)
    for v in missing:
        if progress:
            print(f"stress: writing variant {v} ({sum(1 for r in records if hasattr(r, 'ranges'))} scans)", flush=True)
        tmp = paths[v].with_name(f".{v}.partial.clf.gz")
        write_variant(build_variant(records, v, settings), tmp, v)
        os.replace(tmp, paths[v])
    return paths


def run_stress(
    log: str | os.PathLike[str],
    out: str | os.PathLike[str],
    *,
    relations: str | os.PathLike[str] | None = None,
    reference: str | os.PathLike[str] | None = None,
    variants: Sequence[str] = STRESS_VARIANTS,
    seeds: int = 3,
    base: SlamConfig | None = None,
    settings: StressSettings | None = None,
    max_scans: int | None = None,
    tolerance: float = 1.5,
    workers: int = 1,
    threads: int = 1,
    progress: bool = True,
    report_only: bool = False,
    executor: Executor | None = None,
    resume: bool = True,
    force: bool = False,
    verbose: bool = False,
) -> StressResult:
    """Builds the variants, runs (or resumes) every (variant, seed) and writes the table.

    Parameters
    ----------
    log : path
        A CARMEN log.
    out : path
        The experiment folder.
    relations, reference : path, optional
        How each run's error is measured (one of them is needed).
    variants : sequence of str
        Stress variants (:data:`~crlam.experiments.stress_variants.STRESS_VARIANTS`); the
        unstressed run is always added.
    seeds : int
        Seeds 0..seeds-1 per variant.
    base : SlamConfig, optional
        The SLAM settings (default: the default preset); each run sets its seed.
    settings : StressSettings, optional
        The stresses' sizes.
    max_scans : int, optional
        Only the first N scans of the log.
    tolerance : float
        A variant passes when every seed is within this factor of the unstressed mean.
    """
    if relations is None and reference is None:
        raise ConfigError("crlam experiment stress needs --relations or --reference to measure the runs' errors")
    if seeds < 1:
        raise ConfigError(f"seeds must be >= 1, got {seeds}")
    if not tolerance >= 1.0:
        raise ConfigError(f"tolerance must be >= 1, got {tolerance}")
    unknown = [v for v in variants if v not in STRESS_VARIANTS]
    if unknown:
        raise ConfigError(f"unknown stress variant(s) {', '.join(unknown)}: choose among {', '.join(STRESS_VARIANTS)}")
    base = base or SlamConfig.from_preset()
    settings = settings or StressSettings()
    log_path = Path(log)
    all_variants = [BASELINE, *[v for v in STRESS_VARIANTS if v in variants]]
    fixed = {
        "log": log_path.name,
        "stress": asdict(settings),
        "slam": base.to_dict(),
        "max_scans": max_scans,
        "seeds": seeds,
    }
    root = open_experiment(
        out,
        "stress",
        fixed,
        inputs={"log": input_digest(log_path)},
        resume=resume,
        force=force,
        report_only=report_only,
    )
    logs = _variant_logs(log_path, root, all_variants, settings, max_scans, progress and not report_only)
    specs = [
        RunSpec(
            f"{v}_seed{k}",
            str(logs[v]),
            SlamConfig(**{**base.to_dict(), "seed": k}),
            reference=None if reference is None else str(reference),
            relations=None if relations is None else str(relations),
            # The variant logs hold max_scans scans already; the limit also lets the relations
            # metric skip the relations of the scans left out.
            max_scans=max_scans,
            threads=threads,
        )
        for v in all_variants
        for k in range(seeds)
    ]
    done, errors = run_sweep(
        specs, root, workers=workers, progress=progress, report_only=report_only, executor=executor, verbose=verbose
    )
    rows = _rows(done, all_variants, seeds, tolerance)
    files = _write_tables(root, rows, fixed, errors, relations is not None, tolerance)
    if not report_only:
        close_experiment(root, n_runs=len(specs), failed=errors)
    return StressResult(rows=rows, errors=errors, files=files)


def _rows(done: dict[str, dict[str, Any]], variants: Sequence[str], seeds: int, tolerance: float) -> list[dict[str, Any]]:
    base_errors = [_error_of(done[f"{BASELINE}_seed{k}"]) for k in range(seeds) if f"{BASELINE}_seed{k}" in done]
    base_mean = float(np.mean(base_errors)) if base_errors else float("nan")
    rows = []
    for v in variants:
        per_seed = [(k, done.get(f"{v}_seed{k}")) for k in range(seeds)]
        errs = [_error_of(m) for _, m in per_seed if m is not None]
        offsets = [m.get("time_offset") or {} for _, m in per_seed if m is not None]
        worst = max(errs) if errs else float("nan")
        complete = len(errs) == seeds and len(base_errors) == seeds
        rows.append(
            {
                "variant": v,
                "seeds_done": len(errs),
                "errors_m": [float(e) for e in errs],
                "mean_m": float(np.mean(errs)) if errs else float("nan"),
                "worst_m": worst,
                "ratio_worst_to_unstressed": worst / base_mean if errs and base_mean > 0 else float("nan"),
                "passes": bool(complete and worst <= tolerance * base_mean) if v != BASELINE else None,
                "time_offset_applied_s": [float(o.get("applied_s", 0.0)) for o in offsets],
                "time_offset_identified": [bool(o.get("identified", False)) for o in offsets],
                "wall_time_s": float(np.mean([m["wall_time_s"] for _, m in per_seed if m is not None])) if errs else float("nan"),
            }
        )
    return rows


def _write_tables(
    root: Path,
    rows: list[dict[str, Any]],
    fixed: dict[str, Any],
    errors: dict[str, str],
    relations: bool,
    tolerance: float,
) -> dict[str, Path]:
    metric = "relations mean translational error" if relations else "position RMSE against the reference"
    lines = [
        f"# Stress variants of {fixed['log']}",
        "",
        f"Error: {metric} (m), per seed. Pass: every seed at most {tolerance:g} x the unstressed mean.",
        "",
        "| variant | errors per seed [m] | mean [m] | worst / unstressed mean | pass | time offset applied [s] | wall time [s] |",
        "|---|---|---|---|---|---|---|",
    ]
    for r in rows:
        errs = " / ".join(f"{e:.4f}" for e in r["errors_m"]) or "-"
        passes = "-" if r["passes"] is None else ("yes" if r["passes"] else "no")
        offsets = " / ".join(
            f"{a:+.3f}" if ok else f"{a:+.3f} (not identified)"
            for a, ok in zip(r["time_offset_applied_s"], r["time_offset_identified"], strict=True)
        )
        ratio = "-" if np.isnan(r["ratio_worst_to_unstressed"]) else f"{r['ratio_worst_to_unstressed']:.2f}"
        mean = "-" if np.isnan(r["mean_m"]) else f"{r['mean_m']:.4f}"
        wall = "-" if np.isnan(r["wall_time_s"]) else f"{r['wall_time_s']:.0f}"
        lines.append(f"| {r['variant']} | {errs} | {mean} | {ratio} | {passes} | {offsets or '-'} | {wall} |")
    if errors:
        lines += ["", f"Failed runs: {', '.join(sorted(errors))}."]
    files = {"table": root / "table.md", "csv": root / "table.csv", "json": root / "results.json"}
    files["table"].write_text("\n".join(lines) + "\n")
    with open(files["csv"], "w", newline="") as fh:
        w = csv.writer(fh)
        w.writerow(["variant", "seed", "error_m", "time_offset_applied_s", "time_offset_identified"])
        for r in rows:
            for k, e in enumerate(r["errors_m"]):
                w.writerow([r["variant"], k, f"{e:.6f}", r["time_offset_applied_s"][k], r["time_offset_identified"][k]])
    results = {"settings": fixed, "tolerance": tolerance, "rows": rows, "errors": errors}
    files["json"].write_text(json.dumps(results, indent=2, sort_keys=True, default=float) + "\n")
    return files
