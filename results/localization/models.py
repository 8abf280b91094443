"""The measurement models compared on the same filter (issue 48): the CRM likelihood (``crm``,
the default; and ``crm-exact``) against AMCL's likelihood field and beam model, on simulated
floors.

Runs, for every model, on a SICK LMS200 log simulated on the small look-alike floor
(:func:`crlam.sim.lookalike.lookalike_world`, seed 1, 300 scans):

- **global**: ``--starts`` global localizations, each from scan 0 with its own seed, every scan
  fed: converged (the localizer's rule) within 0.5 m of the truth, converged elsewhere, or not
  at all; travel until convergence;
- **kidnap**: from the known pose of scan 200, scans 200-299, then the robot is carried 8.6 m to
  where scan 0 was taken and driven as scans 0-199 were (the odometry goes on as if nothing
  happened): scans until the estimate is back within 0.5 m for 10 scans in a row;
- **changed**: the map is the floor as drawn, the log is simulated on the floor with its
  furniture changed (every room's desk removed on one side of the corridor, boxes of
  0.4-0.8 m added in the other side's rooms and the corridor): tracking error from the known start
  (median and 95th percentile over the scans) and the global localizations as above;

and times each run's CPU per scan (one thread). Writes ``models.csv`` (one row per run) and
``models_table.md`` (one row per model and case) to the output folder.

Usage, from the repository root (about 10 min of CPU with 5 starts)::

    python results/localization/models.py runs/models results/localization --starts 5
"""

from __future__ import annotations

import argparse
import csv
import os
import time
from pathlib import Path
from typing import Any

import numpy as np
from scipy import ndimage

from crlam.io.carmen import LaserScan, read_scans
from crlam.io.tum import read_tum
from crlam.localize import LocalizeConfig, Localizer
from crlam.localize.map import load_localization_map
from crlam.pose import between, compose
from crlam.sim.lookalike import lookalike_world
from crlam.sim.simulate import SimulationConfig, simulate, write_simulation
from crlam.sim.world import World

MODELS = ("crm", "crm-exact", "likelihood_field", "beam")
CASES = ("global", "kidnap", "changed")
CLOSE = 0.5
"""Metres: a converged estimate this near the truth is at the true place."""


def changed_world(world: World, seed: int) -> World:
    """The floor with its furniture changed: the desks (obstacles thicker than 0.3 m) of the rooms
    south of the corridor's centre line removed, twelve 0.4-0.8 m boxes added in the northern
    rooms and the corridor, 0.6 m or more from any obstacle."""
    occ = world.occupied.copy()
    # Desks are the obstacles thicker than 0.3 m (walls are 0.15 m): what an opening keeps, less
    # the solid block outside the floor (the largest piece).
    res = world.resolution
    thick = ndimage.binary_opening(occ, structure=np.ones((int(0.3 / res), int(0.3 / res)), dtype=bool))
    labels, n = ndimage.label(thick)
    ny = occ.shape[0]
    # The outer wall (0.15 m at the image's border) stays.
    inner = np.zeros_like(occ)
    inner[3:-3, 3:-3] = True
    for k in range(1, n + 1):
        cells = labels == k
        if cells.sum() <= 2000 and np.nonzero(cells)[0].mean() < ny / 2:
            occ[cells & inner] = False
    rng = np.random.default_rng(seed)
    free = ~ndimage.binary_dilation(occ, iterations=int(0.6 / res))
    added = 0
    while added < 12:
        iy, ix = rng.integers(ny // 2, ny), rng.integers(0, occ.shape[1])
        w, h = (rng.uniform(0.4, 0.8, 2) / res).astype(int)
        if free[iy : iy + h, ix : ix + w].size == w * h and free[iy : iy + h, ix : ix + w].all():
            occ[iy : iy + h, ix : ix + w] = True
            free[max(0, iy - 12) : iy + h + 12, max(0, ix - 12) : ix + w + 12] = False
            added += 1
    return World(occ, res, name=world.name + "-changed")


def _sim(folder: Path, world: World, seed: int = 1) -> tuple[list[LaserScan], np.ndarray]:
    folder.mkdir(parents=True, exist_ok=True)
    if not (folder / "log.clf").exists():
        world.to_nav2_yaml(folder / "floor.yaml")
        write_simulation(
            simulate(SimulationConfig(world=str(folder / "floor.yaml"), n_scans=300, seed=seed, sensor="sick")), folder
        )
    return list(read_scans(folder / "log.clf")), read_tum(folder / "groundtruth.tum").poses


def _run(loc: Localizer, scans: list[LaserScan], odoms: list[np.ndarray] | None = None) -> float:
    t = time.process_time()
    for i, s in enumerate(scans):
        r = np.where(s.ranges >= s.max_range, np.inf, s.ranges)
        loc.step(s.odom if odoms is None else odoms[i], s.angles, r, s.laser_offset, s.timestamp)
    return time.process_time() - t


def _errors(loc: Localizer, truth: np.ndarray) -> np.ndarray:
    _, est = loc.trajectory()
    d = between(truth, est)
    return np.asarray(np.hypot(d[:, 0], d[:, 1]))


def _config(model: str, seed: int) -> LocalizeConfig:
    return LocalizeConfig(model=model, seed=seed)


def global_runs(
    model: str, map_path: Path, scans: list[LaserScan], truth: np.ndarray, starts: int, case: str
) -> list[dict[str, Any]]:
    m = load_localization_map(map_path)
    rows = []
    for seed in range(starts):
        loc = Localizer(m, _config(model, seed))
        cpu = _run(loc, scans)
        err = _errors(loc, truth)
        c = loc.convergence
        outcome = "none" if c is None else ("truth" if err[c.scan_index] < CLOSE else "wrong")
        rows.append(
            {
                "case": case,
                "model": model,
                "seed": seed,
                "outcome": outcome,
                "travel_m": "" if c is None else round(c.distance_m, 2),
                "err_median_m": round(float(np.median(err[-40:])), 4),
                "cpu_ms_per_scan": round(1000 * cpu / len(scans), 2),
            }
        )
    return rows


def tracking_run(model: str, map_path: Path, scans: list[LaserScan], truth: np.ndarray, case: str) -> dict[str, Any]:
    loc = Localizer(load_localization_map(map_path), _config(model, 0), initial_pose=truth[0], initial_cov=[0.01, 0.01, 0.005])
    cpu = _run(loc, scans)
    err = _errors(loc, truth)
    return {
        "case": case,
        "model": model,
        "seed": 0,
        "outcome": "tracked" if err.max() < CLOSE else "lost",
        "travel_m": "",
        "err_median_m": round(float(np.median(err)), 4),
        "err_p95_m": round(float(np.percentile(err, 95)), 4),
        "cpu_ms_per_scan": round(1000 * cpu / len(scans), 2),
    }


def kidnap_run(model: str, map_path: Path, scans: list[LaserScan], truth: np.ndarray) -> dict[str, Any]:
    # From the known pose of scan 200 to the end of the log (100 scans), then carried to where
    # scan 0 was taken (8.6 m away on this floor) and driven as scans 0-199 were.
    first, to = 200, 0
    seq = scans[first:] + scans[to:first]
    want = np.vstack([truth[first:], truth[to:first]])
    cut = len(scans) - first
    odoms = [s.odom for s in scans[first:]]
    for k in range(to, first):
        step = np.zeros(3) if k == to else between(scans[k - 1].odom, scans[k].odom)
        odoms.append(compose(odoms[-1], step))
    cfg = _config(model, 0)
    loc = Localizer(load_localization_map(map_path), cfg, initial_pose=truth[first], initial_cov=[0.01, 0.01, 0.005])
    cpu = _run(loc, seq, odoms)
    err = _errors(loc, want)
    carried = float(np.hypot(*(truth[to][:2] - truth[-1][:2])))
    back = next((i for i in range(cut, len(err) - 9) if (err[i : i + 10] < CLOSE).all()), None)
    return {
        "case": f"kidnap ({carried:.1f} m)",
        "model": model,
        "seed": 0,
        "outcome": "recovered" if back is not None else "lost",
        "recovery_scans": "" if back is None else back - cut,
        "recovery_s": "" if back is None else round(seq[back].timestamp - seq[cut].timestamp, 1),
        "err_median_m": round(float(np.median(err[-40:])), 4),
        "cpu_ms_per_scan": round(1000 * cpu / len(seq), 2),
    }


def _case_of(row: dict[str, Any]) -> str:
    c = str(row["case"])
    return "kidnap" if c.startswith("kidnap") else ("changed" if "changed" in c else "global")


def _kept(path: Path, cases: list[str], models: list[str]) -> list[dict[str, Any]]:
    """The rows of an existing models.csv that this run does not redo (numbers read back)."""
    if not path.is_file():
        return []
    with open(path, newline="") as fh:
        old = list(csv.DictReader(fh))
    kept = []
    for r in old:
        if _case_of(r) in cases and r["model"] in models:
            continue
        kept.append({k: (_number(v) if k not in ("case", "model", "outcome") else v) for k, v in r.items()})
    return kept


def _number(v: str) -> Any:
    if v == "":
        return ""
    try:
        return int(v)
    except ValueError:
        return float(v)


def table(rows: list[dict[str, Any]]) -> str:
    lines = [
        "| case | model | result | travel to convergence (m, median) | error (m, median) | CPU per scan (ms) |",
        "|---|---|---|---|---|---|",
    ]
    cases = list(dict.fromkeys(r["case"] for r in rows))
    for case in cases:
        for model in MODELS:
            rs = [r for r in rows if r["case"] == case and r["model"] == model]
            if not rs:
                continue
            if case.startswith("global"):
                ok = [r for r in rs if r["outcome"] == "truth"]
                wrong = sum(r["outcome"] == "wrong" for r in rs)
                result = f"{len(ok)}/{len(rs)} at the truth, {wrong} wrong"
                travel = f"{np.median([r['travel_m'] for r in ok]):.2f}" if ok else "-"
            elif case.startswith("kidnap"):
                r = rs[0]
                result = (
                    f"{r['outcome']} after {r['recovery_scans']} scans ({r['recovery_s']} s)"
                    if r["recovery_scans"] != ""
                    else "lost"
                )
                travel = "-"
            else:
                r = rs[0]
                result = f"{r['outcome']}, 95th percentile {r['err_p95_m']} m"
                travel = "-"
            err = np.median([r["err_median_m"] for r in rs])
            cpu = np.median([r["cpu_ms_per_scan"] for r in rs])
            lines.append(f"| {case} | {model} | {result} | {travel} | {err:.3f} | {cpu:.1f} |")
    return "\n".join(lines) + "\n"


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("work", type=Path, help="folder for the simulated logs")
    ap.add_argument("out", type=Path, help="folder for models.csv and models_table.md")
    ap.add_argument("--starts", type=int, default=5, help="global localizations per model and floor")
    ap.add_argument("--models", nargs="+", default=list(MODELS), choices=MODELS)
    ap.add_argument(
        "--cases",
        nargs="+",
        default=list(CASES),
        choices=CASES,
        help="the cases to run; the rows of the others are kept from an existing models.csv",
    )
    args = ap.parse_args()
    os.environ.setdefault("RAYON_NUM_THREADS", "1")
    floor = lookalike_world(3)
    scans, truth = _sim(args.work / "floor", floor)
    changed_scans, changed_truth = _sim(args.work / "changed", changed_world(floor, 0))
    map_path = args.work / "floor" / "floor.yaml"
    rows: list[dict[str, Any]] = []
    for model in args.models:
        if "global" in args.cases:
            rows += global_runs(model, map_path, scans, truth, args.starts, "global, look-alike floor")
        if "kidnap" in args.cases:
            rows.append(kidnap_run(model, map_path, scans, truth))
        if "changed" in args.cases:
            rows.append(tracking_run(model, map_path, changed_scans, changed_truth, "tracking, furniture changed"))
            rows += global_runs(model, map_path, changed_scans, changed_truth, args.starts, "global, furniture changed")
        print(model, "done", flush=True)
    rows = _kept(args.out / "models.csv", args.cases, args.models) + rows
    args.out.mkdir(parents=True, exist_ok=True)
    keys = list(dict.fromkeys(k for r in rows for k in r))
    with open(args.out / "models.csv", "w", newline="") as fh:
        w = csv.DictWriter(fh, fieldnames=keys)
        w.writeheader()
        w.writerows(rows)
    (args.out / "models_table.md").write_text(table(rows))
    print(table(rows))


if __name__ == "__main__":
    main()
