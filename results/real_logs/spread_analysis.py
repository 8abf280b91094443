"""Relations errors of a run's trajectories split by the particle set's spread.

Usage: ``python spread_analysis.py RUN_DIR RELATIONS [--bins 4]``

RUN_DIR is a ``crlam slam`` / ``crlam experiment real-logs`` run folder written on or after
2026-11-26 (it has ``steps.csv`` and ``trajectory_max_weight.tum``). Each relation gets the
larger of the position spreads recorded at the last processed scan at or before its two stamps;
the relations are split into quantile bins of that spread, and each bin reports the mean
translational error of the weighted mean, the final best particle's path and the online
highest-weight particle. If the weighted mean loses to one lineage only where the set is wide,
its extra error comes from averaging poses of lineages whose maps disagree.
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
    "best path": "trajectory_best_path.tum",
    "max weight": "trajectory_max_weight.tum",
}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("run_dir", type=Path)
    ap.add_argument("relations", type=Path)
    ap.add_argument("--bins", type=int, default=4)
    args = ap.parse_args()
    steps = np.genfromtxt(args.run_dir / "steps.csv", delimiter=",", names=True)
    rels = read_relations(args.relations)
    errs = {}
    for name, file in TRAJECTORIES.items():
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
    print("| spread at the relation [m] | relations | " + " | ".join(TRAJECTORIES) + " |")
    print("|---|---|" + "---|" * len(TRAJECTORIES))
    for r in rows:
        lo, hi = r["spread_m"]
        print(f"| {lo:.3f}-{hi:.3f} | {r['n']} | " + " | ".join(f"{r[k]:.4f}" for k in TRAJECTORIES) + " |")
    print("| all | " + str(first.n) + " | " + " | ".join(f"{summary['all'][k]:.4f}" for k in TRAJECTORIES) + " |")
    (args.run_dir / "spread_analysis.json").write_text(json.dumps(summary, indent=2) + "\n")


if __name__ == "__main__":
    main()
