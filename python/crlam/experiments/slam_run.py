"""``crlam slam``: run a particle filter on a CARMEN log or a ROS bag and write a self-describing run folder.

The folder holds ``config.toml`` (every resolved setting: the ``[input]`` table says how the log
was read (for a bag: the topics, frames and laser mount used), the ``[slam]`` table has every
:class:`crlam.slam.SlamConfig` field and the preset they were resolved from, so
``crlam slam --config DIR/config.toml`` runs the same configuration again), ``trajectory.tum`` (the filter's
estimate: one pose per laser scan, sorted by time, stamped with the scan's timestamp),
``metrics.json``, ``README.txt`` (one line per file), ``estimates/`` with the other estimates
(:data:`ESTIMATES`: ``best_path.tum``, the final best particle's path, GMapping's trajectory,
``*_best_path`` errors; ``best_path_means.tum`` when the poses are drawn from a fitted proposal;
``max_weight.tum``; ``mode.tum``, :func:`crlam.slam.mode_seeking_pose` at each processed scan;
``smoothed.tum`` and ``smoothed_means.tum``, the lineage smoother of
:meth:`crlam.slam.SlamRun.smoothed_trajectory`; each with its ``reference_*`` / ``relations_*``
errors in ``metrics.json``), ``steps.csv``
(per processed scan: N_eff, resampling, the particle set's position and heading spread, the
weighted-mean, highest-weight and mode-seeking poses; their summary is
``particle_set`` in ``metrics.json``), ``map.pgm`` + ``map.yaml`` and ``belief.npz`` (the best
particle's map), ``trajectory.png`` (the trajectory over the map) and, with a reference,
``errors.png`` (error against time), with a relations file ``relations_errors.png`` (every
relation's error against the time of its first pose).
"""

from __future__ import annotations

import csv
import json
import math
import os
import resource
import sys
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Literal

import numpy as np
from numpy.typing import NDArray
from tqdm import tqdm

from crlam import __version__, _native
from crlam.errors import ConfigError, DataFormatError
from crlam.eval.trajectory import ReferenceErrors, RelationsErrors, reference_errors, relations_error
from crlam.experiments.progress import scan_progress_bar
from crlam.fill import fill_rule
from crlam.grid_alignment import into_map_frame
from crlam.io.carmen import LaserScan
from crlam.io.logs import input_description, open_log
from crlam.io.readings import ReadingFilter
from crlam.io.relations import read_relations
from crlam.io.tum import read_tum, write_tum
from crlam.lidar_check import LidarSetup
from crlam.map_range import MapRangeChoice
from crlam.motion_noise import MotionNoiseEstimate
from crlam.slam import SlamConfig, SlamRun
from crlam.slam_continue import SlamPrior, pose_covariance

__all__ = ["ESTIMATES", "SlamResult", "run_slam_log", "write_run_readme", "write_slam_outputs", "write_toml"]


@dataclass
class SlamResult:
    """What :func:`run_slam_log` produced."""

    run: SlamRun
    metrics: dict[str, Any]
    out_dir: Path


def _map_range_setting(map_range: MapRangeChoice | None, run_max_range: float) -> dict[str, Any]:
    """What config.toml records of z_max under ``map_range = "readings"``: the setting (the least
    z_max), not the outcome, so that the file repeats the rule and a sweep resumes with it; the
    chosen z_max is in metrics.json. A z_max cut to the sensor's own range stays cut."""
    return {} if map_range is None else {"max_range": min(map_range.floor, run_max_range)}


def correlative_front_end_record(run: SlamRun) -> dict[str, Any] | None:
    """What ``metrics.json`` records of the correlative front end: the processed scans it
    searched and those whose odometry increment its match corrected (``None`` when it is off)."""
    if run.config.front_end == "none" or not isinstance(run.filter, _native.ClamFilter):
        return None
    searched, corrected = run.filter.front_end_counts()
    return {
        "window": [float(v) for v in run.config.front_end_window],
        "searched": int(searched),
        "corrected": int(corrected),
    }


def peak_rss_mb() -> float:
    """Peak resident memory of this process (MB).

    On Linux this is ``VmHWM`` from ``/proc/self/status``: the high-water mark of this program's
    own memory since it started. ``ru_maxrss`` is not: a process started by ``fork`` (as the
    ``spawn`` workers of a sweep are, before their ``exec``) inherits the parent's peak, so a run
    started by a parent that had just simulated a large log reported the parent's memory. Other
    systems fall back to ``ru_maxrss``.
    """
    try:
        with open("/proc/self/status") as status:
            for line in status:
                if line.startswith("VmHWM:"):
                    return int(line.split()[1]) / 1024.0
    except (OSError, ValueError, IndexError):
        pass
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0


def _toml_plain(v: Any) -> Any:
    """``v`` with numpy scalars as Python numbers and tuples as lists (what tomli-w writes)."""
    if isinstance(v, (bool, np.bool_)):
        return bool(v)
    if isinstance(v, np.integer):
        return int(v)
    if isinstance(v, np.floating):
        return float(v)
    if isinstance(v, (list, tuple, np.ndarray)):
        return [_toml_plain(x) for x in v]
    if isinstance(v, dict):
        return {k: _toml_plain(x) for k, x in v.items() if x is not None}
    return v


def write_toml(path: Path, sections: dict[str, dict[str, Any]]) -> None:
    """A TOML file of ``[section]`` tables written with tomli-w.

    A None value cannot be a TOML value: it is written as the comment line ``# name = (unset)``
    at the end of its table, which :mod:`crlam.presets` and the sweeps read back as None (a key
    that is absent altogether means "the preset's value", which is not the same).
    """
    import tomli_w

    parts = []
    for name, table in sections.items():
        values = {k: _toml_plain(v) for k, v in table.items() if v is not None}
        unset = [f"# {k} = (unset)\n" for k, v in table.items() if v is None]
        text = tomli_w.dumps({name: values}) if values else f"[{name}]\n"
        parts.append(text + "".join(unset))
    path.write_text("\n".join(parts))


def _scan_inputs(scan: LaserScan, readings: ReadingFilter | None = None) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Beam bearings and ranges of a scan for a filter: the no-return policy and body mask of
    ``readings`` (:mod:`crlam.io.readings`) applied; without it (localization), readings at the
    sensor's own maximum become inf (the filter's z_max then makes every longer reading a
    no-return as well)."""
    if not np.all(np.isfinite(scan.odom)):
        raise DataFormatError(f"odometry pose {scan.odom.tolist()} is not finite", line=scan.line, field="odom")
    if readings is None:
        return scan.angles, np.where(scan.ranges >= scan.max_range, np.inf, scan.ranges)
    return readings.apply(scan.angles, scan.ranges, scan.max_range)


def within_sensor_range(config: SlamConfig, sensor_max_range: float) -> SlamConfig:
    """``config`` with z_max no longer than the sensor's own maximum range (m).

    A no-return clears the cells along its beam up to z_max; beyond what the sensor can see
    (a 3.5 m laser under an 8 m preset) that would map unseen space as free. The run's
    config.toml holds the z_max used, so ``--config`` repeats it.
    """
    if math.isfinite(sensor_max_range) and 0 < sensor_max_range < config.max_range:
        from dataclasses import replace

        return replace(config, max_range=float(sensor_max_range))
    return config


def run_slam_log(
    log_path: str | os.PathLike[str],
    out_dir: str | os.PathLike[str],
    config: SlamConfig | None = None,
    *,
    reference: str | os.PathLike[str] | None = None,
    relations: str | os.PathLike[str] | None = None,
    max_scans: int | None = None,
    progress: bool = True,
    figures: bool = True,
    bag_options: dict[str, Any] | None = None,
    mcap: bool = False,
    prior: SlamPrior | None = None,
    odometry: str = "auto",
    verbose: bool = False,
    laser_mount: str = "auto",
    live_feed: Any = None,
) -> SlamResult:
    """Runs ``config`` on a CARMEN log or a ROS bag and writes the run folder (see the module docstring).

    Without a ``config`` the run uses the default preset (``SlamConfig.from_preset()``, ``robust``).
    ``bag_options`` go to the bag reader (:func:`crlam.io.logs.open_log`: ``scan_topic``,
    ``odom_topic``, ``base_frame``, ``laser_mount``, ``upside_down``). ``mcap`` also writes
    ``run.mcap`` (:mod:`crlam.experiments.slam_mcap`: scans, TF, particles, path and map as
    standard ROS 2 messages). ``odometry`` is the motion input (:mod:`crlam.scan_odometry`):
    ``wheel`` (the log's odometry), ``scan_match`` (scan-matching odometry; the log's odometry is
    not read, and the filter takes :func:`~crlam.scan_odometry.scan_match_filter_config`'s motion
    noise) or ``auto`` (``scan_match`` when the input has no odometry); ``config.toml`` and
    ``metrics.json`` record which was used and why. ``prior`` continues a saved run
    (:mod:`crlam.slam_continue`): its folder is only read, and must not be ``out_dir``.
    ``laser_mount`` is ``auto`` (check the mount against the odometry, :mod:`crlam.lidar_check`),
    ``data`` (the data's mount unchecked) or ``given`` (set by ``bag_options``); with
    ``config.body_mask = "auto"`` the body beams are found by the same pre-pass. ``live_feed``
    (a :class:`crlam.experiments.slam_live_view.SlamLiveFeed`) serves the run on a Foxglove
    WebSocket while it runs, and its final map once the run folder is written."""
    if config is None:
        config = SlamConfig.from_preset()
    out = Path(out_dir)
    if prior is not None and out.resolve() == Path(prior.source).resolve():
        raise ConfigError(f"--out {out} is the run being continued: write the continued run to a new folder")
    out.mkdir(parents=True, exist_ok=True)
    # The wall time includes the odometry-noise pre-pass, which is part of the run.
    t0 = time.perf_counter()
    from crlam.scan_odometry import resolve_odometry, scan_match_filter_config

    source = resolve_odometry(log_path, odometry, bag_options)
    if source[0] == "scan_match":
        config = scan_match_filter_config(config)
    from crlam.lidar_check import check_lidar_of_log

    lidar = check_lidar_of_log(log_path, bag_options, laser_mount, config.body_mask, wheel=source[0] == "wheel")
    map_range = None
    if config.map_range == "readings":
        from dataclasses import replace

        from crlam.map_range import map_range_from_readings

        readings_log = open_log(log_path, **(bag_options or {}), **_scan_match_reading(log_path, source[0]))
        map_range = map_range_from_readings(lidar.corrected(readings_log), config.max_range, max_scans=max_scans)
        config = replace(config, max_range=map_range.max_range)
    noise_estimate = None
    if config.motion_noise == "estimate" and config.motion_params is None:
        from dataclasses import replace

        from crlam.motion_noise import estimate_gmapping_noise

        noise_estimate = estimate_gmapping_noise(
            lidar.corrected(open_log(log_path, **(bag_options or {}))),
            linear_update=config.linear_update,
            angular_update=config.angular_update,
            max_range=config.max_range,
            max_scans=max_scans,
            seed=config.seed,
        )
        config = replace(config, motion_params=noise_estimate.params)
        if progress or not noise_estimate.fitted:
            print(noise_estimate.describe(), file=sys.stderr)
    from crlam.time_offset import apply_time_offset, report, resolve_time_offset

    offset = resolve_time_offset(config.time_offset, log_path, bag_options=bag_options, max_scans=max_scans, odometry=source[0])
    if progress or (config.time_offset == "auto" and not offset.identified and source[0] != "scan_match"):
        report(offset)
    reader = open_log(log_path, **(bag_options or {}), **_scan_match_reading(log_path, source[0]))
    records: Any = apply_time_offset(reader, offset)
    front_end = None
    if source[0] == "scan_match":
        from crlam.scan_odometry import ScanMatchOdometry, ScanOdometryConfig, scan_match_odometry

        front_end = ScanMatchOdometry(ScanOdometryConfig())
        records = scan_match_odometry(reader, front_end=front_end)
    recorder = None
    if mcap:
        from crlam.experiments.slam_mcap import SlamMcapRecorder

        recorder = SlamMcapRecorder(out / "run.mcap")
    try:
        run_wall = _run_filter(
            records,
            config,
            log_path,
            max_scans,
            progress,
            recorder,
            t0,
            prior,
            verbose,
            bag_options=bag_options,
            lidar=lidar,
            live_feed=live_feed,
        )
    except BaseException:
        if recorder is not None:
            recorder.close()
        raise
    odometry_info = {"odometry": source[0], "odometry_choice": source[1], "lidar": lidar.record()}
    return _write_outputs(
        run_wall,
        reader,
        log_path,
        out,
        reference,
        relations,
        max_scans,
        figures,
        recorder,
        noise_estimate,
        odometry_info,
        front_end,
        prior,
        offset.to_dict(),
        map_range=map_range,
        live_feed=live_feed,
    )


def _scan_match_reading(log_path: str | os.PathLike[str], source: str) -> dict[str, Any]:
    """The reader options of scan-matching odometry: a bag's odometry is not read, its IMU is."""
    from crlam.io.rosbag import is_bag

    return {"odometry": False, "imu": True} if source == "scan_match" and is_bag(log_path) else {}


def _run_filter(
    reader: Any,
    config: SlamConfig,
    log_path: str | os.PathLike[str],
    max_scans: int | None,
    progress: bool,
    recorder: Any,
    t0: float,
    prior: SlamPrior | None = None,
    verbose: bool = False,
    *,
    bag_options: dict[str, Any] | None = None,
    lidar: LidarSetup | None = None,
    live_feed: Any = None,
) -> tuple[SlamRun, float]:
    """Feeds the log's scans to a filter for ``config``; returns the run and its wall time since ``t0`` (s).
    ``verbose`` prints a line per processed scan (estimate, N_eff, resampling)."""
    run: SlamRun | None = None
    bar = scan_progress_bar(
        log_path,
        desc=f"{config.method} x{config.particles} {Path(log_path).name}",
        progress=progress,
        max_scans=max_scans,
        bag_options=bag_options,
    )
    for rec in reader:
        if not isinstance(rec, LaserScan):
            continue
        if run is None:
            config = within_sensor_range(config, rec.max_range)
            run = SlamRun(config, prior=prior)
            readings = ReadingFilter(config.no_return, config.max_range, None if lidar is None else lidar.body_mask_for_scans())
        if max_scans is not None and run.n_scans >= max_scans:
            break
        if lidar is not None:
            rec = lidar.correct(rec)
        angles, ranges = _scan_inputs(rec, readings)
        step = run.step(rec.odom, angles, ranges, rec.laser_offset, rec.timestamp)
        if recorder is not None or live_feed is not None:
            assert run.filter is not None
            particles = np.asarray(run.filter.particle_poses(), dtype=np.float64) if step.processed else None
            if recorder is not None:
                recorder.scan(rec, step.processed, step.estimate, particles)
            if live_feed is not None:
                live_feed.scan(run, rec, step.processed, step.estimate, particles)
        if verbose and step.processed:
            x, y, th = (float(v) for v in step.estimate)
            tqdm.write(
                f"scan {run.n_scans - 1} t={rec.timestamp:.3f}: estimate ({x:.3f}, {y:.3f}, {th:.4f}), "
                f"N_eff {step.neff:.1f}{', resampled' if step.resampled else ''}",
                file=sys.stderr,
            )
        bar.update(1)
        if max_scans is not None and run.n_scans >= max_scans:
            break  # before the next record is read (a front end would match one scan more)
    bar.close()
    wall = time.perf_counter() - t0
    if run is None or run.n_scans == 0:
        raise DataFormatError("the log holds no laser scans", path=str(log_path))
    if lidar is not None:
        lidar.readings = readings.stats
    return run, wall


def _write_outputs(
    run_wall: tuple[SlamRun, float],
    reader: Any,
    log_path: str | os.PathLike[str],
    out: Path,
    reference: str | os.PathLike[str] | None,
    relations: str | os.PathLike[str] | None,
    max_scans: int | None,
    figures: bool,
    recorder: Any,
    noise_estimate: MotionNoiseEstimate | None = None,
    odometry_info: dict[str, Any] | None = None,
    front_end: Any = None,
    prior: SlamPrior | None = None,
    time_offset: dict[str, Any] | None = None,
    map_range: MapRangeChoice | None = None,
    live_feed: Any = None,
) -> SlamResult:
    run, wall = run_wall
    # The filter's own high-water mark: taken when filtering has finished, before any output.
    filter_peak_mb = peak_rss_mb()
    input_info = input_description(reader) | (odometry_info or {})
    config = run.config
    stamps, poses = run.trajectory()
    name = Path(log_path).name
    # Every trajectory file is sorted by time (evo and other tools expect increasing stamps; a log's
    # file order need not be). A stable sort keeps the file order of equal stamps.
    order = np.argsort(stamps, kind="stable")
    written: dict[str, str] = {}

    def save(rel: str, traj: NDArray[np.float64], header: str, what: str) -> None:
        (out / rel).parent.mkdir(parents=True, exist_ok=True)
        write_tum(out / rel, stamps[order], traj[order], header=header)
        written[rel] = what

    save("trajectory.tum", poses, f"crlam {config.method} trajectory of {name}", ESTIMATES["trajectory.tum"])
    _, path_poses = run.best_path_trajectory()
    save(
        "estimates/best_path.tum",
        path_poses,
        f"crlam {config.method} final best particle's path over {name}",
        ESTIMATES["estimates/best_path.tum"],
    )
    path_means = run.best_path_means_trajectory()
    means_poses = None if path_means is None else path_means[1]
    if means_poses is not None:
        save(
            "estimates/best_path_means.tum",
            means_poses,
            f"crlam {config.method} proposal means along the final best particle's path over {name}",
            ESTIMATES["estimates/best_path_means.tum"],
        )
    _, max_weight_poses = run.max_weight_trajectory()
    save(
        "estimates/max_weight.tum",
        max_weight_poses,
        f"crlam {config.method} highest-weight particle at each processed scan of {name}",
        ESTIMATES["estimates/max_weight.tum"],
    )
    _, mode_poses = run.mode_trajectory()
    save(
        "estimates/mode.tum",
        mode_poses,
        f"crlam {config.method} mode-seeking estimate (bandwidth {config.mode_bandwidth}) over {name}",
        ESTIMATES["estimates/mode.tum"],
    )
    smoothed = {}
    for suffix, use_means, what in (("", False, "poses"), ("_means", True, "proposal means")):
        traj = run.smoothed_trajectory(proposal_means=use_means)
        if traj is not None:
            smoothed[suffix] = traj[1]
            lag = "full" if config.smoothing_lag is None else f"lag {config.smoothing_lag}"
            rel = f"estimates/smoothed{suffix}.tum"
            save(rel, traj[1], f"crlam {config.method} lineage smoother ({lag}, {what}) over {name}", ESTIMATES[rel])
    write_particle_sets(out / "steps.csv", run)
    assert run.filter is not None
    mem_bytes, n_tiles, n_refs = run.filter.map_memory()
    metrics: dict[str, Any] = {
        "crlam_version": __version__,
        "log": str(log_path),
        "method": config.method,
        "particles": config.particles,
        "seed": config.seed,
        "wall_time_s": wall,
        "scans_per_s": run.n_scans / max(wall, 1e-9),
        "filter_peak_rss_mb": filter_peak_mb,
        "map_memory_mb": mem_bytes / 2**20,
        "map_tiles": {"distinct": n_tiles, "references": n_refs},
        "n_scans": run.n_scans,
        "n_processed": int(sum(run.processed)),
        "neff_mean": float(np.mean(run.neff)) if run.neff else float("nan"),
        "neff_min": float(np.min(run.neff)) if run.neff else float("nan"),
        "n_resamples": run.filter.n_resamples,
        "particle_set": particle_set_summary(run),
        "fill_rule": fill_rule(config.fill),
        "preset": config.preset,
        "deviations_from_paper": config.deviations(),
        "motion_noise_estimate": None if noise_estimate is None else noise_estimate.to_dict(),
        "input": input_info,
        "scan_odometry": None if front_end is None else front_end.config.to_dict() | front_end.stats.to_dict(),
        "continued_from": None if prior is None else prior.describe(),
        "map_frame": run.map_frame_record(),
        "correlative_front_end": correlative_front_end_record(run),
        "map_range": None if map_range is None else map_range.to_dict(),
        "time_offset": time_offset,
    }
    ref_poses = None
    rel_figure: dict[str, RelationsErrors] | None = None
    if reference is not None:
        ref = read_tum(reference)

        def ref_errors(traj: NDArray[np.float64]) -> ReferenceErrors:
            # The reference is in the odometry's frame: a turned map frame is turned back first.
            return reference_errors(stamps, run.to_odometry_frame(traj), ref.timestamps, ref.poses)

        errs = ref_errors(poses)
        metrics["reference"] = {"path": str(reference), **errs.summary()}
        metrics["reference_best_path"] = ref_errors(path_poses).summary()
        metrics["reference_max_weight"] = ref_errors(max_weight_poses).summary()
        metrics["reference_mode"] = ref_errors(mode_poses).summary()
        for suffix, sm_poses in smoothed.items():
            metrics[f"reference_smoothed{suffix}"] = ref_errors(sm_poses).summary()
        if means_poses is not None:
            metrics["reference_best_path_means"] = ref_errors(means_poses).summary()
        # Drawn over the map: the reference in the map's frame.
        ref_in_map = ref.poses if run.map_frame is None else into_map_frame(run.map_frame, ref.poses)
        ref_poses = (ref.timestamps, ref_in_map, errs)
    if relations is not None:
        # A run cut short by --max-scans cannot cover every relation; the others are counted.
        rels = read_relations(relations)
        on_missing: Literal["raise", "skip"] = "skip" if max_scans else "raise"
        rel_errors = relations_error(stamps, poses, rels, on_missing=on_missing)
        metrics["relations"] = {"path": str(relations), **rel_errors.summary()}
        rel_path = relations_error(stamps, path_poses, rels, on_missing=on_missing)
        metrics["relations_best_path"] = rel_path.summary()
        rel_max_weight = relations_error(stamps, max_weight_poses, rels, on_missing=on_missing)
        metrics["relations_max_weight"] = rel_max_weight.summary()
        rel_mode = relations_error(stamps, mode_poses, rels, on_missing=on_missing)
        metrics["relations_mode"] = rel_mode.summary()
        for suffix, sm_poses in smoothed.items():
            metrics[f"relations_smoothed{suffix}"] = relations_error(stamps, sm_poses, rels, on_missing=on_missing).summary()
        rel_figure = {
            f"RBPF-{config.method.upper()}, weighted mean": rel_errors,
            "mode-seeking": rel_mode,
            "best particle's path": rel_path,
            "highest-weight particle": rel_max_weight,
        }
        if means_poses is not None:
            rel_means = relations_error(stamps, means_poses, rels, on_missing=on_missing)
            metrics["relations_best_path_means"] = rel_means.summary()
            rel_figure["best path's proposal means"] = rel_means
    from crlam.experiments.map_outputs import map_products, write_belief_archive
    from crlam.experiments.slam_mcap import GridInfo
    from crlam.io.nav2 import write_nav2_image
    from crlam.mapping import ConfidenceRichMap

    # The map's files are read from the native map in bands of rows (crlam.experiments.map_outputs):
    # arrays over the whole bounding box of a campus-scale map would take several times the
    # filter's own memory.
    best = run.best_map()
    if isinstance(best, ConfidenceRichMap):
        # The final estimate and the spread of the last weighed set: what --continue starts from.
        estimate = np.array(poses[-1], dtype=np.float64)
        write_belief_archive(
            out / "belief.npz", best, estimate=estimate, estimate_cov=pose_covariance(*run.filter.weighed_set(), estimate)
        )
    products = map_products(best, grids=recorder is not None or live_feed is not None)
    del best
    if live_feed is not None:
        assert products.grid is not None
        live_feed.finish(
            stamps[order],
            poses[order],
            GridInfo(products.shape, products.origin, products.resolution),
            products.grid,
            products.confidence_grid,
        )
    if recorder is not None:
        try:
            assert products.grid is not None
            grid = GridInfo(products.shape, products.origin, products.resolution)
            topics = recorder.finish_grids(stamps, poses, grid, products.grid, products.confidence_grid)
            metrics["mcap"] = {"path": str(recorder.path), "topics": topics}
        except BaseException:
            recorder.close()
            raise
        products.grid = products.confidence_grid = None
    write_nav2_image(out / "map.pgm", products.nav2, resolution=products.resolution, origin=(*products.origin, 0.0))
    metrics["figure_map_stride"] = products.figure_stride
    write_toml(
        out / "config.toml",
        {
            "run": {
                "log": str(log_path),
                "reference": str(reference) if reference else None,
                "relations": str(relations) if relations else None,
                "max_scans": max_scans,
                "crlam_version": __version__,
                "continue": None if prior is None else prior.source,
            },
            "input": input_info,
            "slam": config.to_dict()
            | _map_range_setting(map_range, config.max_range)
            | {"sigma_hit_resolved": config.mapping_config().hit_sigma},
        }
        | ({} if front_end is None else {"scan_odometry": front_end.config.to_dict()}),
    )

    if figures:
        from crlam.viz.trajectories import save_error_figure, save_relations_error_figure, save_trajectory_figure

        save_trajectory_figure(
            out / "trajectory.png",
            products.figure_mean,
            products.figure_unknown,
            poses,
            reference=None if ref_poses is None else ref_poses[1],
            title=f"{Path(log_path).name}: RBPF-{config.method.upper()}, {config.particles} particles",
            label=f"RBPF-{config.method.upper()}",
        )
        if ref_poses is not None:
            save_error_figure(out / "errors.png", ref_poses[2], title=f"{Path(log_path).name}: error against the reference")
        if rel_figure is not None:
            save_relations_error_figure(
                out / "relations_errors.png",
                rel_figure,
                t0=float(stamps[0]),
                title=f"{Path(log_path).name}: RBPF-{config.method.upper()}, relations metric",
            )
    write_run_readme(out, written, figures=figures, reference=ref_poses is not None, relations=rel_figure is not None)
    # The whole command's high-water mark, outputs included (what /usr/bin/time -v reports).
    metrics["command_peak_rss_mb"] = metrics["peak_rss_mb"] = peak_rss_mb()
    # metrics.json is written last and atomically: its presence marks a finished run (sweeps resume).
    tmp = out / "metrics.json.tmp"
    tmp.write_text(json.dumps(metrics, indent=2, sort_keys=True, default=_jsonable) + "\n")
    tmp.replace(out / "metrics.json")
    return SlamResult(run, metrics, out)


def write_slam_outputs(
    run: SlamRun, wall: float, out: Path, *, source: str, input_info: dict[str, Any], figures: bool = True
) -> SlamResult:
    """Writes the run folder of a finished ``run`` fed by something other than a log file (a live
    ROS 2 node, :mod:`crlam.ros.slam_node`): ``source`` names the input, ``input_info`` is the
    ``[input]`` table (its keys replace those a log reader would give)."""
    out.mkdir(parents=True, exist_ok=True)
    return _write_outputs((run, wall), None, source, out, None, None, None, figures, None, odometry_info=input_info)


ESTIMATES = {
    "trajectory.tum": "the filter's estimate, one pose per laser scan sorted by time: the weighted mean of the "
    "particles at processed scans, carried by the odometry in between (use this one)",
    "estimates/best_path.tum": "the final best particle's path (the trajectory GMapping reports)",
    "estimates/best_path_means.tum": "the same lineage with each pose replaced by the mean of the proposal it was drawn from",
    "estimates/max_weight.tum": "the highest-weight particle at each processed scan, chosen online",
    "estimates/mode.tum": "mode-seeking estimate: the weighted mean of the densest group of particles",
    "estimates/smoothed.tum": "lineage smoother: each scan's weighted mean of the particles' ancestors (final weights, "
    "or --smoothing-lag)",
    "estimates/smoothed_means.tum": "the lineage smoother over the ancestors' proposal means",
}
"""What each trajectory file of a run folder holds (the lines of its ``README.txt``)."""


def write_run_readme(out: Path, written: dict[str, str], *, figures: bool, reference: bool, relations: bool) -> None:
    """``README.txt``: one line per file of the run folder saying what it holds."""
    rows = [*written.items()]
    rows += [
        ("config.toml", "every setting of the run; crlam slam LOG --config config.toml repeats it"),
        ("metrics.json", "timing, memory, particle-set summary and the errors of every trajectory"),
        ("steps.csv", "one row per processed scan: N_eff, resampling, particle spread, estimates"),
        ("map.pgm, map.yaml", "the best particle's map as a Nav2 map (opens in RViz)"),
    ]
    if (out / "belief.npz").exists():
        rows.append(("belief.npz", "the best particle's confidence-rich map, lossless (crlam.io.belief)"))
    if (out / "run.mcap").exists():
        rows.append(("run.mcap", "scans, TF, particles, path and map as ROS 2 messages (Foxglove, ros2 bag play)"))
    if figures:
        rows.append(("trajectory.png", "the trajectory over the map"))
        if reference:
            rows.append(("errors.png", "error against the reference over time"))
        if relations:
            rows.append(("relations_errors.png", "every relation's error against the time of its first pose"))
    width = max(len(k) for k, _ in rows)
    lines = ["crlam slam run folder: what each file holds", ""]
    lines += [f"{k:<{width}}  {v}" for k, v in rows]
    (out / "README.txt").write_text("\n".join(lines) + "\n", encoding="utf-8")


STEPS_COLUMNS = (
    "scan_index",
    "neff",
    "resampled",
    "spread_xy_m",
    "spread_theta_deg",
    "mean_x",
    "mean_y",
    "mean_theta",
    "max_weight_x",
    "max_weight_y",
    "max_weight_theta",
    "mode_x",
    "mode_y",
    "mode_theta",
)


def write_particle_sets(path: Path, run: SlamRun) -> None:
    """``steps.csv``: one row per processed scan with the particle set's summary
    (:class:`crlam.slam.ParticleSetRecord`; poses in m and rad)."""
    with open(path, "w", newline="") as fh:
        w = csv.writer(fh)
        w.writerow(STEPS_COLUMNS)
        for r in run.particle_sets:
            w.writerow(
                [
                    r.scan_index,
                    f"{r.neff:.4f}",
                    int(r.resampled),
                    f"{r.spread_xy:.6f}",
                    f"{math.degrees(r.spread_theta):.5f}",
                    *(f"{v:.6f}" for v in r.estimate),
                    *(f"{v:.6f}" for v in r.max_weight),
                    *(f"{v:.6f}" for v in r.mode),
                ]
            )


def particle_set_summary(run: SlamRun) -> dict[str, float]:
    """Spread of the particle set over the processed scans: mean, median and 95th percentile of the
    position spread (m) and the mean heading spread (deg)."""
    if not run.particle_sets:
        return {}
    xy = np.array([r.spread_xy for r in run.particle_sets])
    th = np.degrees([r.spread_theta for r in run.particle_sets])
    return {
        "spread_xy_mean_m": float(xy.mean()),
        "spread_xy_median_m": float(np.median(xy)),
        "spread_xy_p95_m": float(np.percentile(xy, 95)),
        "spread_theta_mean_deg": float(np.mean(th)),
    }


def _jsonable(o: object) -> object:
    if isinstance(o, (np.integer, np.floating)):
        return o.item()
    if isinstance(o, np.ndarray):
        return o.tolist()
    raise TypeError(f"not JSON serialisable: {type(o).__name__}")
