"""``crlam bench``'s whole-pipeline SLAM figures: the default filter on a real-log-like workload.

The micro-benchmarks of :mod:`crlam.bench` time the core's loops on synthetic scans within 8 m.
A real log differs: a SICK-style laser (180 beams over 180 deg) sees up to 80 m, so the default
preset matches and weighs readings beyond its 8 m map range (``match_range = "full"``), the
update triggers skip most scans, and the run reads and parses the log. These figures run
``crlam slam``'s own pipeline (:func:`crlam.experiments.slam_run.run_slam_log`) on a simulated
log of that kind:

Workload
    The museum world (90 m x 90 m, world seed 0), the ``sick`` sensor preset (180 beams over
    180 deg, 80 m, 1 cm noise), 10 scans per second, seed 0; 2,000 scans (200 with ``quick``).
    The log is simulated once per process and written as a CARMEN file.
Runs
    The default preset (``robust``, 30 particles) and, as the same run's baseline, RBPF-OGM in
    GMapping's setting (hit-mean cells, odometry drawn at every scan, 0.05 m, 80 m, 1 m / 0.5 rad
    triggers: the setting BENCHMARKS.md compares on Intel, with its map-cell limit raised to
    10^8 as there: its 80 m maps outgrow the default 16 million cells). Each runs in a fresh
    ``spawn`` process, so that its peak resident memory is its own, on one thread; the default
    runs once more on two threads (``RAYON_NUM_THREADS=2``: the particles' updates in parallel).

Figures: log scans per second of wall time (the whole run: reading, filtering, writing the
trajectory), its peak resident memory (MB: the whole command's, the run folder's files and
``trajectory.png`` included), the ratio of the two filters' speeds, and the default run's whole
command's peak against the filter's own (``command_peak_rss_mb / filter_peak_rss_mb`` of its
``metrics.json``: what writing the map and the figure adds), and the two-thread run's wall time
over the one-thread run's (the target is 0.6 or less: two cores should nearly halve the filter's
share of the run).
"""

from __future__ import annotations

import multiprocessing
import os
import tempfile
import time
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path
from typing import Any

__all__ = ["SLAM_BENCHES", "slam_pipeline_figures"]

SLAM_BENCHES = (
    "slam_default_scans_per_s_sick",
    "slam_default_peak_rss_mb_sick",
    "slam_ogm_gmapping_scans_per_s_sick",
    "slam_ogm_gmapping_peak_rss_mb_sick",
    "slam_default_over_ogm_gmapping_sick",
    "slam_default_command_over_filter_rss_sick",
    "slam_default_two_threads_scans_per_s_sick",
    "slam_default_two_threads_time_over_one_sick",
)
"""The figures :func:`slam_pipeline_figures` returns (``crlam bench --only`` takes any of them)."""

N_SCANS = 2000
QUICK_SCANS = 200

#: RBPF-OGM in GMapping's setting, as BENCHMARKS.md runs it on Intel (SlamConfig fields over the
#: ``paper`` preset).
OGM_GMAPPING = {
    "method": "ogm",
    "ogm_map": "gmapping",
    "motion": "gmapping",
    "ogm_motion_draws": "per_scan",
    "particles": 30,
    "resolution": 0.05,
    "max_range": 80.0,
    "linear_update": 1.0,
    "angular_update": 0.5,
}


def _simulate(folder: Path, n_scans: int) -> tuple[Path, float]:
    """The workload's CARMEN log, and the share of its returned readings beyond 8 m."""
    import numpy as np

    from crlam.sim.simulate import SimulationConfig, simulate, write_simulation

    log = simulate(SimulationConfig(world="museum", n_scans=n_scans, seed=0, world_seed=0, sensor="sick"))
    returned = log.ranges[log.ranges < log.sensor.max_range]
    far = float(np.mean(returned > 8.0)) if returned.size else 0.0
    return Path(write_simulation(log, folder)["carmen"]), far


#: Map cells allowed to the GMapping-setting run (BENCHMARKS.md's Intel command: --max-map-cells 1e8).
OGM_GMAPPING_MAX_MAP_CELLS = 100_000_000


def _run_in_child(
    log: str, out: str, preset: str, overrides: dict[str, Any], max_map_cells: int | None, threads: int
) -> dict[str, Any]:
    """One whole ``crlam slam`` run (in a spawned process): its metrics and CPU seconds."""
    # Read when the core's thread pool starts, at the run's first parallel update.
    os.environ["RAYON_NUM_THREADS"] = str(threads)
    from dataclasses import replace

    from crlam.experiments.slam_run import run_slam_log
    from crlam.limits import set_limits
    from crlam.slam import SlamConfig

    if max_map_cells is not None:
        set_limits(map_cells=max_map_cells)
    config = replace(SlamConfig.from_preset(preset), **overrides)
    cpu0 = time.process_time()
    # With the figures: the peaks are those of the whole command as a user runs it.
    result = run_slam_log(log, out, config, progress=False, figures=True)
    m = result.metrics
    return {
        "cpu_seconds": time.process_time() - cpu0,
        "wall_time_s": float(m["wall_time_s"]),
        "peak_rss_mb": float(m["command_peak_rss_mb"]),
        "filter_peak_rss_mb": float(m["filter_peak_rss_mb"]),
        "n_scans": int(m["n_scans"]),
        "n_processed": int(m["n_processed"]),
    }


def _timed_run(
    log: Path, out: Path, preset: str, overrides: dict[str, Any], max_map_cells: int | None, threads: int
) -> dict[str, Any]:
    ctx = multiprocessing.get_context("spawn")  # a forked child of a rayon process can hang
    with ProcessPoolExecutor(max_workers=1, mp_context=ctx) as pool:
        return pool.submit(_run_in_child, str(log), str(out), preset, overrides, max_map_cells, threads).result()


def slam_pipeline_figures(*, quick: bool = False, repeats: int = 1) -> tuple[dict[str, float], dict[str, Any]]:
    """The figures of :data:`SLAM_BENCHES` and their details (best of ``repeats`` runs each).

    Returns
    -------
    figures : dict
        ``slam_default_scans_per_s_sick`` and ``slam_ogm_gmapping_scans_per_s_sick`` (log scans
        per second of wall time), ``slam_default_peak_rss_mb_sick`` and
        ``slam_ogm_gmapping_peak_rss_mb_sick`` (MB), and
        ``slam_default_over_ogm_gmapping_sick`` (the ratio of the two speeds, this run), and
        ``slam_default_command_over_filter_rss_sick`` (the default run's whole command's peak
        memory over its filter's), ``slam_default_two_threads_scans_per_s_sick`` and
        ``slam_default_two_threads_time_over_one_sick`` (the default on two threads: its speed,
        and its wall time over the one-thread run's).
    details : dict
        Per filter: scans, processed scans, wall and CPU seconds, scans per CPU second, peak RSS,
        the settings.
    """
    n = QUICK_SCANS if quick else N_SCANS
    runs = {
        "slam_default": ("robust", {}, None, 1),
        "slam_ogm_gmapping": ("paper", OGM_GMAPPING, OGM_GMAPPING_MAX_MAP_CELLS, 1),
        "slam_default_two_threads": ("robust", {}, None, 2),
    }
    details: dict[str, Any] = {}
    with tempfile.TemporaryDirectory(prefix="crlam-bench-") as tmp:
        log, far = _simulate(Path(tmp) / "sim", n)
        for name, (preset, overrides, max_map_cells, threads) in runs.items():
            best: dict[str, Any] | None = None
            for k in range(max(1, repeats)):
                r = _timed_run(log, Path(tmp) / f"{name}_{k}", preset, overrides, max_map_cells, threads)
                if best is None or r["wall_time_s"] < best["wall_time_s"]:
                    best = r
            assert best is not None
            best["scans_per_s"] = best["n_scans"] / best["wall_time_s"]
            best["scans_per_cpu_s"] = best["n_scans"] / best["cpu_seconds"] if best["cpu_seconds"] > 0 else float("nan")
            best["settings"] = {"preset": preset, **overrides}
            if max_map_cells is not None:
                best["max_map_cells"] = max_map_cells
            best["workload"] = f"museum world, sick sensor (180 beams, 180 deg, 80 m), {n} scans, seed 0"
            best["returned_readings_beyond_8m"] = round(far, 3)
            best["repeats"] = repeats
            best["threads"] = threads
            details[name] = best
    d, o, t = details["slam_default"], details["slam_ogm_gmapping"], details["slam_default_two_threads"]
    figures = {
        "slam_default_scans_per_s_sick": round(d["scans_per_s"], 1),
        "slam_default_peak_rss_mb_sick": round(d["peak_rss_mb"], 1),
        "slam_ogm_gmapping_scans_per_s_sick": round(o["scans_per_s"], 1),
        "slam_ogm_gmapping_peak_rss_mb_sick": round(o["peak_rss_mb"], 1),
        "slam_default_over_ogm_gmapping_sick": round(d["scans_per_s"] / o["scans_per_s"], 2),
        "slam_default_command_over_filter_rss_sick": round(d["peak_rss_mb"] / d["filter_peak_rss_mb"], 2),
        "slam_default_two_threads_scans_per_s_sick": round(t["scans_per_s"], 1),
        "slam_default_two_threads_time_over_one_sick": round(t["wall_time_s"] / d["wall_time_s"], 2),
    }
    return figures, details
