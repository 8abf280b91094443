"""The ``crlam`` command line (also ``python -m crlam``)."""

from __future__ import annotations

import argparse
import json
import os
import sys
from collections.abc import Sequence
from pathlib import Path
from typing import TYPE_CHECKING, Any

from crlam import __version__
from crlam.cli_executor import add_executor_options, executor_from_args
from crlam.cli_failures import EXPECTED_FAILURES, describe_failure
from crlam.cli_options import (
    BATCH_KERNEL_HELP,
    BATCH_KERNELS,
    CAUSE_KERNEL_HELP,
    CAUSE_KERNELS,
    MATCH_STRIDE_HELP,
    MOTION_DRAWS,
    MOTION_DRAWS_HELP,
    MOTION_NOISE_HELP,
    OGM_MAP_HELP,
    OGM_MAPS,
    PROPOSAL_HELP,
    PROPOSAL_POSE_HELP,
    PROPOSALS,
    SCAN_MATCH_WEIGHT_HELP,
    SIGMA_RANGE_HELP,
    TEMPERING_BEAMS_HELP,
    WEIGHT_SMOOTHING_HELP,
    add_bag_options,
    add_estimate_options,
    add_force_option,
    add_likelihood_mode_options,
    add_limit_options_everywhere,
    add_map_options,
    add_odometry_options,
    add_preset_option,
    add_resume_options,
    apply_limit_options,
    bag_options,
    finite_float,
    nonnegative_float,
    nonnegative_int,
    positive_float,
    positive_int,
    slam_overrides,
    staged_output,
    stored_input_options,
)
from crlam.presets import DEFAULT_PRESET, PAPER_PRESET

if TYPE_CHECKING:
    from crlam.slam import SlamConfig

__all__ = ["main", "build_parser"]

#: How every SLAM flag's help ends: the flag overrides the preset, whose value is the default.
FROM_PRESET = "default: the preset's"


def _mapping_config(args: argparse.Namespace):  # type: ignore[no-untyped-def]
    from crlam.mapping import MappingConfig

    return MappingConfig(
        resolution=args.resolution,
        max_range=args.max_range,
        model=args.model,
        levels=args.levels,
        scan_update=args.scan_update,
        batch_kernel=args.batch_kernel,
        cause_kernel=args.cause_kernel,
        beam_stride=args.beam_stride,
    )


def cmd_map(args: argparse.Namespace) -> int:
    from crlam.experiments.known_poses import map_log
    from crlam.run_folder import moved

    config = _mapping_config(args)
    with staged_output(args) as stage:
        run, files = map_log(
            args.log,
            stage,
            config,
            poses=args.poses,
            on_error="skip" if args.skip_malformed else "raise",
            max_scans=args.max_scans,
            progress=not args.quiet,
            bag_options=bag_options(args),
        )
    print(f"mapped {run.n_scans} scans in {run.wall_time_s:.1f} s ({run.n_scans / max(run.wall_time_s, 1e-9):.0f} scans/s)")
    for name, path in files.items():
        print(f"  {name:12s} {moved(path, stage, Path(args.out))}")
    return 0


def cmd_simulate(args: argparse.Namespace) -> int:
    from crlam.experiments.simulate import simulate_to_folder
    from crlam.run_folder import moved

    with staged_output(args) as stage:
        summary = simulate_to_folder(
            world=args.world,
            n_scans=args.scans,
            seed=args.seed,
            out_dir=stage,
            sensor=args.sensor,
            progress=not args.quiet,
        )
    summary["out"] = args.out
    summary["files"] = {k: str(moved(v, stage, Path(args.out))) for k, v in summary["files"].items()}
    print(json.dumps(summary, indent=2))
    return 0


def cmd_demo(args: argparse.Namespace) -> int:
    from crlam.experiments.demo import run_demo
    from crlam.run_folder import moved

    with staged_output(args) as stage:
        report = run_demo(stage, n_scans=args.scans, seed=args.seed, progress=not args.quiet)
    print(f"demo written to {args.out}; open {moved(report, stage, Path(args.out))}")
    return 0


def _base_method(methods: list[str]) -> str:
    """The method the base config of a sweep is validated as: RBPF-CLAM whenever the sweep has
    RBPF-CLAM runs (its settings are the stricter), RBPF-OGM for a baseline-only sweep."""
    return "ogm" if set(methods) == {"ogm"} else "clam"


def slam_config_of(args: argparse.Namespace) -> tuple[SlamConfig, int | None]:
    """``crlam slam``'s configuration and scan limit: the preset (``--preset``, default robust) or
    the settings of ``--config FILE``, with every SLAM flag given on top."""
    from crlam.presets import load_config_file, resolve

    preset: str | None = args.preset
    settings: dict[str, object] = {}
    max_scans = args.max_scans
    if args.config is not None:
        stored = load_config_file(args.config)
        preset, settings = stored.preset, stored.settings
        max_scans = stored.max_scans if max_scans is None else max_scans
    elif preset is None:
        preset = DEFAULT_PRESET
    return resolve(preset, settings | slam_overrides(args)), max_scans


def slam_input_of(args: argparse.Namespace) -> tuple[dict[str, Any], str]:
    """``crlam slam``'s bag options and odometry choice: those of ``--config FILE``'s ``[input]``
    table (how that run read its log), with every bag flag given on top."""
    from crlam.presets import load_config_file

    options: dict[str, Any] = {}
    odometry = None
    if args.config is not None:
        options, odometry = stored_input_options(load_config_file(args.config).input)
    given = bag_options(args)
    if "laser_mount" in given or "upside_down" in given:
        options.pop("laser_mount", None)
        options.pop("upside_down", None)
    return options | given, args.odometry or odometry or "auto"


def cmd_slam(args: argparse.Namespace) -> int:
    from crlam.experiments.slam_run import run_slam_log

    prior = None
    saved_settings = False
    if args.continue_from is not None:
        from crlam.slam_continue import load_slam_prior

        prior = load_slam_prior(args.continue_from)
        # The continued run keeps the saved run's settings unless a preset or a config is given.
        saved = Path(args.continue_from) / "config.toml"
        if args.config is None and args.preset is None and saved.is_file():
            args.config, saved_settings = str(saved), True
    config, max_scans = slam_config_of(args)
    if saved_settings and args.max_scans is None:
        max_scans = None  # the saved run's scan limit was for its own log
    if prior is not None and Path(args.out).resolve() == Path(args.continue_from).resolve():
        from crlam.errors import ConfigError

        raise ConfigError(f"--out {args.out} is the run being continued: write the continued run to a new folder")
    input_options, odometry = slam_input_of(args)
    with staged_output(args) as stage:
        res = run_slam_log(
            args.log,
            stage,
            config,
            reference=args.reference,
            relations=args.relations,
            max_scans=max_scans,
            progress=not args.quiet,
            bag_options=input_options,
            mcap=args.mcap,
            odometry=odometry,
            prior=prior,
        )
    m = res.metrics
    print(f"odometry: {m['input']['odometry']} ({m['input']['odometry_choice']})")
    deviations = [d.split(" = ", 1)[0] for d in m["deviations_from_paper"]]
    print(f"preset {config.preset or '(none)'}; differs from the paper in: {', '.join(deviations) or 'nothing'}")
    print(
        f"{m['n_scans']} scans ({m['n_processed']} processed) in {m['wall_time_s']:.1f} s, "
        f"{m['scans_per_s']:.2f} scans/s, peak RSS {m['peak_rss_mb']:.0f} MB -> {args.out}"
    )
    for key in (
        "reference",
        "reference_best_path",
        "reference_best_path_means",
        "reference_max_weight",
        "reference_mode",
        "reference_smoothed",
        "reference_smoothed_means",
        "relations",
        "relations_best_path",
        "relations_best_path_means",
        "relations_max_weight",
        "relations_mode",
        "relations_smoothed",
        "relations_smoothed_means",
    ):
        if key in m:
            print(f"{key}: " + ", ".join(f"{k}={v:.4g}" for k, v in m[key].items() if isinstance(v, float)))
    return 0


def cmd_experiment(args: argparse.Namespace) -> int:
    from crlam.presets import resolve

    out = Path(args.out)
    executor = executor_from_args(args)
    if args.experiment == "iig":
        from crlam.experiments.iig import run_iig_experiment

        res = run_iig_experiment(
            args.map,
            out,
            functions=[f.strip() for f in args.functions.split(",") if f.strip()],
            runs=args.runs,
            mode=args.mode,
            ogmi=args.ogmi,
            particles=args.particles,
            workers=args.workers,
            max_wall_seconds=args.max_seconds,
            start=(args.start[0], args.start[1]),
            progress=not args.quiet,
            executor=executor,
            resume=args.resume,
            force=args.force,
        )
        print(f"{len(res.rows)} runs finished, {len(res.errors)} failed; report: {res.files['report']}")
        return 0 if not res.errors else 1
    if args.experiment == "explore":
        from crlam.experiments.explore_sweep import run_explore_experiment

        sweep = run_explore_experiment(
            out,
            worlds=args.worlds,
            functions=[f.strip() for f in args.functions.split(",") if f.strip()],
            alphas=[float(a) for a in args.alphas.split(",") if a.strip()],
            runs=args.runs,
            budget=args.budget,
            slam=not args.known_poses,
            particles=args.particles,
            workers=args.workers,
            progress=not args.quiet,
            executor=executor,
            resume=args.resume,
            force=args.force,
        )
        print(f"{len(sweep.rows)} runs finished, {len(sweep.errors)} failed; report: {sweep.files['report']}")
        return 0 if not sweep.errors else 1
    if args.experiment == "table1":
        from crlam.experiments.table1 import PROTOCOL_MAX_RANGE, run_table1

        # The paper's protocol: the paper preset unless --preset says otherwise, at the simulated LIDAR's range.
        base = resolve(
            args.preset or PAPER_PRESET,
            slam_overrides(args) | {"method": _base_method(args.methods), "max_range": PROTOCOL_MAX_RANGE},
        )
        run_table1(
            out,
            runs=args.runs,
            scans=args.scans,
            particles=base.particles,
            methods=args.methods,
            workers=args.workers,
            threads=args.threads,
            base=base,
            progress=not args.quiet,
            report_only=args.report_only,
            executor=executor,
            resume=args.resume,
            force=args.force,
        )
    else:
        from crlam.experiments.real_logs import run_real_logs

        # Every run: the preset (default robust) with the flags given; the grid sets method, particles, seed, range.
        base = resolve(args.preset or DEFAULT_PRESET, slam_overrides(args) | {"method": _base_method(args.methods)})
        run_real_logs(
            out,
            datasets=args.datasets,
            methods=args.methods,
            particles=args.particles_list,
            seeds=args.seeds,
            ranges=args.ranges,
            base=base,
            workers=args.workers,
            threads=args.threads,
            max_scans=args.max_scans,
            progress=not args.quiet,
            report_only=args.report_only,
            executor=executor,
            resume=args.resume,
            force=args.force,
        )
    print((out / "table.md").read_text())
    return 0


def cmd_bench(args: argparse.Namespace) -> int:
    from crlam.bench import run_benchmarks, write_json

    result = run_benchmarks(args.only or None, quick=args.quick, repeats=args.repeats)
    print(
        f"crlam bench: vector kernels at {result['simd']} (CRLAM_SIMD; CPU: {' '.join(result['cpu_features']) or 'none'})",
        file=sys.stderr,
    )
    text = json.dumps(result["figures"] if not args.verbose else result, indent=2, sort_keys=True)
    print(text)
    if args.json:
        write_json(result, args.json)
    return 0


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="crlam",
        description="Confidence-rich localization and mapping: CRM, RBPF-CLAM and information functions.",
    )
    parser.add_argument("--version", action="version", version=f"crlam {__version__}")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND")
    sub.required = True

    p = sub.add_parser(
        "demo",
        help="simulate the museum world, map it and write figures and a report",
        description="The main job on built-in data: simulate the 90 m x 90 m museum-like world with the paper's "
        "LIDAR, build the confidence-rich map (and the log-odds baseline) with known poses, and write "
        "figures and report.md.",
    )
    p.add_argument("--out", default="demo-out", help="output folder (default: demo-out)")
    add_force_option(p)
    p.add_argument("--scans", type=positive_int, default=4000, help="number of scans to simulate (default: 4000)")
    p.add_argument("--seed", type=int, default=0, help="random seed (default: 0)")
    p.add_argument("--quiet", action="store_true", help="no progress bars")
    p.set_defaults(func=cmd_demo)

    p = sub.add_parser(
        "simulate",
        help="simulate a robot in a world and write a CARMEN log and ground truth",
        description="Writes log.clf (CARMEN), groundtruth.tum, world.pgm/yaml and simulation.json. Same seed, same bytes.",
    )
    p.add_argument("--world", default="office", help="museum, office, or a PGM/PNG/Nav2-YAML path (default: office)")
    p.add_argument("--scans", type=positive_int, default=500, help="number of scans (default: 500)")
    p.add_argument("--seed", type=int, default=0, help="random seed (default: 0)")
    p.add_argument(
        "--sensor",
        choices=("paper", "sick"),
        default="paper",
        help="paper = 1079 beams over 270 deg, 8 m; sick = 180 beams over 180 deg, 80 m (default: paper)",
    )
    p.add_argument("--out", required=True, help="output folder")
    add_force_option(p)
    p.add_argument("--quiet", action="store_true", help="no progress bars")
    p.set_defaults(func=cmd_simulate)

    p = sub.add_parser(
        "map",
        help="build a confidence-rich map from a log or a ROS bag with trusted poses",
        description="Maps a CARMEN log (plain, .gz or .bz2) or a ROS bag (odometry poses) whose poses are trusted and "
        "writes map.pgm/yaml, "
        "belief.npz, ogm.pgm/yaml, map.png and mapping.json.",
    )
    p.add_argument(
        "log",
        help="CARMEN log, e.g. ../shared/data/corrected/intel-corrected.log.gz, or a ROS bag (folder with "
        "metadata.yaml, .bag or .mcap)",
    )
    p.add_argument("--out", required=True, help="output folder")
    add_force_option(p)
    p.add_argument(
        "--poses",
        choices=("log", "odometry"),
        default="log",
        help="which pose field to trust: the scan's pose field or its odometry field (default: log)",
    )
    p.add_argument("--max-scans", type=positive_int, default=None, help="stop after this many scans")
    p.add_argument("--skip-malformed", action="store_true", help="skip (and count) malformed lines instead of stopping")
    p.add_argument("--quiet", action="store_true", help="no progress bar")
    add_map_options(p)
    add_bag_options(p)
    p.set_defaults(func=cmd_map)

    p = sub.add_parser(
        "slam",
        help="run RBPF-CLAM (or RBPF-OGM) on a CARMEN log or a ROS bag and write a run folder",
        description="Runs a Rao-Blackwellized particle filter on a log and writes config.toml, trajectory.tum "
        "(the estimate to use: one pose per scan, sorted by time), estimates/ (the other estimates), README.txt (what "
        "each file holds), metrics.json, map.pgm/yaml, belief.npz and figures. The settings are a "
        "named preset (--preset, default robust) or a run folder's config.toml (--config); every SLAM flag given "
        "overrides them.",
    )
    p.add_argument("log", help="CARMEN log (plain, .gz or .bz2) or ROS bag (folder with metadata.yaml, .bag or .mcap)")
    p.add_argument("--out", required=True, help="run folder")
    add_force_option(p)
    source = p.add_mutually_exclusive_group()
    add_preset_option(source, DEFAULT_PRESET)
    source.add_argument(
        "--config",
        metavar="FILE",
        help="start from the [slam] settings (and [run] max_scans) of FILE, a run folder's config.toml, instead of a "
        "preset: re-runs that configuration; flags given beside it still override it",
    )
    p.add_argument(
        "--continue",
        dest="continue_from",
        metavar="DIR",
        help="continue a saved crlam slam run: every particle starts with DIR's map, around DIR's final estimate (its "
        "covariance), and the run goes on mapping LOG (which takes up where DIR's log ended); DIR's settings unless "
        "--preset or --config is given; DIR is only read",
    )
    p.add_argument("--method", choices=("clam", "ogm"), default=None, help=f"filter (paper: clam; {FROM_PRESET})")
    p.add_argument("--particles", type=positive_int, default=None, help=f"number of particles (paper: 100; {FROM_PRESET})")
    p.add_argument("--seed", type=nonnegative_int, default=None, help=f"random seed ({FROM_PRESET}; 0 unless it sets one)")
    p.add_argument("--resolution", type=positive_float, default=None, help=f"cell size in metres (paper: 0.2; {FROM_PRESET})")
    p.add_argument("--max-range", type=positive_float, default=None, help=f"z_max in metres (paper: 8; {FROM_PRESET})")
    p.add_argument("--reference", help="ground-truth TUM trajectory: report MAE x, y, theta and position RMSE")
    p.add_argument("--relations", help="Kuemmerle relations file: report the relations metric")
    p.add_argument("--proposal", choices=PROPOSALS, default=None, help=PROPOSAL_HELP)
    p.add_argument("--proposal-pose", choices=("sample", "match"), default=None, help=PROPOSAL_POSE_HELP)
    p.add_argument("--match-stride", type=positive_int, default=None, help=MATCH_STRIDE_HELP)
    add_likelihood_mode_options(p)
    add_estimate_options(p)
    p.add_argument(
        "--motion",
        choices=("gaussian", "thrun", "gmapping"),
        default=None,
        help=f"odometry noise model (paper: gaussian; {FROM_PRESET}); gmapping is GMapping's own model",
    )
    p.add_argument(
        "--motion-params",
        type=float,
        nargs="+",
        default=None,
        help="3 sigmas (gaussian), 4 alphas (thrun; RBPF-OGM's thrun default is 0.04 0.01 0.01 0.04) or srr srt "
        f"str stt (gmapping; default 0.1 0.2 0.1 0.2) ({FROM_PRESET}; unset there: the model's own)",
    )
    p.add_argument(
        "--weight-stride", type=positive_int, default=None, help=f"every n-th beam for the weights (paper: 1; {FROM_PRESET})"
    )
    p.add_argument(
        "--map-stride", type=positive_int, default=None, help=f"every n-th beam for the map update (paper: 1; {FROM_PRESET})"
    )
    p.add_argument("--tempering", type=positive_float, default=None, help=f"weight tempering tau (paper: 1; {FROM_PRESET})")
    p.add_argument("--tempering-beams", type=positive_float, default=None, metavar="B", help=TEMPERING_BEAMS_HELP)
    p.add_argument("--scan-match-weight", choices=("crm", "endpoint"), default=None, help=SCAN_MATCH_WEIGHT_HELP)
    p.add_argument("--motion-noise", choices=("model", "estimate"), default=None, help=MOTION_NOISE_HELP)
    p.add_argument("--sigma-range", type=nonnegative_float, default=None, help=SIGMA_RANGE_HELP)
    p.add_argument("--cause-kernel", choices=CAUSE_KERNELS, default=None, help=CAUSE_KERNEL_HELP)
    p.add_argument("--batch-kernel", choices=BATCH_KERNELS, default=None, help=f"{BATCH_KERNEL_HELP} ({FROM_PRESET})")
    p.add_argument("--ogm-map", choices=OGM_MAPS, default=None, help=OGM_MAP_HELP)
    p.add_argument("--ogm-motion-draws", choices=MOTION_DRAWS, default=None, help=MOTION_DRAWS_HELP)
    p.add_argument("--ogm-weight-smoothing", type=nonnegative_float, default=None, help=WEIGHT_SMOOTHING_HELP)
    p.add_argument(
        "--linear-update",
        type=nonnegative_float,
        default=None,
        help=f"process a scan after this travel in m (paper: 0, every scan; {FROM_PRESET})",
    )
    p.add_argument(
        "--angular-update",
        type=nonnegative_float,
        default=None,
        help=f"... or this rotation in rad (paper: 0, every scan; {FROM_PRESET})",
    )
    p.add_argument(
        "--max-scans", type=positive_int, default=None, help="stop after this many scans (with --config: the file's, if any)"
    )
    p.add_argument(
        "--mcap",
        action="store_true",
        help="also write run.mcap (ROS 2 messages for Foxglove or ros2 bag play): /scan, /tf (map -> odom -> "
        "base_link), /tf_static, /particles (PoseArray), /path, /map and /map_confidence (OccupancyGrid)",
    )
    p.add_argument("--quiet", action="store_true", help="no progress bar")
    add_bag_options(p)
    add_odometry_options(p)
    p.set_defaults(func=cmd_slam)

    from crlam.cli_eval import add_data_parser, add_eval_parser

    add_eval_parser(sub)
    add_data_parser(sub)

    from crlam.cli_convert import add_convert_parser
    from crlam.cli_diagnose import add_diagnose_parser
    from crlam.cli_explore import add_explore_parser
    from crlam.cli_info import add_info_parser
    from crlam.cli_localize import add_localize_parser

    add_info_parser(sub)
    add_localize_parser(sub)
    add_explore_parser(sub)
    add_diagnose_parser(sub)
    add_convert_parser(sub)

    p = sub.add_parser(
        "experiment",
        help="run a paper experiment (resumable) and write its table and figures",
        description="Runs an experiment as a resumable sweep of runs in spawn worker processes on this machine "
        "or on a Dask cluster (--executor dask); rerunning the same command with --resume skips finished runs "
        "(after checking that the folder's runs were made with the same settings), --force starts the folder anew.",
    )
    exp = p.add_subparsers(dest="experiment", metavar="EXPERIMENT")
    exp.required = True
    t1 = exp.add_parser(
        "table1",
        help="Table I protocol on the simulated museum world",
        description="Museum world, 1079 beams over 270 deg, 8 m, 0.2 m grid; Monte Carlo runs per method "
        "against the exact ground truth; writes table.md/csv, results.json and the Fig. 2 figures.",
    )
    t1.add_argument("--out", required=True, help="experiment folder (continued with --resume)")
    t1.add_argument("--runs", type=positive_int, default=15, help="Monte Carlo runs per method (default: 15)")
    t1.add_argument("--scans", type=positive_int, default=5500, help="scans of the simulated log (default: 5500)")
    t1.add_argument("--particles", type=positive_int, default=None, help=f"particles (paper: 100; {FROM_PRESET})")
    t1.add_argument("--methods", nargs="+", choices=("ogm", "clam"), default=["ogm", "clam"], help="filters to run")
    t1.add_argument(
        "--resolution",
        type=positive_float,
        default=None,
        help=f"cell size in metres (paper: 0.2; {FROM_PRESET}; any value other than the paper's is reported as a deviation)",
    )
    add_preset_option(t1, PAPER_PRESET)
    rl = exp.add_parser(
        "real-logs",
        help="Intel and ACES raw logs with their relations",
        description="Both methods on the raw Intel and ACES logs at several particle counts, seeds and ranges; "
        "relations metric, wall time and memory next to the published numbers. Every run has the settings of "
        "--preset (default robust) with the SLAM flags given on top; the grid (--methods, --particles, --seeds, "
        "--ranges) sets each run's method, particle count, seed and z_max.",
    )
    add_preset_option(rl, DEFAULT_PRESET)
    rl.add_argument("--out", required=True, help="experiment folder (continued with --resume)")
    rl.add_argument("--datasets", nargs="+", choices=("intel", "aces"), default=["intel", "aces"])
    rl.add_argument("--methods", nargs="+", choices=("ogm", "clam"), default=["ogm", "clam"])
    rl.add_argument("--particles", dest="particles_list", type=positive_int, nargs="+", default=[30, 100])
    rl.add_argument("--seeds", type=positive_int, default=3, help="seeds per setting (default: 3)")
    rl.add_argument("--ranges", nargs="+", default=["full", "8"], help="z_max settings: 'full' and/or metres (default: full 8)")
    rl.add_argument("--resolution", type=positive_float, default=None, help=f"cell size in metres (paper: 0.2; {FROM_PRESET})")
    rl.add_argument("--max-scans", type=positive_int, default=None, help="only the first N scans of each log")
    rl.add_argument(
        "--linear-update",
        type=nonnegative_float,
        default=None,
        help=f"process a scan after this travel in m (paper: 0, every scan; GMapping's default is 1; {FROM_PRESET})",
    )
    rl.add_argument(
        "--angular-update",
        type=nonnegative_float,
        default=None,
        help=f"... or this rotation in rad (paper: 0, every scan; GMapping's default is 0.5; {FROM_PRESET})",
    )
    rl.add_argument("--ogm-map", choices=OGM_MAPS, default=None, help=OGM_MAP_HELP)
    rl.add_argument("--ogm-motion-draws", choices=MOTION_DRAWS, default=None, help=MOTION_DRAWS_HELP)
    rl.add_argument("--ogm-weight-smoothing", type=nonnegative_float, default=None, help=WEIGHT_SMOOTHING_HELP)
    rl.add_argument(
        "--motion",
        choices=("thrun", "gmapping"),
        default=None,
        help=f"odometry noise model of every method of the sweep ({FROM_PRESET}); gmapping is GMapping's own model",
    )
    rl.add_argument(
        "--motion-params",
        type=nonnegative_float,
        nargs=4,
        default=None,
        metavar=("A1", "A2", "A3", "A4"),
        help=f"the four parameters of the odometry model, given to every method of the sweep ({FROM_PRESET}; unset "
        "there: the model's own). thrun: alpha1..alpha4 (the model's own: 0.1 0.1 0.2 0.05 for RBPF-CLAM, "
        "0.04 0.01 0.01 0.04 for RBPF-OGM); alpha3 scales the variance of the travelled distance (0.002 is a 4.5 %% "
        "standard deviation), alpha2 that of the heading per metre travelled. gmapping: srr srt str stt (the model's "
        "own: 0.1 0.2 0.1 0.2)",
    )
    ig = exp.add_parser(
        "iig",
        help="the IIG planner with several information functions on a map (paper Sec. V.B)",
        description="Plans IIG trees from (10, 2) on the map (default: the Cave map) with each information function "
        "and seeds 0..runs-1 shared across functions, in spawn worker processes; writes runs.csv, per-run trees, "
        "fig3_trees.png, fig4_boxplots.png, fig5_ric_gain.png and report.md (the paper's six claims checked).",
    )
    ig.add_argument("--map", default=None, help="map (.pgm read as the planner reads cave.pgm, or Nav2 .yaml); default: cave-map")
    ig.add_argument("--out", required=True, help="experiment folder (continued with --resume)")
    ig.add_argument("--runs", type=positive_int, default=20, help="runs (seeds) per function (default: 20)")
    ig.add_argument("--functions", default="ogmi,crmi,ucrmi,gpvr,ugpvr", help="comma-separated (default: all five)")
    ig.add_argument("--mode", choices=("reference", "clean"), default="reference", help="planner and function quirks")
    ig.add_argument("--ogmi", choices=("fsmi", "iig_mi", "julian"), default="fsmi", help="what OGMI means (default: exact FSMI)")
    ig.add_argument("--particles", type=positive_int, default=100, help="UCRMI particles per node (default: 100)")
    ig.add_argument("--start", type=finite_float, nargs=2, default=(10.0, 2.0), metavar=("X", "Y"), help="start (default: 10 2)")
    ig.add_argument("--max-seconds", type=positive_float, default=600.0, help="wall-clock guard per run (default: 600)")
    ig.add_argument("--workers", type=positive_int, default=2, help="worker processes (spawn; default: 2)")
    ig.add_argument("--quiet", action="store_true", help="no progress output")
    add_executor_options(ig)
    ig.set_defaults(func=cmd_experiment)
    add_resume_options(ig)
    ex = exp.add_parser(
        "explore",
        help="exploration runs over worlds, functions, UCRMI alphas and seeds",
        description="Runs crlam explore for every world x function (x alpha for UCRMI) x seed in spawn workers "
        "(resumable); writes runs.csv, coverage.png (explored area, map error and pose error against distance), "
        "pose_error.png and report.md. Poses come from RBPF-CLAM unless --known-poses.",
    )
    ex.add_argument("--out", required=True, help="experiment folder (continued with --resume)")
    ex.add_argument("--worlds", nargs="+", default=["office"], help="museum | office | map files (default: office)")
    ex.add_argument("--functions", default="crmi,ucrmi,fsmi,frontier", help="comma-separated (default: all four)")
    ex.add_argument("--alphas", default="0,0.25,0.5,0.75,1", help="UCRMI weights of the map term (default: 0,...,1)")
    ex.add_argument("--runs", type=positive_int, default=3, help="seeds per setting (default: 3)")
    ex.add_argument("--budget", type=positive_float, default=60.0, help="travel budget per run in metres (default: 60)")
    ex.add_argument("--particles", type=positive_int, default=30, help="RBPF-CLAM particles (default: 30)")
    ex.add_argument("--known-poses", action="store_true", help="no SLAM: the robot knows its pose")
    ex.add_argument("--workers", type=positive_int, default=2, help="worker processes (spawn; default: 2)")
    ex.add_argument("--quiet", action="store_true", help="no progress output")
    add_executor_options(ex)
    ex.set_defaults(func=cmd_experiment)
    add_resume_options(ex)
    for q in (t1, rl):
        add_resume_options(q)
        q.add_argument("--workers", type=positive_int, default=2, help="worker processes (spawn; default: 2)")
        q.add_argument(
            "--threads", type=positive_int, default=1, help="threads of each run (default: 1; the results do not depend on it)"
        )
        q.add_argument(
            "--weight-stride", type=positive_int, default=None, help=f"beam stride of the weights (paper: 1; {FROM_PRESET})"
        )
        q.add_argument("--tempering", type=positive_float, default=None, help=f"weight tempering (paper: 1; {FROM_PRESET})")
        q.add_argument("--tempering-beams", type=positive_float, default=None, metavar="B", help=TEMPERING_BEAMS_HELP)
        q.add_argument("--scan-match-weight", choices=("crm", "endpoint"), default=None, help=SCAN_MATCH_WEIGHT_HELP)
        q.add_argument("--motion-noise", choices=("model", "estimate"), default=None, help=MOTION_NOISE_HELP)
        q.add_argument("--sigma-range", type=nonnegative_float, default=None, help=SIGMA_RANGE_HELP)
        q.add_argument("--cause-kernel", choices=CAUSE_KERNELS, default=None, help=CAUSE_KERNEL_HELP)
        q.add_argument("--proposal", choices=PROPOSALS, default=None, help=PROPOSAL_HELP)
        q.add_argument("--proposal-pose", choices=("sample", "match"), default=None, help=PROPOSAL_POSE_HELP)
        q.add_argument("--match-stride", type=positive_int, default=None, help=MATCH_STRIDE_HELP)
        add_likelihood_mode_options(q)
        add_estimate_options(q)
        q.add_argument("--quiet", action="store_true", help="no progress output")
        q.add_argument(
            "--report-only", action="store_true", help="run nothing: write the table (and figures) of the runs finished so far"
        )
        add_executor_options(q)
        q.set_defaults(func=cmd_experiment)

    p = sub.add_parser(
        "bench",
        help="run the micro-benchmarks and print named figures as JSON",
        description="Runs the core's micro-benchmarks (one thread, timed in Rust) and prints a JSON object of "
        "named figures, all measured in this run. The vector kernels run at the best instruction-set level the "
        "CPU supports unless the environment variable CRLAM_SIMD=scalar|avx2|avx512 lowers it (the level is "
        'reported as "simd" in the --json/--verbose result).',
    )
    p.add_argument("--json", help="also write the full result (figures, details, machine) to this file")
    p.add_argument("--only", nargs="*", help="run only these figures")
    p.add_argument("--quick", action="store_true", help="small workloads (smoke test)")
    p.add_argument("--repeats", type=positive_int, default=3, help="best of N (default: 3)")
    p.add_argument("--verbose", action="store_true", help="print the full result, not just the figures")
    p.set_defaults(func=cmd_bench)
    add_limit_options_everywhere(parser)
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    try:
        apply_limit_options(args)
        status = int(args.func(args))
        sys.stdout.flush()
        return status
    except BrokenPipeError:
        # The reader of our output went away (`crlam slam ... | head`): stop without a traceback,
        # with the status a process killed by SIGPIPE has, and keep Python's exit-time flush of
        # stdout from raising again.
        devnull = os.open(os.devnull, os.O_WRONLY)
        os.dup2(devnull, sys.stdout.fileno())
        return 141
    except EXPECTED_FAILURES as e:
        # Expected failures (bad input, a file system refusing, a limit, memory) are one line;
        # CRLAM_TRACEBACK=1 shows the traceback. Other exceptions are bugs and keep theirs.
        if os.environ.get("CRLAM_TRACEBACK"):
            raise
        print(f"crlam {args.command}: error: {describe_failure(e)}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print(f"crlam {args.command}: interrupted", file=sys.stderr)
        return 130


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
