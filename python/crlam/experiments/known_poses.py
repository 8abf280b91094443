"""Mapping with known poses: a CARMEN log or a ROS bag in, a self-describing map folder out (``crlam map``).

The folder holds ``map.pgm``/``map.yaml`` (the CRM's expected occupancy as a Nav2 map),
``belief.npz`` (lossless beliefs), ``ogm.pgm``/``ogm.yaml`` (the log-odds baseline), ``map.png``
(expected occupancy and confidence side by side) and ``mapping.json`` (settings, counters and
timing).
"""

from __future__ import annotations

import json
import math
import os
import time
from collections.abc import Iterable, Iterator
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Literal

import numpy as np
from numpy.typing import NDArray
from tqdm import tqdm

from crlam.errors import ConfigError, DataFormatError
from crlam.experiments.map_outputs import PANEL_CELLS, UNKNOWN_ENTROPY_TOL, map_products, write_belief_archive
from crlam.io.carmen import LaserScan
from crlam.io.known_pose_scan import KnownPoseScan
from crlam.io.logs import count_scans, input_description, open_log
from crlam.io.nav2 import write_nav2_image
from crlam.io.readings import ReadingFilter
from crlam.mapping import ConfidenceRichMap, LogOddsConfig, LogOddsOccupancyMap, MapLayer, MappingConfig, ScanUpdateStats
from crlam.pose import compose

__all__ = [
    "PoseSource",
    "KnownPoseScan",
    "MappingRun",
    "sensor_pose",
    "known_pose_scans",
    "mapping_ranges",
    "map_scans",
    "map_log",
    "write_map_folder",
]

PoseSource = Literal["log", "odometry"]


def sensor_pose(scan: LaserScan, source: PoseSource) -> NDArray[np.float64]:
    """World pose of the laser for a scan.

    ``"log"`` trusts the logged pose field (the laser pose for FLASER/RLASER; the robot pose,
    to be composed with the laser offset, for ROBOTLASER1). ``"odometry"`` composes the
    odometry pose with the laser offset.
    """
    if source == "log":
        if scan.kind.startswith("ROBOTLASER"):
            return compose(scan.pose, scan.laser_offset)
        return scan.pose
    if source == "odometry":
        return compose(scan.odom, scan.laser_offset)
    raise ConfigError(f"pose source must be 'log' or 'odometry', got {source!r}")


def mapping_ranges(scan: LaserScan) -> NDArray[np.float64]:
    """The scan's ranges ``(n,)`` with no-returns as ``inf``: readings at or beyond the sensor's
    own maximum are no-returns whatever the map's z_max is."""
    return np.where(scan.ranges >= scan.max_range, np.inf, scan.ranges)


def known_pose_scans(
    reader: Iterable[object], source: PoseSource, readings: ReadingFilter | None = None
) -> Iterator[KnownPoseScan]:
    """Laser scans of a CARMEN record stream as :class:`KnownPoseScan` (odometry is skipped).

    A scan whose pose is not finite raises :class:`DataFormatError` naming its line. With
    ``readings`` its no-return policy (:mod:`crlam.io.readings`) decides the scan's beams;
    without, no-returns are ``inf`` (:func:`mapping_ranges`).
    """
    for rec in reader:
        if not isinstance(rec, LaserScan):
            continue
        pose = sensor_pose(rec, source)
        if not np.all(np.isfinite(pose)):
            raise DataFormatError(f"scan pose {pose.tolist()} is not finite", line=rec.line, field=f"{source} pose")
        if readings is None:
            yield KnownPoseScan(np.asarray(pose, dtype=np.float64), rec.angles, mapping_ranges(rec), rec.timestamp)
        else:
            angles, ranges = readings.apply(rec.angles, rec.ranges, rec.max_range)
            yield KnownPoseScan(np.asarray(pose, dtype=np.float64), angles, ranges, rec.timestamp)


@dataclass
class MappingRun:
    """Result of mapping a scan stream with known poses."""

    crm: ConfidenceRichMap
    ogm: LogOddsOccupancyMap
    poses: NDArray[np.float64]
    timestamps: NDArray[np.float64]
    wall_time_s: float
    stats: ScanUpdateStats = field(default_factory=ScanUpdateStats)

    @property
    def n_scans(self) -> int:
        return int(self.poses.shape[0])


def map_scans(
    scans: Iterable[KnownPoseScan],
    config: MappingConfig,
    *,
    ogm_config: LogOddsConfig | None = None,
    max_scans: int | None = None,
    progress: bool = True,
    desc: str = "mapping",
    total: int | None = None,
) -> MappingRun:
    """Builds a CRM and the log-odds baseline from scans with trusted poses. ``total``: the number
    of scans for the progress bar (default ``max_scans``)."""
    crm = ConfidenceRichMap(config)
    ogm = LogOddsOccupancyMap(
        ogm_config or LogOddsConfig(resolution=config.resolution, max_range=config.max_range, origin=config.origin)
    )
    poses: list[NDArray[np.float64]] = []
    stamps: list[float] = []
    t0 = time.perf_counter()
    bar = tqdm(
        total=max_scans if total is None else total, desc=desc, unit="scan", disable=not progress, leave=False, mininterval=1.0
    )
    for scan in scans:
        if max_scans is not None and len(poses) >= max_scans:
            break
        crm.update(scan.pose, scan.angles, scan.ranges)
        ogm.update(scan.pose, scan.angles, scan.ranges)
        poses.append(scan.pose)
        stamps.append(scan.timestamp)
        bar.update(1)
    bar.close()
    if not poses:
        raise DataFormatError("the log holds no laser scans to map")
    return MappingRun(crm, ogm, np.array(poses), np.array(stamps), time.perf_counter() - t0, crm.stats)


def unknown_mask(crm: ConfidenceRichMap, entropy: MapLayer) -> NDArray[np.bool_]:
    """Cells whose belief still equals the prior (never informed)."""
    p = crm.native.prior
    h_prior = float(-(p * np.log2(p)).sum())
    return np.abs(entropy.values - h_prior) < UNKNOWN_ENTROPY_TOL


def write_map_folder(
    run: MappingRun, out_dir: str | os.PathLike[str], *, title: str, extra: dict[str, object] | None = None
) -> dict[str, Path]:
    """Writes map.pgm/yaml, belief.npz, ogm.pgm/yaml, map.png and mapping.json.

    The maps are read from the native maps in bands of rows (:mod:`crlam.experiments.map_outputs`),
    so that writing takes little more memory than mapping did; ``mapping.json`` records both
    high-water marks (``mapping_peak_rss_mb`` before the files, ``command_peak_rss_mb`` after)."""
    from crlam.experiments.slam_run import peak_rss_mb
    from crlam.viz.maps import save_crm_figure

    mapping_peak_mb = peak_rss_mb()
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    crm = map_products(run.crm, figure_cells=PANEL_CELLS)
    write_nav2_image(out / "map.pgm", crm.nav2, resolution=crm.resolution, origin=(*crm.origin, 0.0))
    files = {"map.pgm": out / "map.pgm", "map.yaml": out / "map.yaml"}
    write_belief_archive(out / "belief.npz", run.crm)
    files["belief.npz"] = out / "belief.npz"
    ogm = map_products(run.ogm, figure_cells=PANEL_CELLS)
    write_nav2_image(out / "ogm.pgm", ogm.nav2, resolution=ogm.resolution, origin=(*ogm.origin, 0.0))
    del ogm
    files["ogm.pgm"], files["ogm.yaml"] = out / "ogm.pgm", out / "ogm.yaml"
    assert crm.figure_variance is not None
    files["map.png"] = save_crm_figure(
        out / "map.png", crm.figure_mean, crm.figure_variance, unknown=crm.figure_unknown, title=title, trajectory=run.poses
    )
    summary: dict[str, object] = {
        "title": title,
        "config": run.crm.config.to_dict(),
        "n_scans": run.n_scans,
        "wall_time_s": run.wall_time_s,
        "scans_per_s": run.n_scans / max(run.wall_time_s, 1e-9),
        "update_stats": run.stats.as_dict(),
        "map_cells": {
            "shape_yx": list(crm.shape),
            "origin": list(crm.origin),
            "n_known": crm.n_known,
            "n_occupied": crm.n_occupied,
            "n_free": crm.n_free,
        },
        "figure_map_stride": crm.figure_stride,
        "mapping_peak_rss_mb": mapping_peak_mb,
        "tiles": run.crm.native.tile_stats(),
    }
    if extra:
        summary.update(extra)
    summary["command_peak_rss_mb"] = peak_rss_mb()
    (out / "mapping.json").write_text(json.dumps(summary, indent=2, sort_keys=True, default=_jsonable) + "\n")
    files["mapping.json"] = out / "mapping.json"
    return files


def _jsonable(o: object) -> object:
    if isinstance(o, (np.integer, np.floating)):
        return o.item()
    if isinstance(o, np.ndarray):
        return o.tolist()
    if isinstance(o, float) and not math.isfinite(o):
        return str(o)
    raise TypeError(f"not JSON serialisable: {type(o).__name__}")


def map_log(
    log_path: str | os.PathLike[str],
    out_dir: str | os.PathLike[str],
    config: MappingConfig,
    *,
    poses: PoseSource = "log",
    on_error: Literal["raise", "skip"] = "raise",
    max_scans: int | None = None,
    progress: bool = True,
    bag_options: dict[str, Any] | None = None,
    no_return: str = "z_max",
) -> tuple[MappingRun, dict[str, Path]]:
    """``crlam map``: maps a CARMEN log or a ROS bag with trusted poses and writes the map folder.

    ``no_return`` is the no-return policy (:mod:`crlam.io.readings`): ``z_max`` (the spec's
    atom) or ``drop``; ``mapping.json`` records it and the beams it left out.

    A bag's scans carry the odometry pose (composed with the laser mount) in both pose fields, so
    ``poses`` makes no difference there; ``bag_options`` go to :func:`crlam.io.logs.open_log`."""
    reader = open_log(log_path, on_error=on_error, **(bag_options or {}))
    total = count_scans(log_path, max_scans, bag_options=bag_options) if progress else None
    readings = ReadingFilter(no_return, config.max_range)
    scans = known_pose_scans(reader, poses, readings)
    run = map_scans(scans, config, max_scans=max_scans, progress=progress, desc=Path(log_path).name, total=total)
    st = reader.stats
    extra: dict[str, object] = {
        "log": str(log_path),
        "pose_source": poses,
        "input": input_description(reader),
        "reader": {
            "records": st.records,
            "ignored": st.ignored,
            "unknown_kinds": st.unknown_kinds,
            "skipped_malformed": st.skipped_malformed,
            "malformed_examples": st.malformed_examples,
            "n_no_return_ranges": st.n_no_return_ranges,
            "n_nonfinite_ranges": st.n_nonfinite_ranges,
            "n_nonpositive_ranges": st.n_nonpositive_ranges,
        },
        "no_return": no_return,
        "readings": readings.stats.to_dict(),
    }
    files = write_map_folder(run, out_dir, title=f"{Path(log_path).name}: CRM ({config.model}), poses from {poses}", extra=extra)
    return run, files
