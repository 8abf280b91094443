"""``crlam localize``: Monte Carlo localization of a CARMEN log or a ROS bag on a fixed map, written
to a run folder like ``crlam slam``'s.

The folder holds ``config.toml`` (``[run]``: the log, the map and the start; ``[input]``: how the
log was read; ``[localize]``: every :class:`crlam.localize.LocalizeConfig` field), ``trajectory.tum``
(one pose per laser scan, file order, stamped with the scan's time), ``particles.csv`` (per
processed scan: the particle count before and after resampling, N_eff, the random particles of
recovery, the fit, the heaviest cluster's weight and spread, the estimate, whether the
convergence criterion held, the distance travelled, and the share of the scan's beam endpoints
within 0.1 m of an occupied cell of the map), ``metrics.json`` (written last: its presence marks a
finished run) and ``localization.png`` (the estimate over the map, the particle count and spread
against time).
"""

from __future__ import annotations

import csv
import json
import math
import os
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Literal

import numpy as np
from numpy.typing import NDArray

from crlam import __version__
from crlam.errors import DataFormatError
from crlam.experiments.progress import scan_progress_bar
from crlam.experiments.slam_run import _jsonable, _scan_inputs, peak_rss_mb, write_toml
from crlam.io.carmen import LaserScan
from crlam.io.logs import input_description, open_log
from crlam.io.relations import read_relations
from crlam.io.tum import read_tum, write_tum
from crlam.localize import LocalizeConfig, Localizer, LocalizeStep
from crlam.localize.map import LocalizationMap, Nav2Prior, load_localization_map

__all__ = ["LocalizeResult", "ENDPOINT_DISTANCE", "endpoint_fractions", "run_localize_log"]

ENDPOINT_DISTANCE = 0.1
"""Beam endpoints within this distance (m) of an occupied cell count as on the map's walls."""

OCCUPIED = 0.5
"""Cells with m̂ at or above this are occupied for the endpoint statistic."""


@dataclass
class LocalizeResult:
    """What :func:`run_localize_log` produced."""

    localizer: Localizer
    metrics: dict[str, Any]
    out_dir: Path


class EndpointCounter:
    """Share of a scan's beam endpoints (readings below the maximum range) within
    :data:`ENDPOINT_DISTANCE` of an occupied cell of the map, from a pose."""

    def __init__(self, localizer: Localizer) -> None:
        assert localizer.filter is not None
        self.dist = np.asarray(localizer.filter.occupied_distance(OCCUPIED))
        m = localizer.map
        res, (ox, oy) = m.crm.config.resolution, m.crm.config.origin
        ix0, iy0, _, _ = m.rect
        self.res = res
        self.origin = (ox + ix0 * res, oy + iy0 * res)

    def fraction(self, pose: NDArray[np.float64], scan: LaserScan) -> tuple[int, int]:
        """(endpoints near an occupied cell, endpoints) of ``scan`` seen from robot pose ``pose``."""
        ok = np.isfinite(scan.ranges) & (scan.ranges < scan.max_range) & (scan.ranges > 0)
        r, a = scan.ranges[ok], scan.angles[ok]
        if r.size == 0:
            return 0, 0
        off = scan.laser_offset
        c, s = math.cos(pose[2]), math.sin(pose[2])
        lx = pose[0] + c * off[0] - s * off[1]
        ly = pose[1] + s * off[0] + c * off[1]
        th = pose[2] + off[2] + a
        ex, ey = lx + r * np.cos(th), ly + r * np.sin(th)
        ix = np.floor((ex - self.origin[0]) / self.res).astype(np.int64)
        iy = np.floor((ey - self.origin[1]) / self.res).astype(np.int64)
        ny, nx = self.dist.shape
        inside = (ix >= 0) & (ix < nx) & (iy >= 0) & (iy < ny)
        near = np.zeros(r.size, dtype=bool)
        near[inside] = self.dist[iy[inside], ix[inside]] <= ENDPOINT_DISTANCE
        return int(near.sum()), int(r.size)


def endpoint_fractions(near: NDArray[np.int64], total: NDArray[np.int64], split: int | None) -> dict[str, float | None]:
    """Pooled shares of endpoints near an occupied cell over the scans before ``split`` and from
    it on (every scan when ``split`` is None: all after)."""

    def share(sl: slice) -> float | None:
        t = int(total[sl].sum())
        return None if t == 0 else float(near[sl].sum()) / t

    if split is None:
        return {"before_convergence": share(slice(0, len(near))), "after_convergence": None, "all": share(slice(None))}
    return {
        "before_convergence": share(slice(0, split)),
        "after_convergence": share(slice(split, None)),
        "all": share(slice(None)),
    }


PARTICLE_COLUMNS = (
    "scan_index",
    "stamp",
    "n_particles",
    "n_after",
    "neff",
    "resampled",
    "n_injected",
    "inject_probability",
    "fit",
    "tempering",
    "sigma_hit_m",
    "cluster_weight",
    "n_clusters",
    "spread_xy_m",
    "spread_theta_deg",
    "x",
    "y",
    "theta",
    "converged",
    "distance_m",
    "endpoints_near",
    "endpoints",
)


def write_particles_csv(path: Path, loc: Localizer, near: NDArray[np.int64], total: NDArray[np.int64]) -> None:
    """``particles.csv``: one row per processed scan (see the module docstring)."""
    dist = loc.distances
    with open(path, "w", newline="") as fh:
        w = csv.writer(fh)
        w.writerow(PARTICLE_COLUMNS)
        for s in loc.steps:
            if not s.processed:
                continue
            i = s.scan_index
            w.writerow(
                [
                    i,
                    f"{loc.stamps[i]:.6f}",
                    s.n_particles,
                    s.n_after,
                    f"{s.neff:.3f}",
                    int(s.resampled),
                    s.n_injected,
                    f"{s.inject_probability:.4f}",
                    f"{s.fit:.4f}",
                    f"{s.tempering:.4g}",
                    f"{s.sigma_hit:.4f}",
                    f"{s.cluster_weight:.4f}",
                    s.n_clusters,
                    f"{s.spread_xy:.4f}",
                    f"{math.degrees(s.spread_theta):.3f}",
                    *(f"{v:.5f}" for v in s.estimate),
                    int(s.converged),
                    f"{dist[i]:.3f}",
                    int(near[i]),
                    int(total[i]),
                ]
            )


def _stats(values: list[int]) -> dict[str, float]:
    a = np.asarray(values, dtype=np.float64)
    if a.size == 0:
        return {}
    return {"mean": float(a.mean()), "min": float(a.min()), "max": float(a.max()), "p95": float(np.percentile(a, 95))}


def run_localize_log(
    log_path: str | os.PathLike[str],
    map_path: str | os.PathLike[str],
    out_dir: str | os.PathLike[str],
    config: LocalizeConfig | None = None,
    *,
    initial_pose: NDArray[np.float64] | None = None,
    initial_cov: NDArray[np.float64] | None = None,
    nav2_prior: Nav2Prior | None = None,
    relations: str | os.PathLike[str] | None = None,
    reference: str | os.PathLike[str] | None = None,
    max_scans: int | None = None,
    progress: bool = True,
    figures: bool = True,
    bag_options: dict[str, Any] | None = None,
    time_offset: str | float = "auto",
    live_feed: Any = None,
) -> LocalizeResult:
    """Localizes the log's scans on the map and writes the run folder (module docstring).

    ``time_offset`` (``auto``, ``off`` or seconds) re-attaches the odometry at each scan's
    corrected stamp (:mod:`crlam.slam.time_offset`); ``metrics.json`` records it (``time_offset``).
    Without ``initial_pose`` the localization is global. ``relations`` (a Kuemmerle relations
    file) and ``reference`` (a TUM trajectory in the map's frame) add their errors to
    ``metrics.json``. ``live_feed`` (a :class:`crlam.experiments.slam_live_view.SlamLiveFeed`)
    serves the map, scans, particles and pose on a Foxglove WebSocket while the run goes.
    """
    config = config or LocalizeConfig()
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    loc_map = load_localization_map(map_path, nav2_prior=nav2_prior)
    from crlam.slam.time_offset import apply_time_offset, report, resolve_time_offset

    offset = resolve_time_offset(time_offset, log_path, bag_options=bag_options, max_scans=max_scans)
    if progress or (time_offset == "auto" and not offset.identified):
        report(offset)
    reader = open_log(log_path, **(bag_options or {}))
    records = apply_time_offset(reader, offset)
    t0, c0 = time.perf_counter(), time.process_time()
    loc: Localizer | None = None
    endpoints: EndpointCounter | None = None
    near: list[int] = []
    total: list[int] = []
    bar = scan_progress_bar(
        log_path, desc=f"localize {Path(log_path).name}", progress=progress, max_scans=max_scans, bag_options=bag_options
    )
    for rec in records:
        if not isinstance(rec, LaserScan):
            continue
        if loc is None:
            loc = Localizer(loc_map, config, initial_pose=initial_pose, initial_cov=initial_cov, laser_max_range=rec.max_range)
            endpoints = EndpointCounter(loc)
            if live_feed is not None:
                live_feed.publish_known_map(loc_map.expected_occupancy())
        if max_scans is not None and loc.n_scans >= max_scans:
            break
        angles, ranges = _scan_inputs(rec)
        step = loc.step(rec.odom, angles, ranges, rec.laser_offset, rec.timestamp)
        if live_feed is not None:
            particles = np.asarray(loc.particles()[0], dtype=np.float64) if step.processed else None
            live_feed.scan(loc, rec, step.processed, step.estimate, particles, spread=(step.spread_xy, step.spread_theta))
        assert endpoints is not None
        k, n = endpoints.fraction(step.estimate, rec) if step.processed else (0, 0)
        near.append(k)
        total.append(n)
        bar.update(1)
    bar.close()
    wall, cpu = time.perf_counter() - t0, time.process_time() - c0
    if loc is None or loc.n_scans == 0:
        raise DataFormatError("the log holds no laser scans", path=str(log_path))
    near_a, total_a = np.asarray(near, dtype=np.int64), np.asarray(total, dtype=np.int64)
    metrics = _metrics(loc, loc_map, log_path, wall, cpu, near_a, total_a, initial_pose, initial_cov, reader)
    metrics["time_offset"] = offset.to_dict()
    stamps, poses = loc.trajectory()
    # Sorted by time like slam's (a CARMEN log's file order need not be; evo and the TUM
    # readers expect increasing stamps). A stable sort keeps the file order of equal stamps.
    order = np.argsort(stamps, kind="stable")
    stamps, poses = np.asarray(stamps)[order], np.asarray(poses)[order]
    if live_feed is not None:
        live_feed.finish_path(stamps, poses)
    mode = "global" if initial_pose is None else "initial pose"
    write_tum(
        out / "trajectory.tum", stamps, poses, header=f"crlam localize ({mode}) of {Path(log_path).name} on {loc_map.source}"
    )
    write_particles_csv(out / "particles.csv", loc, near_a, total_a)
    ref_poses = None
    if reference is not None:
        from crlam.eval.trajectory import reference_errors

        ref = read_tum(reference)
        errs = reference_errors(stamps, poses, ref.timestamps, ref.poses)
        metrics["reference"] = {"path": str(reference), **errs.summary()}
        ref_poses = ref.poses
    if relations is not None:
        from crlam.eval.trajectory import relations_error

        on_missing: Literal["raise", "skip"] = "skip" if max_scans else "raise"
        rel = relations_error(stamps, poses, read_relations(relations), on_missing=on_missing)
        metrics["relations"] = {"path": str(relations), **rel.summary()}
    write_toml(
        out / "config.toml",
        {
            "run": {
                "log": str(log_path),
                "map": str(map_path),
                "initial_pose": None if initial_pose is None else [float(v) for v in np.asarray(initial_pose).reshape(3)],
                "initial_cov": None if initial_cov is None else [float(v) for v in np.asarray(initial_cov).reshape(-1)],
                "relations": str(relations) if relations else None,
                "reference": str(reference) if reference else None,
                "max_scans": max_scans,
                "crlam_version": __version__,
            },
            "input": input_description(reader),
            "localize": {k: (list(v) if isinstance(v, tuple) else v) for k, v in config.to_dict().items()},
            "nav2_prior": {} if nav2_prior is None else nav2_prior.__dict__,
        },
    )
    if figures:
        from crlam.viz.localization import save_localization_figure

        save_localization_figure(
            out / "localization.png", loc, reference=ref_poses, title=f"{Path(log_path).name} on {Path(loc_map.source).name}"
        )
    tmp = out / "metrics.json.tmp"
    tmp.write_text(json.dumps(metrics, indent=2, sort_keys=True, default=_jsonable) + "\n")
    tmp.replace(out / "metrics.json")
    return LocalizeResult(loc, metrics, out)


def _metrics(
    loc: Localizer,
    loc_map: LocalizationMap,
    log_path: str | os.PathLike[str],
    wall: float,
    cpu: float,
    near: NDArray[np.int64],
    total: NDArray[np.int64],
    initial_pose: NDArray[np.float64] | None,
    initial_cov: NDArray[np.float64] | None,
    reader: Any,
) -> dict[str, Any]:
    processed: list[LocalizeStep] = [s for s in loc.steps if s.processed]
    conv = loc.convergence
    model = loc.model
    return {
        "crlam_version": __version__,
        "log": str(log_path),
        "map": loc_map.description,
        "mode": "global" if initial_pose is None else "initial pose",
        "initial_pose": None if initial_pose is None else np.asarray(initial_pose).reshape(3).tolist(),
        "initial_cov": None if initial_cov is None else np.asarray(initial_cov).tolist(),
        "seed": loc.config.seed,
        "wall_time_s": wall,
        "cpu_time_s": cpu,
        "scans_per_s": loc.n_scans / max(wall, 1e-9),
        "log_duration_s": float(loc.stamps[-1] - loc.stamps[0]),
        "peak_rss_mb": peak_rss_mb(),
        "n_scans": loc.n_scans,
        "n_processed": len(processed),
        "distance_m": loc.distance_travelled,
        "particles": _stats([s.n_particles for s in processed]),
        "n_injected": int(sum(s.n_injected for s in processed)),
        "convergence": None
        if conv is None
        else {"scan_index": conv.scan_index, "time_s": conv.time_s, "distance_m": conv.distance_m, "rule": _rule(loc.config)},
        "endpoints_within_0.1m": endpoint_fractions(near, total, None if conv is None else conv.scan_index),
        "sensor_model": {
            "kind": model.kind,
            "z_max": model.z_max,
            "sigma_hit": model.sigma_hit,
            "w": [model.w_hit, model.w_short, model.w_max, model.w_rand],
            "lambda_short": model.lambda_short,
            "cause_kernel": model.cause_kernel,
        },
        "measurement_model": loc.config.model,
        "likelihood_error": _likelihood_error(loc.config),
        "estimate_rule": "the weighted mean of the heaviest cluster of the weighted particles (AMCL's); between processed "
        "scans, the last one composed with the raw-odometry increment",
        "input": input_description(reader),
    }


def _likelihood_error(c: LocalizeConfig) -> str:
    """What the run's likelihood leaves out, against the exact CRM likelihood of every beam."""
    beams = "every beam" if c.max_beams == 0 else f"at most {c.max_beams} beams of each scan, spread evenly"
    if c.model == "crm-exact":
        return "each beam's log-likelihood to rounding (tail tolerance 2^-60), every beam"
    if c.model == "crm":
        return (
            f"each beam's log-likelihood is low by less than tail_tolerance = {c.tail_tolerance:g} "
            f"(its walk stops once the rest of the ray can change it by less; never high); {beams}"
        )
    return f"AMCL's {c.model} model (not the CRM likelihood); {beams}"


def _rule(c: LocalizeConfig) -> str:
    return (
        f"from the first processed scan of {c.convergence_hold} in a row where the heaviest cluster holds >= "
        f"{c.convergence_weight:g} of the weight with position spread <= {c.convergence_xy:g} m and heading spread <= "
        f"{math.degrees(c.convergence_theta):.1f} deg"
        + (f", >= {c.convergence_odds:g} times the second-heaviest cluster's weight" if c.convergence_odds > 1 else "")
    )
