"""Global localization on the simulated floors of look-alike rooms (:mod:`crlam.sim.lookalike`):
the runs the localizer's ``min_cluster``, ``convergence_odds``, ``min_bin``, ``spread_particles``,
``place_xy`` and ``spread_climb`` were chosen on.

Simulates a SICK LMS200 log on the floor (seeded), then for every setting (``SETTINGS``) runs
global localizations from random scans of it for ``--travel`` metres each (never stopped at
convergence) and records every processed scan's heaviest and second-heaviest cluster with the
estimate's error against the ground truth. The convergence rule (:func:`crlam.localize.converged_at`,
held for ``convergence_hold`` processed scans) is then applied afterwards for every odds value, so
one run per setting judges them all. Writes ``steps.csv`` (one row per processed scan),
``cpu.csv`` (CPU seconds per trial) and the choice table (per setting: trials converged to the
truth, to a wrong place, not at all, the distance travelled until convergence and the CPU per
trial): ``lookalike_choice.csv`` for the small floor (four rooms each side of the corridor, 150 m²
free), ``lookalike_intel_scale_choice.csv`` for the floor of Intel's scale (``--floor
intel-scale``: ten 5 m x 5 m rooms each side, 627 m² free; Intel's map has about 765 m²).

Usage, from the repository root::

    python results/localization/lookalike.py runs/lookalike results/localization
    python results/localization/lookalike.py runs/lookalike-intel-scale results/localization --floor intel-scale

The rule for the choice: convergence is declared only once no other place is kept, so the odds
are 1 / ``keep_ratio`` (the table shows the other odds beside it); ``min_cluster`` on (30, the one
value tried) or off by the fewest trials converged to a wrong place, then the most converged to
the truth within 10 m; ``min_bin`` (1 or off) and ``spread_particles`` (20,000 or 5,000, one
value tried) by the same rule on the small floor, then the cheaper setting on a tie;
``place_xy`` (2 m or off, one value tried) and then ``spread_climb`` (on or off, its steps set by
the KLD bin and the map's cell, not tried) by the same rule over both floors (the trials of the two
added up).
"""

from __future__ import annotations

import argparse
import csv
import math
import time
from dataclasses import replace
from pathlib import Path

import numpy as np

from crlam.io.carmen import read_scans
from crlam.io.tum import read_tum
from crlam.localize import LocalizeConfig, Localizer, converged_at
from crlam.localize.map import load_localization_map
from crlam.pose import between
from crlam.sim.lookalike import INTEL_SCALE, lookalike_world
from crlam.sim.simulate import SimulationConfig, simulate, write_simulation

# (min_cluster, min_bin, spread_particles, place_xy m, spread_climb): AMCL's resampling, the
# cluster floor, the cluster floor with the bin floor of a spread set, with more particles while
# spread, with the floor kept per place of place_xy m (and place_theta) while spread, and with the
# scan-matched proposal of a spread set.
Setting = tuple[int, int, int, float, int]
SETTINGS: dict[str, tuple[Setting, ...]] = {
    "small": (
        (0, 0, 0, 0.0, 0),
        (30, 0, 0, 0.0, 0),
        (30, 1, 0, 0.0, 0),
        (30, 0, 20000, 0.0, 0),
        (30, 0, 20000, 2.0, 0),
        (30, 0, 20000, 2.0, 1),
    ),
    "intel-scale": ((30, 0, 20000, 0.0, 0), (30, 0, 20000, 2.0, 0), (30, 0, 20000, 2.0, 1)),
}
FLOORS = {"small": {}, "intel-scale": INTEL_SCALE}
SCANS = {"small": 2400, "intel-scale": 4000}
CHOICE = {"small": "lookalike_choice.csv", "intel-scale": "lookalike_intel_scale_choice.csv"}
ODDS = (1.0, 10.0, 100.0, 1000.0)
CORRECT_XY, CORRECT_THETA = 0.5, 0.2  # as crlam.experiments.localize_trials


def _simulate(folder: Path, floor: str, n_scans: int, seed: int) -> None:
    if (folder / "log.clf").is_file():
        return
    folder.mkdir(parents=True, exist_ok=True)
    lookalike_world(**FLOORS[floor]).to_nav2_yaml(folder / "floor.yaml")
    write_simulation(
        simulate(SimulationConfig(world=str(folder / "floor.yaml"), n_scans=n_scans, seed=seed, sensor="sick")), folder
    )


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("runs", type=Path)
    ap.add_argument("out", type=Path)
    ap.add_argument("--trials", type=int, default=8)
    ap.add_argument("--travel", type=float, default=12.0)
    ap.add_argument("--floor", choices=sorted(FLOORS), default="small")
    ap.add_argument("--scans", type=int, help="scans to simulate (default: 2,400 on the small floor, 4,000 on intel-scale)")
    ap.add_argument("--only", action="append", metavar="MC,MB,SP,PX,CL", help="run only this setting of SETTINGS (repeatable)")
    args = ap.parse_args()
    only = {tuple(float(v) for v in o.split(",")) for o in args.only or []}
    sim = args.runs / "sim"
    _simulate(sim, args.floor, args.scans or SCANS[args.floor], seed=5)
    scans = list(read_scans(sim / "log.clf"))
    truth = read_tum(sim / "groundtruth.tum").poses
    m = load_localization_map(sim / "floor.yaml")
    steps_xy = [math.hypot(*between(a.odom, b.odom)[:2]) for a, b in zip(scans[:-1], scans[1:])]
    travelled = np.concatenate([[0.0], np.cumsum(steps_xy)])
    ok = np.nonzero(travelled[-1] - travelled >= args.travel)[0]
    starts = np.sort(np.random.default_rng(0).choice(ok, size=args.trials, replace=False))
    args.runs.mkdir(parents=True, exist_ok=True)
    rows = []
    path = args.runs / "steps.csv"
    done = set()
    if path.is_file():
        with open(path) as fh:
            rows = list(csv.DictReader(fh))
        for r in rows:
            r.setdefault("min_bin", "0")  # rows written before these columns existed
            r.setdefault("spread_particles", "0")
            r.setdefault("place_xy", "0")
            r.setdefault("spread_climb", "0")
        done = {_key(r) + (int(r["trial"]),) for r in rows}
    cols = [
        "min_cluster",
        "min_bin",
        "spread_particles",
        "place_xy",
        "spread_climb",
        "trial",
        "start",
        "scan",
        "distance_m",
        "weight",
        "second",
        "spread_xy",
        "spread_theta",
        "err_xy",
        "err_theta",
        "n_particles",
    ]
    if rows and "spread_climb" not in open(path).readline():
        # A file from before one of the columns: rewrite it with them (its rows are 0).
        with open(path, "w", newline="") as fh:
            w = csv.DictWriter(fh, cols)
            w.writeheader()
            w.writerows(rows)
    with open(path, "a", newline="") as fh:
        w = csv.DictWriter(fh, cols)
        if not rows:
            w.writeheader()
        for setting in SETTINGS[args.floor]:
            if only and setting not in only:
                continue
            mc, mb, sp, px, cl = setting
            cfg = _config(setting)
            for t, s0 in enumerate(starts):
                if setting + (t,) in done:
                    continue
                t0 = time.process_time()
                loc = Localizer(m, replace(cfg, seed=t), laser_max_range=scans[s0].max_range)
                k = int(s0)
                while k < len(scans) and travelled[k] - travelled[s0] <= args.travel:
                    sc = scans[k]
                    r = np.where(sc.ranges >= sc.max_range, np.inf, sc.ranges)
                    st = loc.step(sc.odom, sc.angles, r, sc.laser_offset, sc.timestamp)
                    if st.processed:
                        d = between(truth[k], st.estimate)
                        row = {
                            "min_cluster": mc,
                            "min_bin": mb,
                            "spread_particles": sp,
                            "place_xy": px,
                            "spread_climb": cl,
                            "trial": t,
                            "start": int(s0),
                            "scan": k,
                            "distance_m": f"{travelled[k] - travelled[s0]:.3f}",
                            "weight": f"{st.cluster_weight:.6g}",
                            "second": f"{st.second_weight:.6g}",
                            "spread_xy": f"{st.spread_xy:.4f}",
                            "spread_theta": f"{st.spread_theta:.4f}",
                            "err_xy": f"{math.hypot(d[0], d[1]):.4f}",
                            "err_theta": f"{abs(d[2]):.4f}",
                            "n_particles": st.n_particles,
                        }
                        w.writerow(row)
                        rows.append({c: str(v) for c, v in row.items()})
                    k += 1
                fh.flush()
                with open(args.runs / "cpu.csv", "a") as fc:
                    fc.write(f"{mc},{mb},{sp},{px},{cl},{t},{time.process_time() - t0:.1f}\n")
                print(
                    f"min_cluster {mc} min_bin {mb} spread_particles {sp} place_xy {px} spread_climb {cl} "
                    f"trial {t} start {s0}: "
                    f"{time.process_time() - t0:.0f} s CPU",
                    flush=True,
                )
    cpu: dict[Setting, list[float]] = {}
    if (args.runs / "cpu.csv").is_file():
        for line in open(args.runs / "cpu.csv"):
            f = line.strip().split(",")
            if len(f) == 6:  # a line from before the spread_climb column
                f.insert(4, "0")
            cpu.setdefault((int(f[0]), int(f[1]), int(f[2]), float(f[3]), int(f[4])), []).append(float(f[6]))
    _choose(rows, args.out / CHOICE[args.floor], cpu)


def _config(setting: Setting, **more: float) -> LocalizeConfig:
    """The setting's :class:`LocalizeConfig`."""
    mc, mb, sp, px, cl = setting
    return LocalizeConfig(
        min_cluster=mc,
        keep_ratio=1e-3,
        min_bin=mb,
        spread_particles=sp,
        place_xy=px,
        spread_climb=bool(cl),
        **more,  # type: ignore[arg-type]
    )


def _key(r: dict[str, str]) -> Setting:
    return (
        int(r["min_cluster"]),
        int(r["min_bin"]),
        int(r["spread_particles"]),
        float(r["place_xy"]),
        int(r["spread_climb"]),
    )


def _judge(trial: list[dict[str, str]], cfg: LocalizeConfig) -> tuple[str, float]:
    """(correct / wrong / none, distance at convergence) of one trial's processed scans."""
    held = 0
    for i, r in enumerate(trial):
        ok = converged_at(cfg, float(r["weight"]), float(r["second"]), float(r["spread_xy"]), float(r["spread_theta"]))
        held = held + 1 if ok else 0
        if held >= cfg.convergence_hold:
            first = trial[i - held + 1]
            right = all(float(x["err_xy"]) <= CORRECT_XY and float(x["err_theta"]) <= CORRECT_THETA for x in (first, r))
            return ("correct" if right else "wrong"), float(first["distance_m"])
    return "none", math.nan


def _choose(rows: list[dict[str, str]], out: Path, cpu: dict[Setting, list[float]]) -> None:
    by: dict[tuple[int, int, int, float, int, int], list[dict[str, str]]] = {}
    for r in rows:
        by.setdefault(_key(r) + (int(r["trial"]),), []).append(r)
    table = []
    for setting in sorted({k[:5] for k in by}):
        mc, mb, sp, px, cl = setting
        for odds in ODDS:
            cfg = _config(setting, convergence_odds=odds)
            res = [_judge(v, cfg) for k, v in sorted(by.items()) if k[:5] == setting]
            dist = [d for v, d in res if v == "correct"]
            table.append(
                {
                    "min_cluster": mc,
                    "min_bin": mb,
                    "spread_particles": sp,
                    "place_xy": px,
                    "spread_climb": cl,
                    "convergence_odds": odds,
                    "trials": len(res),
                    "correct": sum(v == "correct" for v, _ in res),
                    "correct_within_10m": sum(v == "correct" and d <= 10.0 for v, d in res),
                    "wrong": sum(v == "wrong" for v, _ in res),
                    "not_converged": sum(v == "none" for v, _ in res),
                    "median_distance_m": f"{np.median(dist):.2f}" if dist else "",
                    "cpu_s_per_trial": f"{np.mean(cpu[setting]):.0f}" if cpu.get(setting) else "",
                }
            )
    out.parent.mkdir(parents=True, exist_ok=True)
    with open(out, "w", newline="") as fh:
        w = csv.DictWriter(fh, list(table[0]))
        w.writeheader()
        w.writerows(table)
    for t in table:
        print(t)


if __name__ == "__main__":
    main()
