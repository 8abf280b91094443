"""``crlam experiment iig``: the offline comparison of information functions with IIG (paper Sec. V.B).

Every (function, seed) run plans a tree on the same prior map from the same start; seeds are
shared across functions (the only randomness is SampleFree, plus UCRMI's particles). Each run
writes ``runs/<function>-sNN/tree.npz`` and then ``result.json`` (last, atomically): rerunning
the command skips finished runs. The experiment folder gets ``runs.csv``, the figures (Fig. 3
trees, Fig. 4 box plots, Fig. 5 RIC and gain curves) and ``report.md``, which checks the paper's
six qualitative claims (planner-spec 7.3) against the measured numbers.
"""

from __future__ import annotations

import csv
import json
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from crlam.errors import ConfigError, CrlamError
from crlam.experiments.executor import Executor, RunLayout
from crlam.experiments.pool import run_jobs, write_atomic
from crlam.experiments.resume import close_experiment, input_digest, load_json_dict, open_experiment
from crlam.info import InformationFunction, load_map_prior, make_function
from crlam.io.run_folder import staged_folder
from crlam.planner import IigSettings, IigTree, check_start, plan_iig

__all__ = ["FUNCTIONS", "LABELS", "IigExperiment", "function_for", "run_iig_experiment", "run_one"]

FUNCTIONS = ("ogmi", "crmi", "ucrmi", "gpvr", "ugpvr")
LABELS = {"ogmi": "OGMI", "crmi": "CRMI", "ucrmi": "UCRMI", "gpvr": "GPVR", "ugpvr": "UGPVR"}
OGMI_IMPLEMENTATIONS = {"fsmi": "fsmi", "iig_mi": "iig_mi", "julian": "ogmi"}
#: A planner run reads the map and writes ``tree.npz``, then ``result.json``.
IIG_RUN_LAYOUT = RunLayout(inputs=("map_path",))


def function_for(name: str, *, mode: str, ogmi: str = "fsmi", particles: int = 100) -> InformationFunction:
    """The information function of an experiment column. ``ogmi`` picks what "OGMI" means:
    exact FSMI (default), the IIG reference 'mi' heuristic or Julian's integration."""
    if name not in FUNCTIONS:
        raise ConfigError(f"unknown function {name!r}; expected one of {', '.join(FUNCTIONS)}")
    if name == "ogmi":
        if ogmi not in OGMI_IMPLEMENTATIONS:
            raise ConfigError(f"--ogmi must be one of {', '.join(OGMI_IMPLEMENTATIONS)}, got {ogmi!r}")
        return make_function(OGMI_IMPLEMENTATIONS[ogmi], mode=mode)
    if name == "ucrmi":
        return make_function(name, mode=mode, n_particles=particles)
    return make_function(name, mode=mode)


def _folder(out: Path, name: str) -> Path:
    return out / "runs" / name


def run_one(
    map_path: str,
    function: str,
    seed: int,
    mode: str,
    ogmi: str,
    particles: int,
    max_wall_seconds: float,
    start: tuple[float, float],
    folder: str,
) -> dict[str, Any]:
    """One planner run; writes ``tree.npz`` and then ``result.json`` into ``folder``."""
    prior = load_map_prior(map_path)
    f = function_for(function, mode=mode, ogmi=ogmi, particles=particles)
    settings = IigSettings(mode=mode, start=(float(start[0]), float(start[1])), max_wall_seconds=max_wall_seconds)
    tree = plan_iig(f, prior, settings, seed=seed)
    row = {**tree.summary(), "function": function, "implementation": f.name}
    # Staged: the run's folder appears (replacing an older, unfinished or corrupt one) only whole.
    with staged_folder(folder, command=f"crlam experiment iig ({function}, seed {seed})") as d:
        tree.save(d / "tree.npz")
        write_atomic(d / "result.json", json.dumps(row, indent=2, sort_keys=True) + "\n")
    return row


@dataclass(frozen=True)
class IigExperiment:
    """What a finished experiment produced."""

    out: Path
    rows: list[dict[str, Any]]
    errors: dict[str, str]
    files: dict[str, Path]


def run_iig_experiment(
    map_path: str | Path | None,
    out: str | Path,
    *,
    functions: Sequence[str] = FUNCTIONS,
    runs: int = 20,
    mode: str = "reference",
    ogmi: str = "fsmi",
    particles: int = 100,
    workers: int = 2,
    max_wall_seconds: float = 600.0,
    start: tuple[float, float] = (10.0, 2.0),
    progress: bool = True,
    executor: Executor | None = None,
    resume: bool = True,
    force: bool = False,
    verbose: bool = False,
) -> IigExperiment:
    """Runs (resuming) the comparison and writes ``runs.csv``, the figures and ``report.md``.
    ``executor``: where the runs go (default: ``workers`` local processes).

    An existing ``out`` is resumed (``resume``; its runs must have been made on the same map, by
    its content, with the same planner settings) or replaced (``force``); see
    :mod:`crlam.experiments.resume`. A run whose ``result.json`` or ``tree.npz`` cannot be read is
    run again."""
    if not functions:
        raise ConfigError("no information function given (e.g. --functions crmi ucrmi)")
    for name in functions:
        function_for(name, mode=mode, ogmi=ogmi, particles=particles)  # validate before any run
    if map_path is None:
        from crlam.io.fetch import find_dataset

        map_path = find_dataset("cave-map")
    map_path = str(Path(map_path).resolve())
    # A clean error for an unusable map or start before spawning workers.
    check_start(load_map_prior(map_path), (float(start[0]), float(start[1])))
    root = open_experiment(
        out,
        "iig",
        {
            "map_sha256": input_digest(map_path),
            "mode": mode,
            "ogmi": ogmi,
            "particles": particles,
            "max_wall_seconds": max_wall_seconds,
            "start": [float(start[0]), float(start[1])],
        },
        resume=resume,
        force=force,
    )
    jobs = [
        (
            f"{name}-s{seed:02d}",
            {
                "map_path": map_path,
                "function": name,
                "seed": seed,
                "mode": mode,
                "ogmi": ogmi,
                "particles": particles,
                "max_wall_seconds": max_wall_seconds,
                "start": (float(start[0]), float(start[1])),
                "folder": str(_folder(root, f"{name}-s{seed:02d}")),
            },
        )
        for name in functions
        for seed in range(runs)
    ]
    done, errors = run_jobs(
        jobs,
        run_one,
        lambda n: _finished_run(_folder(root, n)) is not None,
        lambda n: _finished_run(_folder(root, n)) or {},
        workers=workers,
        progress=progress,
        verbose=verbose,
        desc="planner runs",
        executor=executor,
        layout=IIG_RUN_LAYOUT,
    )
    rows = [done[n] for n, _ in jobs if n in done]
    files = {"runs": root / "runs.csv"}
    _write_csv(files["runs"], rows)
    if rows:
        from crlam.viz.iig import save_boxplots, save_ric_and_gain, save_trees

        prior = load_map_prior(map_path)
        first = {name: _folder(root, f"{name}-s00") / "tree.npz" for name in functions}
        trees = {name: IigTree.load(p) for name, p in first.items() if p.is_file()}
        files["fig3"] = save_trees(root / "fig3_trees.png", prior, trees, LABELS)
        files["fig4"] = save_boxplots(root / "fig4_boxplots.png", rows, functions, LABELS)
        files["fig5"] = save_ric_and_gain(root / "fig5_ric_gain.png", trees, LABELS)
    files["report"] = root / "report.md"
    files["report"].write_text(report_markdown(rows, functions, errors, mode=mode, ogmi=ogmi, map_path=map_path))
    close_experiment(root, n_runs=len(jobs), failed=errors)
    return IigExperiment(out=root, rows=rows, errors=errors, files=files)


def _finished_run(folder: Path) -> dict[str, Any] | None:
    """The result row of a finished run, or None when its files are missing or unreadable (the
    run is then done again)."""
    row = load_json_dict(folder / "result.json")
    if row is None or "function" not in row:
        return None
    try:
        IigTree.load(folder / "tree.npz")
    except (CrlamError, OSError):
        return None
    return row


def _write_csv(path: Path, rows: Sequence[dict[str, Any]]) -> None:
    keys = list(rows[0]) if rows else ["function", "seed"]
    with path.open("w", newline="") as fh:
        w = csv.DictWriter(fh, fieldnames=keys)
        w.writeheader()
        for r in rows:
            w.writerow(r)


def _stats(rows: Sequence[dict[str, Any]], function: str, key: str) -> tuple[float, float]:
    v = np.array([float(r.get(key, np.nan)) for r in rows if r["function"] == function])
    if v.size == 0:
        return float("nan"), float("nan")
    return float(v.mean()), float(v.std(ddof=1)) if v.size > 1 else 0.0


def claims(rows: Sequence[dict[str, Any]], functions: Sequence[str]) -> list[tuple[str, bool | None, str]]:
    """The paper's six qualitative claims (planner-spec 7.3) checked on the means over runs:
    (claim, holds (None if a function is missing), the numbers)."""
    keys = ("samples", "nodes", "total_cost_m", "planning_time_s", "mean_ric", "final_cum_ric", "total_info")
    m = {f: {k: _stats(rows, f, k)[0] for k in keys} for f in functions}
    for f in functions:
        m[f]["gain_per_node"] = m[f]["total_info"] / max(m[f]["nodes"] - 1, 1)
    have = set(m) & {f for f in functions if any(r["function"] == f for r in rows)}
    out: list[tuple[str, bool | None, str]] = []

    def need(*fs: str) -> bool:
        return all(f in have for f in fs)

    others = [f for f in ("ogmi", "crmi", "gpvr", "ugpvr") if f in have]
    if need("ucrmi") and others:
        ok = all(m["ucrmi"][k] >= m[f][k] for f in others for k in ("samples", "nodes", "total_cost_m"))
        nums = ", ".join(
            f"{LABELS[f]} {m[f]['samples']:.0f}/{m[f]['nodes']:.0f}/{m[f]['total_cost_m']:.0f} m" for f in ["ucrmi", *others]
        )
        out.append(
            ("1. UCRMI has the most samples and nodes and the largest total cost", ok, f"samples/nodes/total cost: {nums}")
        )
        # "Average I_RIC" is ambiguous (planner-spec Q4): the mean over nodes or the final
        # cumulative value of Fig. 5(a); the claim holds only if it holds under the reading named.
        mean_ok = all(m["ucrmi"]["mean_ric"] >= m[f]["mean_ric"] for f in others)
        cum_ok = all(m["ucrmi"]["final_cum_ric"] >= m[f]["final_cum_ric"] for f in others)
        nums = ", ".join(f"{LABELS[f]} {m[f]['mean_ric']:.4g} / {m[f]['final_cum_ric']:.1f}" for f in ["ucrmi", *others])
        verdict = (
            f"mean over nodes: {'holds' if mean_ok else 'does not hold'}; "
            f"final cumulative: {'holds' if cum_ok else 'does not hold'}"
        )
        out.append(
            ("2. UCRMI has the highest average penalized I_RIC", mean_ok, f"{verdict}; mean / final cumulative I_RIC: {nums}")
        )
    else:
        out.append(
            ("1. UCRMI has the most samples and nodes and the largest total cost", None, "needs UCRMI and another function")
        )
        out.append(("2. UCRMI has the highest average penalized I_RIC", None, "needs UCRMI and another function"))
    rough = [f for f in ("ogmi", "gpvr", "crmi") if f in have]
    if need("ucrmi") and rough:
        ok = all(m[f]["samples"] < m["ucrmi"]["samples"] and m[f]["nodes"] < m["ucrmi"]["nodes"] for f in rough)
        nums = ", ".join(f"{LABELS[f]} {m[f]['samples']:.0f}/{m[f]['nodes']:.0f}" for f in [*rough, "ucrmi"])
        out.append(("3. OGMI, GPVR and CRMI use fewer samples and nodes than UCRMI", ok, f"samples/nodes: {nums}"))
    else:
        out.append(("3. OGMI, GPVR and CRMI use fewer samples and nodes than UCRMI", None, "needs UCRMI and one of them"))
    if need("ugpvr", "ucrmi"):
        ok = (
            m["ugpvr"]["samples"] < m["ucrmi"]["samples"]
            and m["ugpvr"]["nodes"] < m["ucrmi"]["nodes"]
            and m["ugpvr"]["planning_time_s"] > m["ucrmi"]["planning_time_s"]
        )
        nums = (
            f"UGPVR {m['ugpvr']['samples']:.0f}/{m['ugpvr']['nodes']:.0f}/{m['ugpvr']['planning_time_s']:.2f} s, "
            f"UCRMI {m['ucrmi']['samples']:.0f}/{m['ucrmi']['nodes']:.0f}/{m['ucrmi']['planning_time_s']:.2f} s"
        )
        out.append(("4. UGPVR has fewer samples and nodes than UCRMI but more planning time", ok, f"samples/nodes/time: {nums}"))
    else:
        out.append(("4. UGPVR has fewer samples and nodes than UCRMI but more planning time", None, "needs UGPVR and UCRMI"))
    if need("ucrmi", "crmi"):
        ok = m["ucrmi"]["samples"] > m["crmi"]["samples"]
        nums = f"samples to convergence: UCRMI {m['ucrmi']['samples']:.0f}, CRMI {m['crmi']['samples']:.0f}"
        out.append(("5. UCRMI converges more slowly than CRMI", ok, nums))
        # Q4 again: the sum over the whole tree or the gain per node (the reference's plotted mean).
        sum_ok = m["ucrmi"]["total_info"] < m["crmi"]["total_info"]
        per_ok = m["ucrmi"]["gain_per_node"] < m["crmi"]["gain_per_node"]
        nums = (
            f"sum over nodes: {'holds' if sum_ok else 'does not hold'} (UCRMI {m['ucrmi']['total_info']:.1f}, "
            f"CRMI {m['crmi']['total_info']:.1f} bits); per node: {'holds' if per_ok else 'does not hold'} "
            f"(UCRMI {m['ucrmi']['gain_per_node']:.3f}, CRMI {m['crmi']['gain_per_node']:.3f} bits)"
        )
        out.append(("6. UCRMI has a lower total information gain than CRMI", sum_ok, nums))
    else:
        out.append(("5. UCRMI converges more slowly than CRMI", None, "needs UCRMI and CRMI"))
        out.append(("6. UCRMI has a lower total information gain than CRMI", None, "needs UCRMI and CRMI"))
    return out


def report_markdown(
    rows: Sequence[dict[str, Any]], functions: Sequence[str], errors: dict[str, str], *, mode: str, ogmi: str, map_path: str
) -> str:
    """The experiment's report: the summary table and the six claims with their numbers."""
    lines = [
        "# IIG comparison of information functions",
        "",
        f"Map: `{map_path}`; planner settings: **{mode}** mode (planner-spec 3, 7.1); "
        f"OGMI computed by **{OGMI_IMPLEMENTATIONS.get(ogmi, ogmi)}**. Mean ± std over runs; seeds shared across functions.",
        "",
        "| function | runs | units | planning time [s] | samples | nodes | total cost [m] | total info | mean I_RIC "
        "| converged |",
        "|---|---|---|---|---|---|---|---|---|---|",
    ]
    for f in functions:
        rs = [r for r in rows if r["function"] == f]
        if not rs:
            lines.append(f"| {LABELS[f]} | 0 | | | | | | | | |")
            continue

        def cell(key: str, fmt: str, rs: list[dict[str, Any]] = rs, f: str = f) -> str:
            mean, std = _stats(rows, f, key)
            return f"{mean:{fmt}} ± {std:{fmt}}"

        conv = sum(1 for r in rs if str(r["converged"]).lower() == "true")
        lines.append(
            f"| {LABELS[f]} | {len(rs)} | {rs[0]['units']} | {cell('planning_time_s', '.3f')} | {cell('samples', '.0f')} | "
            f"{cell('nodes', '.0f')} | {cell('total_cost_m', '.1f')} | {cell('total_info', '.1f')} | "
            f"{cell('mean_ric', '.4f')} | {conv}/{len(rs)} |"
        )
    lines += ["", "## The paper's qualitative claims (planner-spec 7.3)", ""]
    for text, ok, nums in claims(rows, functions):
        verdict = "not checked" if ok is None else ("**holds**" if ok else "**does not hold**")
        lines.append(f"- {text}: {verdict} ({nums}).")
    if errors:
        lines += ["", "## Failed runs", ""]
        lines += [f"- `{n}`: {e.splitlines()[0]}" for n, e in sorted(errors.items())]
    lines += [
        "",
        "Figures: `fig3_trees.png` (seed 0: tree, main paths, most informative path, 90 % pose ellipses), "
        "`fig4_boxplots.png` (planning time and total cost over runs), `fig5_ric_gain.png` (cumulative penalized "
        "I_RIC against nodes; information gain per sample). Units differ between functions (bits for CRMI/UCRMI, "
        "nats for the others); RIC is unit-free.",
        "",
    ]
    return "\n".join(lines)
