"""Scores the runs of run.sh: position RMSE after an SE(2) alignment, of the filter and of the
odometry it was given, and their ratio; relative error over 10 m of travel (translation, heading).
Usage: python score.py OUT"""

from __future__ import annotations

import math
import sys
from pathlib import Path

import numpy as np

from crlam.eval.trajectory import reference_errors
from crlam.io.tum import read_tum
from crlam.pose import between


def rmse(stamps, poses, t_ref, p_ref) -> float:
    r = reference_errors(stamps, poses, t_ref, p_ref, align="se2")
    return float(np.sqrt(np.mean(np.sum(r.errors[:, :2] ** 2, axis=1))))


def relative_10m(est, ref) -> tuple[float, float]:
    travelled = np.r_[0.0, np.cumsum(np.hypot(*np.diff(ref[:, :2], axis=0).T))]
    trans, rot = [], []
    for a in range(len(ref)):
        b = int(np.searchsorted(travelled, travelled[a] + 10.0))
        if b >= len(ref):
            break
        e = between(between(ref[a], ref[b]), between(est[a], est[b]))
        trans.append(math.hypot(e[0], e[1]))
        rot.append(abs(e[2]))
    return float(np.mean(trans)), math.degrees(float(np.mean(rot)))


def main(out: Path) -> None:
    print("| log | odometry RMSE [m] | model RMSE [m] | estimate RMSE [m] | odometry / model / estimate per 10 m [m, deg] |")
    print("|---|---|---|---|---|")
    for log in sorted(p for p in out.iterdir() if (p / "semireal.json").exists()):
        truth = read_tum(log / "groundtruth.tum")
        odom = read_tum(log / "odometry.tum")
        index = {round(t, 6): i for i, t in enumerate(truth.timestamps)}
        cells = [f"{rmse(truth.timestamps, odom.poses, truth.timestamps, truth.poses):.2f}"]
        rel = [relative_10m(odom.poses, truth.poses)]
        for noise in ("model", "estimate"):
            traj = out / f"runs-{noise}" / log.name / "trajectory.tum"
            if not traj.exists():
                cells.append("-")
                continue
            est = read_tum(traj)
            keep = [i for i, t in enumerate(est.timestamps) if round(t, 6) in index]
            ref = truth.poses[[index[round(est.timestamps[i], 6)] for i in keep]]
            cells.append(f"{rmse(est.timestamps, est.poses, truth.timestamps, truth.poses):.2f}")
            rel.append(relative_10m(est.poses[keep], ref))
        rels = " / ".join(f"{t:.2f}, {r:.2f}" for t, r in rel)
        print(f"| {log.name} | {' | '.join(cells)} | {rels} |")


if __name__ == "__main__":
    main(Path(sys.argv[1]))
