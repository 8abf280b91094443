"""table.md of results/corridor from the run folders of run_all.sh.

    python results/corridor/collect.py RUNS OUT

Two measures per run against the simulator's ground truth: the position RMSE after the best
rigid fit (SE(2)), and the scale error along the corridor: over windows of 100 scans, the
distance the estimate moves forward (in the frame of the window's first pose) minus the
distance the robot moved, summed and divided by the distance the robot moved. A filter that
is pulled back towards the part of the corridor it has mapped comes out short (negative).
"""

from __future__ import annotations

import json
import statistics
import sys
from pathlib import Path

import numpy as np

from crlam.eval.trajectory import reference_errors
from crlam.io.tum import read_tum
from crlam.pose import between

SETTINGS = {
    "odometry": "the simulated odometry",
    "default": "`robust` preset (the default: `--degeneracy remap`)",
    "off": "`--degeneracy off` (the scan read in every direction)",
    "posterior": "`--degeneracy off --match-climb posterior`",
    "endpoint-weight": "`--degeneracy off --scan-match-weight endpoint` (GMapping's weight instead of the CRM likelihood)",
    "posterior-endpoint-weight": "`--degeneracy off --match-climb posterior --scan-match-weight endpoint`",
    "ogm-gmapping": "RBPF-OGM in GMapping's setting",
}
WINDOW = 100


def rmse_and_scale(estimate: Path, truth: Path) -> tuple[float, float]:
    est, ref = read_tum(estimate), read_tum(truth)
    r = reference_errors(est.timestamps, est.poses, ref.timestamps, ref.poses, align="se2")
    rmse = float(np.sqrt(np.mean(np.sum(r.errors[:, :2] ** 2, axis=1))))
    e, g = est.poses, ref.poses
    n = min(len(e), len(g))
    moved = [between(g[k], g[k + WINDOW])[0] for k in range(0, n - WINDOW, WINDOW)]
    seen = [between(e[k], e[k + WINDOW])[0] for k in range(0, n - WINDOW, WINDOW)]
    scale = (sum(seen) - sum(moved)) / sum(abs(m) for m in moved)
    return rmse, scale


def main(runs: Path, out: Path) -> None:
    lines = [
        "Position RMSE (m, after the best rigid fit) and scale error along the corridor (%) against the ground",
        "truth, weighted-mean trajectory; logs 0 and 1, filter seeds 0 / 1 (seed 0 only where one value is given).",
        "",
        "| setting | log 0 RMSE | log 1 RMSE | mean RMSE | scale error, log 0 | scale error, log 1 | wall time per run [s] |",
        "|---|---|---|---|---|---|---|",
    ]
    for name, title in SETTINGS.items():
        rmse_cells, scale_cells, errs, times = [], [], [], []
        for log in (0, 1):
            truth = runs / f"log-{log}" / "groundtruth.tum"
            found = []
            if name == "odometry":
                found.append(rmse_and_scale(runs / f"log-{log}" / "odometry.tum", truth))
            else:
                for seed in (0, 1):
                    run = runs / f"{name}-log{log}-seed{seed}"
                    if (run / "COMPLETE").is_file():
                        found.append(rmse_and_scale(run / "trajectory.tum", truth))
                        times.append(json.loads((run / "metrics.json").read_text())["wall_time_s"])
            errs += [f[0] for f in found]
            rmse_cells.append(" / ".join(f"{f[0]:.2f}" for f in found) or "-")
            scale_cells.append(" / ".join(f"{100 * f[1]:+.1f}" for f in found) or "-")
        if errs:
            time = f"{statistics.mean(times):.0f}" if times else "-"
            lines.append(
                f"| {title} | {rmse_cells[0]} | {rmse_cells[1]} | {statistics.mean(errs):.2f} | "
                f"{scale_cells[0]} | {scale_cells[1]} | {time} |"
            )
    (out / "table.md").write_text("\n".join(lines) + "\n")
    print("\n".join(lines))


if __name__ == "__main__":
    main(Path(sys.argv[1]), Path(sys.argv[2]))
