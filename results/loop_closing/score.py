"""Scores the runs of run.sh: position RMSE after an SE(2) alignment against the semi-real logs'
truth (and the odometry's), the relations error of Intel and ACES, and what loop closing did.
Usage: python score.py OUT"""

from __future__ import annotations

import json
import re
import sys
from pathlib import Path

import numpy as np

from crlam.eval.trajectory import reference_errors
from crlam.io.tum import read_tum


def rmse(stamps, poses, t_ref, p_ref) -> float:
    r = reference_errors(stamps, poses, t_ref, p_ref, align="se2")
    return float(np.sqrt(np.mean(np.sum(r.errors[:, :2] ** 2, axis=1))))


def error(run: Path, truth) -> str:
    metrics = run / "metrics.json"
    if not metrics.exists():
        return "-"
    if truth is None:
        return f"{json.loads(metrics.read_text())['relations']['trans_mean_m']:.4f}"
    est = read_tum(run / "trajectory.tum")
    return f"{rmse(est.timestamps, est.poses, truth.timestamps, truth.poses):.2f}"


def closing(run: Path) -> str:
    metrics = run / "metrics.json"
    if not metrics.exists():
        return "-"
    lc = json.loads(metrics.read_text()).get("loop_closing") or {}
    moves = ", ".join(f"{r['moved_m']:.1f}" for r in lc.get("reanchorings", []))
    return f"{lc.get('loops_closed', 0)} / {lc.get('inconsistent', 0)} / {lc.get('reanchors', 0)} ({moves})" if lc else "-"


def main(out: Path) -> None:
    print(
        "| log | odometry | loop closing off | loop closing on "
        "| loops closed / dropped as inconsistent / re-anchorings (m moved) |"
    )
    print("|---|---|---|---|---|")
    names = sorted(p.name for p in (out / "runs-graph").iterdir() if p.is_dir())
    for name in names:
        log = out / re.sub(r"-s\d+$", "", name)  # the semi-real log of a run of another filter seed
        truth = read_tum(log / "groundtruth.tum") if (log / "semireal.json").exists() else None
        odom = "-"
        if truth is not None:
            o = read_tum(log / "odometry.tum")
            odom = f"{rmse(truth.timestamps, o.poses, truth.timestamps, truth.poses):.2f}"
        off, on = error(out / "runs-off" / name, truth), error(out / "runs-graph" / name, truth)
        print(f"| {name} | {odom} | {off} | {on} | {closing(out / 'runs-graph' / name)} |")


if __name__ == "__main__":
    main(Path(sys.argv[1]))
