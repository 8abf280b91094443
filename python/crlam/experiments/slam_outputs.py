"""The run folder of ``crlam slam`` (:func:`crlam.experiments.slam_run.run_slam_log`): what a
finished :class:`~crlam.slam.SlamRun` writes, self-describing.

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
import sys
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Literal

import numpy as np
from numpy.typing import NDArray

from crlam import __version__, _native
from crlam.eval.odometry_travel import odometry_travel
from crlam.eval.trajectory import ReferenceErrors, RelationsErrors, reference_errors, relations_error
from crlam.io.logs import input_description
from crlam.io.relations import read_relations
from crlam.io.tum import read_tum, write_tum
from crlam.preflight.map_range import MapRangeChoice
from crlam.process_memory import peak_rss_mb
from crlam.slam import SlamRun
from crlam.slam.fill import fill_rule
from crlam.slam.grid_alignment import into_map_frame
from crlam.slam.motion_noise import MotionNoiseEstimate
from crlam.slam.prior import SlamPrior, pose_covariance

__all__ = [
    "ESTIMATES",
    "STEPS_COLUMNS",
    "SlamResult",
    "correlative_front_end_record",
    "degeneracy_record",
    "particle_set_summary",
    "peak_rss_mb",
    "write_particle_sets",
    "write_run_outputs",
    "write_run_readme",
    "write_slam_outputs",
    "write_toml",
]


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


def degeneracy_record(run: SlamRun) -> dict[str, Any] | None:
    """What ``metrics.json`` records of the degenerate scans: the setting and the processed scans
    whose geometry left a direction free (``None`` without the scan-match proposal)."""
    if run.config.proposal != "scan_match" or not isinstance(run.filter, _native.ClamFilter):
        return None
    return {"mode": run.config.degeneracy, "degenerate_scans": int(run.filter.degenerate_scans())}


def _odometry_travel_record(run: SlamRun, poses: NDArray[np.float64], input_info: dict[str, Any]) -> dict[str, Any] | None:
    """The estimate's travel against the wheel odometry's (:mod:`crlam.eval.odometry_travel`), with a
    warning on stderr when they disagree; None when the motion input is not a wheel odometry (a
    scan-matching odometry has no scale of its own to check against)."""
    if input_info.get("odometry") != "wheel" or len(run.odometry) != len(poses):
        return None
    travel = odometry_travel(poses, np.asarray(run.odometry))
    warning = travel.warning()
    if warning is not None:
        print(warning, file=sys.stderr)
    return travel.to_dict()


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
    at the end of its table, which :mod:`crlam.slam.presets` and the sweeps read back as None (a key
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


def write_run_outputs(
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
    release_maps: bool = False,
) -> SlamResult:
    """Writes the run folder of a finished run (see the module docstring) and returns its result.

    ``release_maps`` frees the particles' maps once the map's files are written and before the
    figures are drawn (:meth:`SlamRun.release_maps`): a command that ends with the run keeps its
    peak near the filter's own; a caller that goes on mapping (a live node saving its map) keeps
    them.
    """
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
    if run.loops is not None and run.loops.reanchors > 0:
        _, online_poses = run.online_trajectory()
        save(
            "estimates/online.tum",
            online_poses,
            f"crlam {config.method} weighted-mean estimates as they stood online, before loop closing's corrections, over {name}",
            ESTIMATES["estimates/online.tum"],
        )
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
        "loop_closing": None if run.loops is None else run.loops.record(),
        "preset": config.preset,
        "deviations_from_paper": config.deviations(),
        "motion_noise_estimate": None if noise_estimate is None else noise_estimate.to_dict(),
        "input": input_info,
        "scan_odometry": None if front_end is None else front_end.config.to_dict() | front_end.stats.to_dict(),
        "continued_from": None if prior is None else prior.describe(),
        "map_frame": run.map_frame_record(),
        "correlative_front_end": correlative_front_end_record(run),
        "degeneracy": degeneracy_record(run),
        "map_range": None if map_range is None else map_range.to_dict(),
        "time_offset": time_offset,
        "odometry_travel": _odometry_travel_record(run, poses, input_info),
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
    if release_maps:
        run.release_maps()
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
            # The filter's own σ_hit: the chord kernel's where the sub-cell geometry was used.
            | {"sigma_hit_resolved": (run.filter_config or config).mapping_config().hit_sigma},
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
    return write_run_outputs((run, wall), None, source, out, None, None, None, figures, None, odometry_info=input_info)


ESTIMATES = {
    "trajectory.tum": "the filter's estimate, one pose per laser scan sorted by time: the weighted mean of the "
    "particles at processed scans (with loop closing: their poses in the corrected pose graph), carried by the "
    "odometry in between (use this one)",
    "estimates/best_path.tum": "the final best particle's path (the trajectory GMapping reports)",
    "estimates/best_path_means.tum": "the same lineage with each pose replaced by the mean of the proposal it was drawn from",
    "estimates/max_weight.tum": "the highest-weight particle at each processed scan, chosen online",
    "estimates/mode.tum": "mode-seeking estimate: the weighted mean of the densest group of particles",
    "estimates/smoothed.tum": "lineage smoother: each scan's weighted mean of the particles' ancestors (final weights, "
    "or --smoothing-lag)",
    "estimates/smoothed_means.tum": "the lineage smoother over the ancestors' proposal means",
    "estimates/online.tum": "with loop closing: the weighted-mean estimates as they stood online, before the pose "
    "graph corrected them (trajectory.tum is then the graph's poses)",
}


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
