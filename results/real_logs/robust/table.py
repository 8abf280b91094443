"""Compile ``table.md`` and ``table.csv`` of this folder from run folders (one row per run).

    python results/real_logs/robust/table.py results/real_logs/robust RUN [RUN ...]

Each RUN is a ``crlam slam`` run folder made with ``--relations`` (its ``metrics.json``); the
row is named after the folder. Runs named ``i_rob_sN`` / ``a_rob_sN`` (the default filter, seed N,
on Intel / ACES) are also summarized per log: mean, median and range of the weighted mean's error
over the seeds.
"""

from __future__ import annotations

import csv
import json
import re
import statistics
import sys
from pathlib import Path

COLUMNS = {
    "trans_mean_m": ("relations", "weighted mean [m]"),
    "trans_best_path_m": ("relations_best_path", "best path [m]"),
    "trans_best_path_means_m": ("relations_best_path_means", "best path, proposal means [m]"),
    "trans_mode_m": ("relations_mode", "mode-seeking [m]"),
    "trans_smoothed_m": ("relations_smoothed", "smoothed [m]"),
    "trans_smoothed_means_m": ("relations_smoothed_means", "smoothed, proposal means [m]"),
}


def row_of(run: Path) -> dict[str, object]:
    m = json.loads((run / "metrics.json").read_text())
    row: dict[str, object] = {
        "run": run.name,
        "dataset": "intel" if "intel" in m["log"] else "aces",
        "method": m["method"],
        "particles": m["particles"],
        "seed": m["seed"],
        "n_scans": m["n_scans"],
    }
    for name, (key, _) in COLUMNS.items():
        row[name] = (m.get(key) or {}).get("trans_mean_m", float("nan"))
    row["wall_time_s"] = m["wall_time_s"]
    row["peak_rss_mb"] = m["peak_rss_mb"]
    return row


def main(out: Path, runs: list[Path]) -> None:
    rows = [row_of(r) for r in runs]
    lines = [
        "Relations metric (Kuemmerle et al. 2009), absolute translational error, mean over the relations.",
        "",
        "| run | log | method | particles | seed | scans | "
        + " | ".join(title for _, title in COLUMNS.values())
        + " | wall time [s] | peak RSS [MB] |",
        "|" + "---|" * (8 + len(COLUMNS)),
    ]
    for r in rows:
        lines.append(
            f"| `{r['run']}` | {r['dataset']} | {r['method']} | {r['particles']} | {r['seed']} | {r['n_scans']} | "
            + " | ".join(f"{r[n]:.4f}" for n in COLUMNS)
            + f" | {r['wall_time_s']:.0f} | {r['peak_rss_mb']:.0f} |"
        )
    lines += ["", "The default filter over its seeds (weighted mean):", ""]
    for prefix, log in (("i_rob_s", "Intel"), ("a_rob_s", "ACES")):
        errs = [float(r["trans_mean_m"]) for r in rows if re.fullmatch(prefix + r"\d+", str(r["run"]))]  # type: ignore[arg-type]
        if errs:
            lines.append(
                f"- {log}, {len(errs)} seeds: mean {statistics.mean(errs):.4f} m, median {statistics.median(errs):.4f} m, "
                f"{min(errs):.4f} - {max(errs):.4f} m"
            )
    (out / "table.md").write_text("\n".join(lines) + "\n")
    with open(out / "table.csv", "w", newline="") as fh:
        writer = csv.DictWriter(fh, fieldnames=list(rows[0]))
        writer.writeheader()
        writer.writerows(rows)


if __name__ == "__main__":
    main(Path(sys.argv[1]), [Path(p) for p in sys.argv[2:]])
