"""``crlam slam``: run a particle filter on a CARMEN log or a ROS bag and write a self-describing run folder.

:func:`run_slam_log` reads the log, runs the filter and writes the folder through
:mod:`crlam.experiments.slam_outputs` (which describes its files; its writers are re-exported
here).
"""

from __future__ import annotations

import math
import os
import sys
import time
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np
from numpy.typing import NDArray
from tqdm import tqdm

from crlam.errors import ConfigError, DataFormatError
from crlam.experiments.progress import scan_progress_bar
from crlam.experiments.slam_outputs import (
    ESTIMATES,
    SlamResult,
    peak_rss_mb,
    write_run_outputs,
    write_run_readme,
    write_slam_outputs,
    write_toml,
)
from crlam.experiments.slam_outputs import (
    _jsonable as _jsonable,  # re-exported: localize_run and localize_trials import it from here
)
from crlam.io.carmen import LaserScan
from crlam.io.logs import open_log
from crlam.io.readings import ReadingFilter
from crlam.preflight.lidar_check import LidarSetup
from crlam.slam import SlamConfig, SlamRun
from crlam.slam.prior import SlamPrior

if TYPE_CHECKING:
    from crlam.slam.motion_noise import MotionNoiseEstimate
    from crlam.slam.time_offset import TimeOffsetEstimate

# The run folder's writers live in crlam.experiments.slam_outputs; re-exported here, where the
# run's callers (localize_run, the ROS SLAM node, the benches) import them from.
__all__ = [
    "ESTIMATES",
    "SlamResult",
    "peak_rss_mb",
    "run_slam_log",
    "within_sensor_range",
    "write_run_readme",
    "write_slam_outputs",
    "write_toml",
]


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
    standard ROS 2 messages). ``odometry`` is the motion input (:mod:`crlam.slam.scan_odometry`):
    ``wheel`` (the log's odometry), ``scan_match`` (scan-matching odometry; the log's odometry is
    not read, and the filter takes :func:`~crlam.slam.scan_odometry.scan_match_filter_config`'s motion
    noise) or ``auto`` (``scan_match`` when the input has no odometry); ``config.toml`` and
    ``metrics.json`` record which was used and why. ``prior`` continues a saved run
    (:mod:`crlam.slam.prior`): its folder is only read, and must not be ``out_dir``.
    ``laser_mount`` is ``auto`` (check the mount against the odometry, :mod:`crlam.preflight.lidar_check`),
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
    from crlam.slam.scan_odometry import resolve_odometry, scan_match_filter_config

    source = resolve_odometry(log_path, odometry, bag_options)
    if source[0] == "scan_match":
        config = scan_match_filter_config(config)
    from crlam.preflight.lidar_check import check_lidar_of_log

    lidar = check_lidar_of_log(log_path, bag_options, laser_mount, config.body_mask, wheel=source[0] == "wheel")
    map_range = None
    if config.map_range == "readings":
        from dataclasses import replace

        from crlam.preflight.map_range import map_range_from_readings

        readings_log = open_log(log_path, **(bag_options or {}), **_scan_match_reading(log_path, source[0]))
        map_range = map_range_from_readings(lidar.corrected(readings_log), config.max_range, max_scans=max_scans)
        config = replace(config, max_range=map_range.max_range)
    from crlam.slam.time_offset import apply_time_offset, match_threads, report, resolve_time_offset

    fit_config = config

    def fit_noise(offset: TimeOffsetEstimate | None = None) -> MotionNoiseEstimate | None:
        if fit_config.motion_noise != "estimate" or fit_config.motion_params is not None:
            return None
        from crlam.slam.motion_noise import estimate_gmapping_noise

        records: Any = open_log(log_path, **(bag_options or {}))
        if offset is not None:
            records = apply_time_offset(records, offset)
        return estimate_gmapping_noise(
            lidar.corrected(records),
            linear_update=fit_config.linear_update,
            angular_update=fit_config.angular_update,
            max_range=fit_config.max_range,
            max_scans=max_scans,
            seed=fit_config.seed,
        )

    def find_offset() -> TimeOffsetEstimate:
        return resolve_time_offset(
            fit_config.time_offset, log_path, bag_options=bag_options, max_scans=max_scans, odometry=source[0]
        )

    # The odometry's noise is fitted to the odometry the filter reads: re-attached at the
    # corrected stamps when the offset is applied (fitted to the odometry as the log attaches
    # it, a laser lag's 0.15 s doubled Intel's fitted heading noise). With more than one thread
    # the fit to the log's odometry runs beside the offset's estimate, and is made again on the
    # re-attached odometry only when the offset turns out to be applied; on one thread the
    # estimate comes first. Either way the result is the same.
    if match_threads() > 1:
        from concurrent.futures import ThreadPoolExecutor

        with ThreadPoolExecutor(max_workers=1) as pool:
            noise_job = pool.submit(fit_noise)
            offset = find_offset()
            noise_estimate = noise_job.result()
        if offset.retimed:
            noise_estimate = fit_noise(offset)
    else:
        offset = find_offset()
        noise_estimate = fit_noise(offset if offset.retimed else None)
    if noise_estimate is not None:
        from dataclasses import replace

        config = replace(config, motion_params=noise_estimate.params)
        if progress or not noise_estimate.fitted:
            print(noise_estimate.describe(), file=sys.stderr)
    if progress or (config.time_offset == "auto" and not offset.identified and source[0] != "scan_match"):
        report(offset)
    reader = open_log(log_path, **(bag_options or {}), **_scan_match_reading(log_path, source[0]))
    records: Any = apply_time_offset(reader, offset)
    front_end = None
    if source[0] == "scan_match":
        from crlam.slam.scan_odometry import ScanMatchOdometry, ScanOdometryConfig, scan_match_odometry

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
    return write_run_outputs(
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
        release_maps=True,
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


"""What each trajectory file of a run folder holds (the lines of its ``README.txt``)."""
