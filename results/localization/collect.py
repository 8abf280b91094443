"""Tables, settings and figures of results/localization from the run folders of ``run_all.sh``.

    python results/localization/collect.py RUNS OUT [--data DATA]

Reads RUNS/{intel-loc, intel-trials, tb4-global, aces-whole-sS, aces-first-sS, aces-cont-sS} and
writes into OUT: ``table.md`` (every figure of the README), ``config.toml`` (the settings of every
run, from their own ``config.toml``), ``metrics/*.json`` (the runs' ``metrics.json``) and the
figures (copied from the run folders, or drawn here: ``aces_continue.png``).
"""

from __future__ import annotations

import argparse
import hashlib
import json
import math
import shutil
import tomllib
from pathlib import Path
from typing import Any

import numpy as np
import tomli_w

from crlam.eval.trajectory import relations_error
from crlam.io.relations import read_relations
from crlam.io.tum import read_tum

SEEDS = tuple(range(12))


def mann_whitney(a: list[float], b: list[float]) -> tuple[float, float]:
    """Mann-Whitney U of ``a`` against ``b`` and its exact two-sided p-value (no ties assumed: the
    errors are continuous). The null distribution of U counts the orderings of the pooled sample,
    by the recursion c(m, n, u) = c(m - 1, n, u - n) + c(m, n - 1, u)."""
    m, n = len(a), len(b)
    u = sum(1.0 if x > y else 0.5 if x == y else 0.0 for x in a for y in b)
    counts: dict[tuple[int, int], list[int]] = {}

    def dist(i: int, j: int) -> list[int]:
        if i == 0 or j == 0:
            return [1]
        if (i, j) not in counts:
            c = [0] * (i * j + 1)
            for k, v in enumerate(dist(i - 1, j)):
                c[k + j] += v
            for k, v in enumerate(dist(i, j - 1)):
                c[k] += v
            counts[(i, j)] = c
        return counts[(i, j)]

    c = dist(m, n)
    total = sum(c)
    low = min(u, m * n - u)
    tail = sum(v for k, v in enumerate(c) if k <= low) / total
    return u, min(1.0, 2.0 * tail)


def _json(p: Path) -> dict[str, Any]:
    return json.loads(p.read_text())


def _untouched(runs: Path, name: str) -> bool | None:
    """Whether every file of RUNS/name still has the SHA-256 recorded before the continued run."""
    sums = runs / f"{name}.sha256"
    if not sums.is_file():
        return None
    for line in sums.read_text().splitlines():
        digest, rel = line.split(maxsplit=1)
        f = runs / name / rel.lstrip("*")
        if not f.is_file() or hashlib.sha256(f.read_bytes()).hexdigest() != digest:
            return False
    return True


def _rel(m: dict[str, Any]) -> str:
    return f"{m['trans_mean_m']:.4f} ± {m['trans_std_m']:.4f} m, {m['rot_mean_deg']:.2f} ± {m['rot_std_deg']:.2f} deg"


def _outliers(loc: Path, data: Path) -> list[str]:
    """The relations whose error exceeds 1 m, the scan they share, and the metric without them."""
    import collections

    t = read_tum(loc / "trajectory.tum")
    rels = read_relations(data / "intel" / "intel.relations")
    tr = np.asarray(relations_error(t.timestamps, t.poses, rels).trans)
    bad = np.nonzero(tr > 1.0)[0]
    if bad.size == 0:
        return [f"Median {np.median(tr):.4f} m; no relation has an error above 1 m.", ""]
    index = {float(s): i for i, s in enumerate(t.timestamps)}
    ends = collections.Counter(index.get(float(s), -1) for i in bad for s in (rels.t1[i], rels.t2[i]))
    scan, count = ends.most_common(1)[0]
    ok = tr[tr <= 1.0]
    return [
        f"Median {np.median(tr):.4f} m. {bad.size} relations have errors above 1 m ({tr[bad].min():.2f}-{tr[bad].max():.2f} m); "
        f"{count} of them have scan {scan} as one end. Without them: {ok.mean():.4f} ± {np.std(ok, ddof=1):.4f} m "
        f"(n = {ok.size}).",
        "",
    ]


def intel(runs: Path, out: Path, lines: list[str], settings: dict[str, Any], data: Path) -> None:
    loc = runs / "intel-loc"
    if not (loc / "metrics.json").is_file():
        return
    m = _json(loc / "metrics.json")
    r = m["relations"]
    lines += [
        "### Intel: the raw log localized on the map of the corrected log",
        "",
        "| trajectory | relations error (translation) | rotation | n | target |",
        "|---|---|---|---|---|",
        f"| `crlam localize`, every scan, from the known start | **{r['trans_mean_m']:.4f} ± {r['trans_std_m']:.4f} m** | "
        f"{r['rot_mean_deg']:.2f} ± {r['rot_std_deg']:.2f} deg | {r['n']} | <= 0.035 m: "
        f"{'met' if r['trans_mean_m'] <= 0.035 else 'not met'} |",
        "| GMapping-corrected log + odometry fill (data README) | 0.0424 ± 0.0367 m | 1.92 ± 1.67 deg | 2984 | |",
        "",
        f"{m['n_scans']} scans ({m['n_processed']} processed), {m['distance_m']:.0f} m travelled; particles per processed "
        f"scan mean {m['particles']['mean']:.0f}, max {m['particles']['max']:.0f}; {m['n_injected']} random particles "
        f"injected by recovery; wall {m['wall_time_s']:.0f} s, CPU {m['cpu_time_s']:.0f} s "
        f"({m['n_scans'] / m['cpu_time_s']:.1f} scans per CPU second; the log: "
        f"{m['n_scans'] / m['log_duration_s']:.1f} scans/s); peak RSS {m['peak_rss_mb']:.0f} MB. Endpoints within 0.1 m "
        f"of an occupied cell: {m['endpoints_within_0.1m']['all']:.3f}.",
        "",
    ]
    lines += _outliers(loc, data)
    shutil.copy(loc / "localization.png", out / "intel_localization.png")
    shutil.copy(loc / "metrics.json", out / "metrics" / "intel_loc.json")
    settings["intel_map"] = {"command": "crlam map", "resolution": 0.05, "max_range": 20.0}
    settings["intel_loc"] = tomllib.loads((loc / "config.toml").read_text())
    tr = runs / "intel-trials"
    if (tr / "metrics.json").is_file():
        t = _json(tr / "metrics.json")
        d = t["distance_m"]
        lines += [
            "### Intel: global localization from 20 random start times",
            "",
            "| trials | converged | converged to the reference pose | within 10 m of travel | target |",
            "|---|---|---|---|---|",
            f"| {t['n_trials']} | {t['n_converged']} | {t['n_converged_correct']} | **{t['n_within_target']} "
            f"({100 * t['fraction_within_target']:.0f} %)** | >= 95 %: "
            f"{'met' if t['fraction_within_target'] >= 0.95 else 'not met'} |",
            "",
            f"Distance travelled until convergence (correct trials): median {d.get('median', math.nan):.2f} m, "
            f"mean {d.get('mean', math.nan):.2f} m, max {d.get('max', math.nan):.2f} m; time: median "
            f"{t['time_s'].get('median', math.nan):.1f} s. Correct: {t['correct_rule']} (the reference is the run from the "
            "known start above).",
            "",
        ]
        shutil.copy(tr / "trials.png", out / "intel_trials.png")
        shutil.copy(tr / "trials.csv", out / "intel_trials.csv")
        shutil.copy(tr / "metrics.json", out / "metrics" / "intel_trials.json")
        settings["intel_trials"] = {k: t[k] for k in ("n_trials", "max_travel_m", "target_travel_m", "trial_seed")}


def tb4(runs: Path, out: Path, lines: list[str], settings: dict[str, Any]) -> None:
    run = runs / "tb4-global"
    if not (run / "metrics.json").is_file():
        return
    m = _json(run / "metrics.json")
    c, ep = m["convergence"], m["endpoints_within_0.1m"]
    conv = (
        "did not converge"
        if c is None
        else f"converged at scan {c['scan_index']}, {c['time_s']:.1f} s and {c['distance_m']:.2f} m after the start"
    )

    def share(v: float | None) -> str:
        return "-" if v is None else f"{v:.3f}"

    lines += [
        "### TurtleBot 4 bag on its floor map, no initial pose",
        "",
        "| convergence | endpoints within 0.1 m of an occupied cell: before | after | all |",
        "|---|---|---|---|",
        f"| {conv} | {share(ep['before_convergence'])} | **{share(ep['after_convergence'])}** | {share(ep['all'])} |",
        "",
        f"{m['n_scans']} scans ({m['n_processed']} processed), {m['distance_m']:.1f} m travelled; particles per processed "
        f"scan mean {m['particles']['mean']:.0f}, max {m['particles']['max']:.0f}; wall {m['wall_time_s']:.0f} s, CPU "
        f"{m['cpu_time_s']:.0f} s. The map as a CRM prior (mean ± standard deviation of each class's occupancy): "
        + ", ".join(f"{k} {v['mean']:.2f} ± {v['std']:.3f}" for k, v in m["map"].get("confidence", {}).items())
        + ".",
        "",
    ]
    shutil.copy(run / "localization.png", out / "tb4_global.png")
    shutil.copy(run / "metrics.json", out / "metrics" / "tb4_global.json")
    settings["tb4_global"] = tomllib.loads((run / "config.toml").read_text())


def aces(runs: Path, out: Path, lines: list[str], settings: dict[str, Any], data: Path) -> None:
    rels = read_relations(data / "aces" / "aces.relations")
    rows, whole_t, cont_t = [], [], []
    for s in SEEDS:
        whole, first, cont = (runs / f"aces-{k}-s{s}" for k in ("whole", "first", "cont"))
        if not all((p / "metrics.json").is_file() for p in (whole, first, cont)):
            continue
        w = _json(whole / "metrics.json")["relations"]
        a, b = read_tum(first / "trajectory.tum"), read_tum(cont / "trajectory.tum")
        stamps = np.concatenate([a.timestamps, b.timestamps])
        poses = np.concatenate([a.poses, b.poses])
        c = relations_error(stamps, poses, rels).summary()
        untouched = _untouched(runs, f"aces-first-s{s}")
        rows.append(
            f"| {s} | {w['trans_mean_m']:.4f} ± {w['trans_std_m']:.4f} m | {c['trans_mean_m']:.4f} ± {c['trans_std_m']:.4f} m "
            f"| {w['rot_mean_deg']:.2f} / {c['rot_mean_deg']:.2f} deg | "
            f"{'yes (SHA-256 of every file)' if untouched else ('not checked' if untouched is None else 'NO')} |"
        )
        whole_t.append(w["trans_mean_m"])
        cont_t.append(c["trans_mean_m"])
        shutil.copy(cont / "metrics.json", out / "metrics" / f"aces_cont_s{s}.json")
        shutil.copy(whole / "metrics.json", out / "metrics" / f"aces_whole_s{s}.json")
        if s == 0:
            settings["aces_slam"] = tomllib.loads((whole / "config.toml").read_text())
            _aces_figure(out / "aces_continue.png", a, b, read_tum(whole / "trajectory.tum"), first)
    if not rows:
        return
    u, p = mann_whitney(cont_t, whole_t)
    lines += [
        "### ACES: mapping the first half, then continuing with the second",
        "",
        "| seed | one run over the whole log | first half + `--continue` second half | rotation (whole / continued) "
        "| first folder untouched |",
        "|---|---|---|---|---|",
        *rows,
        "",
        f"Over {len(rows)} seeds: whole log mean {np.mean(whole_t):.4f} m, median {np.median(whole_t):.4f} m; continued mean "
        f"{np.mean(cont_t):.4f} m, median {np.median(cont_t):.4f} m. Spread of the whole-log runs over the seeds (the "
        f"filter's noise): {np.min(whole_t):.4f} - {np.max(whole_t):.4f} m; continued runs within it: "
        f"{sum(np.min(whole_t) <= c <= np.max(whole_t) for c in cont_t)} of {len(cont_t)}. Mann-Whitney U of continued "
        f"against whole = {u:.0f}, exact two-sided p = {p:.2f}.",
        "",
    ]


def _aces_figure(path: Path, first: Any, cont: Any, whole: Any, first_dir: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(7, 6.5), layout="constrained")
    ax.plot(whole.poses[:, 0], whole.poses[:, 1], color="0.6", lw=2.5, label="one run over the whole log")
    ax.plot(first.poses[:, 0], first.poses[:, 1], color="tab:blue", lw=1, label="first half")
    ax.plot(cont.poses[:, 0], cont.poses[:, 1], color="tab:orange", lw=1, label="second half, --continue")
    ax.plot(*cont.poses[0, :2], "ko", ms=5, label="where the second half starts")
    ax.set_aspect("equal")
    ax.set_xlabel("x [m]")
    ax.set_ylabel("y [m]")
    ax.set_title("ACES, seed 0: estimates of the continued run and of one run")
    ax.legend(loc="best", fontsize=8)
    fig.savefig(path, dpi=110)
    plt.close(fig)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("runs", type=Path)
    ap.add_argument("out", type=Path)
    ap.add_argument("--data", type=Path, default=Path("../shared/data"))
    a = ap.parse_args()
    (a.out / "metrics").mkdir(parents=True, exist_ok=True)
    lines = ["<!-- generated by results/localization/collect.py from the run folders; see README.md -->", ""]
    settings: dict[str, Any] = {}
    intel(a.runs, a.out, lines, settings, a.data)
    tb4(a.runs, a.out, lines, settings)
    aces(a.runs, a.out, lines, settings, a.data)
    (a.out / "table.md").write_text("\n".join(lines))
    (a.out / "config.toml").write_text(
        "# Settings of every run of results/localization, copied from the runs' own config.toml.\n"
        + tomli_w.dumps(_no_none(settings))
    )
    print("\n".join(lines))


def _no_none(v: Any) -> Any:
    if isinstance(v, dict):
        return {k: _no_none(x) for k, x in v.items() if x is not None}
    if isinstance(v, list):
        return [_no_none(x) for x in v if x is not None]
    return v


if __name__ == "__main__":
    main()
