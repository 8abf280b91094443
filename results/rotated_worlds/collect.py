"""table.md of results/rotated_worlds from the run folders of run_all.sh.

    python results/rotated_worlds/collect.py RUNS OUT
"""

from __future__ import annotations

import json
import statistics
import sys
from pathlib import Path

SETTINGS = {
    "default": "`robust` preset with `--degeneracy off` (the grid turned onto the first scan's walls)",
    "no-alignment": "`--grid-alignment none` (the first pose's frame)",
    "sub-cell-unaligned": "`--grid-alignment none --sub-cell unaligned` (there: chord causes and hit means)",
    "hit-means": "`--grid-alignment none --hit-means`",
    "chord": "`--grid-alignment none --cause-kernel chord`",
    "sub-cell-on": "`--sub-cell on` (the grid on the walls, chord causes and hit means)",
    "match": "`--grid-alignment none --proposal-pose match`",
    "gmapping-lattice": "`--grid-alignment none --lattice-step 0.01 0.005`",
    "range20": "`--grid-alignment none --max-range 20`",
    "cell005": "`--grid-alignment none --resolution 0.05`",
    "ogm-gmapping": "RBPF-OGM in GMapping's setting",
    "remap-no-alignment": "`--grid-alignment none` with the default's `--degeneracy remap`",
}
LOGS = ("museum-0", "museum-1", "office-0", "office-1")


def main(runs: Path, out: Path) -> None:
    lines = [
        "Position RMSE (m) against the ground truth, weighted-mean trajectory; one column per log, the seeds of the filter",
        "separated by '/'.",
        "",
        "| setting | " + " | ".join(LOGS) + " | mean | median | wall time per run [s] |",
        "|---|" + "---|" * (len(LOGS) + 3),
    ]
    for name, title in SETTINGS.items():
        cells, errs, times = [], [], []
        for log in LOGS:
            found = []
            for seed in (0, 1):
                m = runs / f"{name}-{log}-seed{seed}" / "metrics.json"
                if m.is_file():
                    d = json.loads(m.read_text())
                    found.append(d["reference"]["rmse_position_m"])
                    times.append(d["wall_time_s"])
            errs += found
            cells.append(" / ".join(f"{e:.3f}" for e in found) or "-")
        if errs:
            lines.append(
                f"| {title} | " + " | ".join(cells) + f" | {statistics.mean(errs):.3f} | {statistics.median(errs):.3f} | "
                f"{statistics.mean(times):.0f} |"
            )
    (out / "table.md").write_text("\n".join(lines) + "\n")
    print("\n".join(lines))


if __name__ == "__main__":
    main(Path(sys.argv[1]), Path(sys.argv[2]))
