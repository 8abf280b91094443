"""``crlam localize --trials N``: global localizations from random scans of a log.

Each trial starts a localizer with no initial pose (particles over the map's free space) at a
scan drawn uniformly (seeded) among those with at least ``max_travel`` metres of odometry path
left (else ``target_travel``), and runs until it converges (:class:`crlam.localize.Convergence`)
or the robot has travelled ``max_travel`` metres. With a reference trajectory (e.g. the
``trajectory.tum`` of a run started from the known pose) a converged trial is correct when its
estimate is within :data:`CORRECT_XY` m and :data:`CORRECT_THETA` rad of the reference at the
convergence scan and at the trial's last scan. The folder gets ``trials.csv`` (one row per
trial, written as each finishes), ``trials.png`` (the share of trials converged against the
distance travelled) and ``metrics.json`` (the summary, written last); ``--resume`` keeps the
finished trials of an interrupted folder.
"""

from __future__ import annotations

import csv
import json
import math
import os
import time
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray
from tqdm import tqdm

from crlam import __version__
from crlam.errors import ConfigError, DataFormatError
from crlam.experiments.resume import close_experiment, open_experiment
from crlam.experiments.slam_run import _jsonable, _scan_inputs
from crlam.io.carmen import LaserScan
from crlam.io.logs import open_log
from crlam.io.tum import read_tum
from crlam.localize import LocalizeConfig, Localizer
from crlam.localize.map import Nav2Prior, load_localization_map
from crlam.pose import between

__all__ = ["CORRECT_THETA", "CORRECT_XY", "TrialScan", "run_global_trials"]

CORRECT_XY = 0.5
"""A converged trial is correct when its estimate is within this distance (m) of the reference..."""

CORRECT_THETA = 0.2
"""... and this heading difference (rad), at convergence and at its last scan."""

TRIAL_COLUMNS = (
    "trial",
    "start_scan",
    "start_stamp",
    "converged",
    "convergence_scan",
    "time_s",
    "distance_m",
    "error_xy_m",
    "error_theta_deg",
    "final_error_xy_m",
    "final_error_theta_deg",
    "correct",
    "scans_run",
    "wall_s",
)


@dataclass(frozen=True)
class TrialScan:
    """A scan held in memory for the trials."""

    odom: NDArray[np.float64]
    angles: NDArray[np.float64]
    ranges: NDArray[np.float64]
    laser_offset: NDArray[np.float64]
    stamp: float
    max_range: float


def _read_scans(log_path: str | os.PathLike[str], bag_options: dict[str, Any] | None) -> list[TrialScan]:
    out = []
    for rec in open_log(log_path, **(bag_options or {})):
        if isinstance(rec, LaserScan):
            a, r = _scan_inputs(rec)
            out.append(TrialScan(rec.odom, a, r, rec.laser_offset, rec.timestamp, rec.max_range))
    if not out:
        raise DataFormatError("the log holds no laser scans", path=str(log_path))
    return out


def _pose_error(p: NDArray[np.float64], q: NDArray[np.float64]) -> tuple[float, float]:
    d = between(q, p)
    return float(math.hypot(d[0], d[1])), float(abs(d[2]))


def run_global_trials(
    log_path: str | os.PathLike[str],
    map_path: str | os.PathLike[str],
    out_dir: str | os.PathLike[str],
    config: LocalizeConfig | None = None,
    *,
    n_trials: int = 20,
    max_travel: float = 30.0,
    target_travel: float = 10.0,
    trial_seed: int = 0,
    reference: str | os.PathLike[str] | None = None,
    nav2_prior: Nav2Prior | None = None,
    bag_options: dict[str, Any] | None = None,
    progress: bool = True,
    resume: bool = False,
    force: bool = False,
) -> dict[str, Any]:
    """Runs the trials (module docstring) and returns the summary written to ``metrics.json``.
    Trial i uses ``config`` with seed ``config.seed + i``.

    An existing folder is refused unless ``resume`` (its finished trials are kept when its
    ``experiment.json`` records the same settings; the rest are run) or ``force`` (it is emptied
    first); see :mod:`crlam.experiments.resume`."""
    config = config or LocalizeConfig()
    if not (n_trials >= 1 and max_travel > 0 and target_travel > 0):
        raise ConfigError("n_trials must be >= 1 and the travels > 0")
    settings = {
        "log": str(log_path),
        "map": str(map_path),
        "config": config.to_dict(),
        "n_trials": n_trials,
        "max_travel_m": max_travel,
        "target_travel_m": target_travel,
        "trial_seed": trial_seed,
        "reference": None if reference is None else str(reference),
        "nav2_prior": None if nav2_prior is None else nav2_prior.__dict__,
        "bag_options": bag_options or {},
    }
    out = open_experiment(out_dir, "localize-trials", settings, resume=resume, force=force)
    loc_map = load_localization_map(map_path, nav2_prior=nav2_prior)
    scans = _read_scans(log_path, bag_options)
    travelled = np.concatenate(
        [[0.0], np.cumsum([math.hypot(*between(a.odom, b.odom)[:2]) for a, b in zip(scans[:-1], scans[1:])])]
    )
    ref: dict[float, NDArray[np.float64]] | None = None
    if reference is not None:
        r = read_tum(reference)
        ref = {float(t): p for t, p in zip(r.timestamps, r.poses)}
    left = travelled[-1] - travelled
    starts_ok = np.nonzero(left >= max_travel)[0]
    if starts_ok.size == 0:
        starts_ok = np.nonzero(left >= target_travel)[0]
    if starts_ok.size == 0:
        raise ConfigError(f"the log's {travelled[-1]:.1f} m of travel leave no start with {target_travel:g} m ahead")
    rng = np.random.default_rng(trial_seed)
    starts = np.sort(rng.choice(starts_ok, size=n_trials, replace=starts_ok.size < n_trials))
    csv_path = out / "trials.csv"
    done = _finished_rows(csv_path, starts)
    rows: list[dict[str, Any]] = []
    with open(csv_path, "w", newline="") as fh:
        w = csv.writer(fh)
        w.writerow(TRIAL_COLUMNS)
        for i, start in enumerate(tqdm(starts, desc="global localization trials", disable=not progress)):
            row = done.get(i)
            if row is None:
                row = _run_trial(i, int(start), scans, travelled, loc_map, replace(config, seed=config.seed + i), max_travel, ref)
            rows.append(row)
            w.writerow([row[c] for c in TRIAL_COLUMNS])
            fh.flush()
    summary = _summary(rows, target_travel, ref is not None)
    summary.update(
        {
            "crlam_version": __version__,
            "log": str(log_path),
            "map": loc_map.description,
            "n_trials": n_trials,
            "max_travel_m": max_travel,
            "target_travel_m": target_travel,
            "trial_seed": trial_seed,
            "reference": None if reference is None else str(reference),
            "correct_rule": None
            if ref is None
            else f"converged with the estimate within {CORRECT_XY} m and {math.degrees(CORRECT_THETA):.1f} deg of the reference "
            "at the convergence scan and at the trial's last scan",
            "config": config.to_dict(),
        }
    )
    from crlam.viz.localization import save_trials_figure

    save_trials_figure(
        out / "trials.png", rows, target_travel, max_travel, title=f"{Path(log_path).name}: {n_trials} global localizations"
    )
    tmp = out / "metrics.json.tmp"
    tmp.write_text(json.dumps(summary, indent=2, sort_keys=True, default=_jsonable) + "\n")
    tmp.replace(out / "metrics.json")
    close_experiment(out, n_runs=n_trials, failed={})
    return summary


def _finished_rows(csv_path: Path, starts: NDArray[np.int64]) -> dict[int, dict[str, Any]]:
    """The rows of a resumed folder's ``trials.csv`` that finished with the start they should have
    (by trial index); an unreadable file or row counts as not finished."""
    out: dict[int, dict[str, Any]] = {}
    try:
        with open(csv_path, newline="") as fh:
            for raw in csv.DictReader(fh):
                if set(TRIAL_COLUMNS) - set(raw):
                    return {}
                i = int(raw["trial"])
                if 0 <= i < len(starts) and int(raw["start_scan"]) == int(starts[i]):
                    row: dict[str, Any] = dict(raw)
                    for key in ("trial", "start_scan", "converged", "scans_run"):
                        row[key] = int(row[key])
                    if row["correct"] != "":
                        row["correct"] = int(row["correct"])
                    out[i] = row
    except (OSError, ValueError, csv.Error):
        return {}
    return out


def _run_trial(
    i: int,
    start: int,
    scans: list[TrialScan],
    travelled: NDArray[np.float64],
    loc_map: Any,
    config: LocalizeConfig,
    max_travel: float,
    ref: dict[float, NDArray[np.float64]] | None,
) -> dict[str, Any]:
    t0 = time.perf_counter()
    loc = Localizer(loc_map, config, laser_max_range=scans[start].max_range)
    k = start
    while k < len(scans) and travelled[k] - travelled[start] <= max_travel:
        s = scans[k]
        loc.step(s.odom, s.angles, s.ranges, s.laser_offset, s.stamp)
        k += 1
        if loc.convergence is not None:
            break
    conv = loc.convergence
    row: dict[str, Any] = {
        "trial": i,
        "start_scan": start,
        "start_stamp": f"{scans[start].stamp:.6f}",
        "converged": int(conv is not None),
        "convergence_scan": "" if conv is None else start + conv.scan_index,
        "time_s": "" if conv is None else f"{conv.time_s:.2f}",
        "distance_m": "" if conv is None else f"{conv.distance_m:.3f}",
        "error_xy_m": "",
        "error_theta_deg": "",
        "final_error_xy_m": "",
        "final_error_theta_deg": "",
        "correct": "",
        "scans_run": loc.n_scans,
        "wall_s": f"{time.perf_counter() - t0:.2f}",
    }
    if ref is not None and conv is not None:
        _, poses = loc.trajectory()
        at_conv, last = conv.scan_index, loc.n_scans - 1
        r_conv, r_last = ref.get(scans[start + at_conv].stamp), ref.get(scans[start + last].stamp)
        if r_conv is None or r_last is None:
            raise DataFormatError("the reference has no pose at a trial's scan stamp (it must be a run over the same log)")
        e_xy, e_th = _pose_error(poses[at_conv], r_conv)
        f_xy, f_th = _pose_error(poses[last], r_last)
        row.update(
            {
                "error_xy_m": f"{e_xy:.4f}",
                "error_theta_deg": f"{math.degrees(e_th):.3f}",
                "final_error_xy_m": f"{f_xy:.4f}",
                "final_error_theta_deg": f"{math.degrees(f_th):.3f}",
                "correct": int(e_xy <= CORRECT_XY and e_th <= CORRECT_THETA and f_xy <= CORRECT_XY and f_th <= CORRECT_THETA),
            }
        )
    elif ref is not None:
        row["correct"] = 0
    return row


def _summary(rows: list[dict[str, Any]], target: float, judged: bool) -> dict[str, Any]:
    conv = [r for r in rows if r["converged"]]
    ok = [r for r in conv if (r["correct"] == 1 if judged else True)]
    within = [r for r in ok if float(r["distance_m"]) <= target]
    dist = np.array([float(r["distance_m"]) for r in ok])
    n = len(rows)
    return {
        "n_converged": len(conv),
        "n_converged_correct": len(ok),
        "n_within_target": len(within),
        "fraction_within_target": len(within) / n,
        "distance_m": {}
        if dist.size == 0
        else {"median": float(np.median(dist)), "max": float(dist.max()), "mean": float(dist.mean())},
        "time_s": {} if not ok else {"median": float(np.median([float(r["time_s"]) for r in ok]))},
        "judged_against_reference": judged,
    }
