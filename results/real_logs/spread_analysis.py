"""Relations errors of a run's trajectories split by the particle set's spread.

Usage: ``python spread_analysis.py RUN_DIR RELATIONS [--bins 4] [--window 300]``

RUN_DIR is a ``crlam slam`` / ``crlam experiment real-logs`` run folder (``steps.csv`` and the
trajectories under ``estimates/``). Each relation gets the
larger of the position spreads recorded at the last processed scan at or before its two stamps;
the relations are split into quantile bins of that spread, and each bin reports the mean
translational error of the weighted mean, the final best particle's path and the online
highest-weight particle (and the mode-seeking estimate ``estimates/mode.tum`` and the lineage
smoother ``estimates/smoothed[_means].tum``, where the run wrote them). If the weighted mean loses to one lineage only where the set is wide,
its extra error comes from averaging poses of lineages whose maps disagree.

A second table splits the same relations by the time of their first pose into windows of
``--window`` seconds from the log's start, with each window's mean spread and the share of its
processed scans that revisit ground (the final best path passes within 1 m of a pose it held at
least 60 s earlier): where in the log the trajectories differ, and whether that is new ground.
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path
from typing import Any

import numpy as np

from crlam.eval.trajectory import relations_error
from crlam.io.relations import read_relations
from crlam.io.tum import read_tum

TRAJECTORIES = {
    "weighted mean": "trajectory.tum",
    "best path": "estimates/best_path.tum",
    "best path means": "estimates/best_path_means.tum",
    "max weight": "estimates/max_weight.tum",
    "mode": "estimates/mode.tum",
    "smoothed": "estimates/smoothed.tum",
    "smoothed means": "estimates/smoothed_means.tum",
}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("run_dir", type=Path)
    ap.add_argument("relations", type=Path)
    ap.add_argument("--bins", type=int, default=4)
    ap.add_argument("--window", type=float, default=300.0, help="seconds per time window (default: 300)")
    args = ap.parse_args()
    steps = np.genfromtxt(args.run_dir / "steps.csv", delimiter=",", names=True)
    rels = read_relations(args.relations)
    errs = {}
    names = [n for n, f in TRAJECTORIES.items() if (args.run_dir / f).is_file()]
    for name in names:
        file = TRAJECTORIES[name]
        traj = read_tum(args.run_dir / file)
        errs[name] = relations_error(traj.timestamps, traj.poses, rels)
    stamps = read_tum(args.run_dir / "trajectory.tum").timestamps
    first = next(iter(errs.values()))
    # The processed step in force at a stamp: the last one whose scan index is at or before it.
    scan_of = np.searchsorted(stamps, np.stack([first.t1, first.t2]), side="right") - 1
    step_of = np.searchsorted(steps["scan_index"], scan_of, side="right") - 1
    spread = np.max(steps["spread_xy_m"][np.clip(step_of, 0, None)], axis=0)
    edges = np.quantile(spread, np.linspace(0, 1, args.bins + 1))
    which = np.clip(np.searchsorted(edges, spread, side="right") - 1, 0, args.bins - 1)
    rows: list[dict[str, Any]] = []
    for b in range(args.bins):
        sel = which == b
        rows.append(
            {
                "spread_m": [float(edges[b]), float(edges[b + 1])],
                "n": int(sel.sum()),
                **{name: float(e.trans[sel].mean()) for name, e in errs.items()},
            }
        )
    summary: dict[str, Any] = {"all": {name: float(e.trans.mean()) for name, e in errs.items()}, "bins": rows}
    print("| spread at the relation [m] | relations | " + " | ".join(names) + " |")
    print("|---|---|" + "---|" * len(names))
    for r in rows:
        lo, hi = r["spread_m"]
        print(f"| {lo:.3f}-{hi:.3f} | {r['n']} | " + " | ".join(f"{r[k]:.4f}" for k in names) + " |")
    print("| all | " + str(first.n) + " | " + " | ".join(f"{summary['all'][k]:.4f}" for k in names) + " |")
    summary["windows"] = _time_windows(args, steps, stamps, first.t1, errs, names)
    (args.run_dir / "spread_analysis.json").write_text(json.dumps(summary, indent=2) + "\n")


def _revisits(t: np.ndarray, xy: np.ndarray, radius: float = 1.0, age: float = 60.0) -> np.ndarray:
    """Whether each pose lies within ``radius`` m of a pose held at least ``age`` s earlier."""
    out = np.zeros(len(t), dtype=bool)
    for k in range(len(t)):
        old = t < t[k] - age
        if old.any():
            out[k] = bool(np.min(np.hypot(*(xy[old] - xy[k]).T)) < radius)
    return out


def _time_windows(
    args: argparse.Namespace, steps: np.ndarray, stamps: np.ndarray, t1: np.ndarray, errs: dict[str, Any], names: list[str]
) -> list[dict[str, Any]]:
    path = read_tum(args.run_dir / "estimates/best_path.tum")
    idx = steps["scan_index"].astype(int)
    t_step = stamps[idx] - stamps[0]
    revisit = _revisits(t_step, path.poses[idx, :2])
    rel_t = t1 - stamps[0]
    rows = []
    print()
    print("| first pose at [s] | relations | mean spread [m] | revisited | " + " | ".join(names) + " |")
    print("|---|---|---|---|" + "---|" * len(names))
    for lo in np.arange(0.0, float(t_step.max()) + 1e-9, args.window):
        sel = (rel_t >= lo) & (rel_t < lo + args.window)
        at = (t_step >= lo) & (t_step < lo + args.window)
        if not sel.any() or not at.any():
            continue
        row = {
            "t_s": [float(lo), float(lo + args.window)],
            "n": int(sel.sum()),
            "spread_xy_mean_m": float(steps["spread_xy_m"][at].mean()),
            "revisited": float(revisit[at].mean()),
            **{name: float(errs[name].trans[sel].mean()) for name in names},
        }
        rows.append(row)
        print(
            f"| {lo:.0f}-{lo + args.window:.0f} | {row['n']} | {row['spread_xy_mean_m']:.3f} | {row['revisited']:.2f} | "
            + " | ".join(f"{row[k]:.4f}" for k in names)
            + " |"
        )
    return rows


if __name__ == "__main__":
    main()
