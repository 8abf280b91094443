"""``crlam experiment``: the paper's experiments as resumable sweeps (table1, real-logs, iig, explore, stress)."""

from __future__ import annotations

import argparse
from pathlib import Path
from typing import Any

from crlam.cli.conventions import (
    ListAction,
    add_output_options,
    deprecated_alias,
    group,
    input_file,
    list_choices,
    map_file,
    print_settings,
    world_arg,
)
from crlam.cli.executor import add_executor_options, executor_from_args
from crlam.cli.options import (
    FROM_PRESET,
    add_preset_option,
    add_slam_flags,
    finite_float,
    nonnegative_float,
    positive_float,
    positive_int,
    slam_overrides,
)
from crlam.slam.presets import DEFAULT_PRESET, PAPER_PRESET

__all__ = ["add_parser", "cmd_experiment"]

#: The SLAM flags both filter sweeps take (table1 adds --particles; real-logs the GMapping-side flags).
_SWEEP_FLAGS = (
    "--resolution",
    "--grid-alignment",
    "--sub-cell",
    "--weight-stride",
    "--tempering",
    "--tempering-beams",
    "--scan-match-weight",
    "--match-range",
    "--hit-means",
    "--match-climb",
    "--degeneracy",
    "--hits-first",
    "--match-min-score",
    "--map-range",
    "--front-end",
    "--front-end-window",
    "--motion-noise",
    "--sigma-range",
    "--cause-kernel",
    "--proposal",
    "--proposal-pose",
    "--match-stride",
    "--lattice-step",
    "--motion-outlier",
    "--mode-bandwidth",
    "--smoothing-lag",
    "--fill",
)
_REAL_LOG_FLAGS = (
    "--linear-update",
    "--angular-update",
    "--ogm-map",
    "--ogm-motion-draws",
    "--ogm-weight-smoothing",
    "--motion",
    "--motion-params",
)


def _base_method(methods: list[str]) -> str:
    """The method the base config of a sweep is validated as: RBPF-CLAM whenever the sweep has
    RBPF-CLAM runs (its settings are the stricter), RBPF-OGM for a baseline-only sweep."""
    return "ogm" if set(methods) == {"ogm"} else "clam"


def cmd_experiment(args: argparse.Namespace) -> int:
    from crlam.slam.presets import resolve

    out = Path(args.out)
    executor = executor_from_args(args)
    # What every sweep takes alike: where its runs go, how it reports, what it does with an existing folder.
    sweep_options: dict[str, Any] = {
        "workers": args.workers,
        "progress": not args.quiet,
        "executor": executor,
        "resume": args.resume,
        "force": args.force,
        "verbose": args.verbose,
    }
    if args.experiment == "iig":
        from crlam.experiments.iig import run_iig_experiment

        print_settings(args, executor=executor.describe())
        res = run_iig_experiment(
            args.map,
            out,
            functions=args.functions,
            runs=args.runs,
            mode=args.mode,
            ogmi=args.ogmi,
            particles=args.ucrmi_particles,
            max_wall_seconds=args.max_seconds,
            start=(args.start[0], args.start[1]),
            **sweep_options,
        )
        print(f"{len(res.rows)} runs finished, {len(res.errors)} failed; report: {res.files['report']}")
        return 0 if not res.errors else 1
    if args.experiment == "explore":
        from crlam.experiments.explore_sweep import run_explore_experiment

        print_settings(args, executor=executor.describe())
        sweep = run_explore_experiment(
            out,
            worlds=args.worlds,
            functions=args.functions,
            alphas=args.alphas,
            runs=args.runs,
            budget=args.budget,
            slam=not args.known_poses,
            particles=args.slam_particles,
            **sweep_options,
        )
        print(f"{len(sweep.rows)} runs finished, {len(sweep.errors)} failed; report: {sweep.files['report']}")
        return 0 if not sweep.errors else 1
    if args.experiment == "stress":
        return _cmd_stress(args, out, sweep_options)
    if args.experiment == "table1":
        from crlam.experiments.table1 import PROTOCOL_MAX_RANGE, run_table1

        # The paper's protocol: the paper preset unless --preset says otherwise, at the simulated LIDAR's range.
        base = resolve(
            args.preset or PAPER_PRESET,
            slam_overrides(args) | {"method": _base_method(args.methods), "max_range": PROTOCOL_MAX_RANGE},
        )
        print_settings(args, base_settings=base, executor=executor.describe())
        run_table1(
            out,
            runs=args.runs,
            scans=args.scans,
            particles=base.particles,
            methods=args.methods,
            threads=args.threads,
            base=base,
            report_only=args.report_only,
            **sweep_options,
        )
    else:
        from crlam.experiments.real_logs import run_real_logs

        # Every run: the preset (default robust) with the flags given; the grid sets method, particles, seed, range.
        base = resolve(args.preset or DEFAULT_PRESET, slam_overrides(args) | {"method": _base_method(args.methods)})
        print_settings(args, base_settings=base, executor=executor.describe())
        run_real_logs(
            out,
            datasets=args.datasets,
            methods=args.methods,
            particles=args.particles_list,
            seeds=args.runs,
            ranges=args.ranges,
            base=base,
            threads=args.threads,
            max_scans=args.max_scans,
            report_only=args.report_only,
            **sweep_options,
        )
    print((out / "table.md").read_text())
    return 0


def _sweep_output(p: argparse.ArgumentParser, *, report_only: bool) -> None:
    """The ``output`` group of a sweep: the experiment folder, --resume/--force, -q/-v."""
    g = add_output_options(p, out="experiment folder (continued with --resume)", replace="resume")
    if report_only:
        g.add_argument(
            "--report-only", action="store_true", help="run nothing: write the table (and figures) of the runs finished so far"
        )


def _workers(p: argparse.ArgumentParser, *, threads: bool) -> None:
    run = group(p, "run control")
    run.add_argument("--workers", type=positive_int, default=2, help="worker processes (spawn; default: 2)")
    if threads:
        run.add_argument(
            "--threads", type=positive_int, default=1, help="threads of each run (default: 1; the results do not depend on it)"
        )


def _add_table1(exp: argparse._SubParsersAction) -> None:  # type: ignore[type-arg]
    t1 = exp.add_parser(
        "table1",
        help="Table I protocol on the simulated museum world",
        description="Museum world, 1079 beams over 270 deg, 8 m, 0.2 m grid; Monte Carlo runs per method "
        "against the exact ground truth; writes table.md/csv, results.json and the Fig. 2 figures.",
    )
    _sweep_output(t1, report_only=True)
    run = group(t1, "run control")
    run.add_argument("--runs", type=positive_int, default=15, help="Monte Carlo runs per method (default: 15)")
    run.add_argument("--scans", type=positive_int, default=5500, help="scans of the simulated log (default: 5500)")
    run.add_argument(
        "--methods",
        action=ListAction,
        choices=list_choices(("ogm", "clam")),
        default=["ogm", "clam"],
        help="filters to run (default: ogm clam)",
    )
    _workers(t1, threads=True)
    add_preset_option(group(t1, "settings", "a preset; every flag of the groups below overrides it"), PAPER_PRESET)
    add_slam_flags(
        t1,
        ("--particles", *_SWEEP_FLAGS),
        resolution={
            "help": f"cell size in metres (paper: 0.2; {FROM_PRESET}; any value other than the paper's is reported as a "
            "deviation)"
        },
    )
    add_executor_options(t1)
    t1.set_defaults(func=cmd_experiment)


def _add_real_logs(exp: argparse._SubParsersAction) -> None:  # type: ignore[type-arg]
    rl = exp.add_parser(
        "real-logs",
        help="Intel and ACES raw logs with their relations",
        description="Both methods on the raw Intel and ACES logs at several particle counts, seeds and ranges; "
        "relations metric, wall time and memory next to the published numbers. Every run has the settings of "
        "--preset (default robust) with the SLAM flags given on top; the grid (--methods, --particles, --runs, "
        "--ranges) sets each run's method, particle count, seed and z_max.",
    )
    inp = group(rl, "input")
    inp.add_argument(
        "--datasets",
        action=ListAction,
        metavar="NAME",
        choices=list_choices(("intel", "aces")),
        default=["intel", "aces"],
        help="the raw logs: intel and/or aces, with their relations (default: intel aces)",
    )
    inp.add_argument("--max-scans", type=positive_int, default=None, help="only the first N scans of each log")
    _sweep_output(rl, report_only=True)
    grid = group(rl, "run control", "the grid of runs")
    grid.add_argument(
        "--methods",
        action=ListAction,
        choices=list_choices(("ogm", "clam")),
        default=["ogm", "clam"],
        help="filters (default: ogm clam)",
    )
    grid.add_argument(
        "--particles",
        dest="particles_list",
        action=ListAction,
        type=positive_int,
        metavar="N",
        default=[30, 100],
        help="particle counts (default: 30 100)",
    )
    grid.add_argument("--runs", type=positive_int, default=3, help="seeds per setting (default: 3)")
    grid.add_argument(
        "--ranges",
        action=ListAction,
        metavar="RANGE",
        default=["full", "8"],
        help="z_max settings: 'full' and/or metres (default: full 8)",
    )
    deprecated_alias(rl, "--seeds", "--runs")
    _workers(rl, threads=True)
    add_preset_option(group(rl, "settings", "a preset; every flag of the groups below overrides it"), DEFAULT_PRESET)
    add_slam_flags(
        rl,
        (*_SWEEP_FLAGS, *_REAL_LOG_FLAGS),
        motion={
            "choices": ("thrun", "gmapping"),
            "help": f"odometry noise model of every method of the sweep ({FROM_PRESET}); gmapping is GMapping's own model",
        },
        motion_params={
            "type": nonnegative_float,
            "nargs": 4,
            "metavar": ("A1", "A2", "A3", "A4"),
            "help": f"the four parameters of the odometry model, given to every method of the sweep ({FROM_PRESET}; "
            "unset there: the model's own). thrun: alpha1..alpha4 (the model's own: 0.1 0.1 0.2 0.05 for RBPF-CLAM, "
            "0.04 0.01 0.01 0.04 for RBPF-OGM); alpha3 scales the variance of the travelled distance (0.002 is a 4.5 %% "
            "standard deviation), alpha2 that of the heading per metre travelled. gmapping: srr srt str stt (the "
            "model's own: 0.1 0.2 0.1 0.2)",
        },
    )
    add_executor_options(rl)
    rl.set_defaults(func=cmd_experiment)


def _add_iig(exp: argparse._SubParsersAction) -> None:  # type: ignore[type-arg]
    ig = exp.add_parser(
        "iig",
        help="the IIG planner with several information functions on a map (paper Sec. V.B)",
        description="Plans IIG trees from (10, 2) on the map (default: the Cave map) with each information function "
        "and seeds 0..runs-1 shared across functions, in spawn worker processes; writes runs.csv, per-run trees, "
        "fig3_trees.png, fig4_boxplots.png, fig5_ric_gain.png and report.md (the paper's six claims checked).",
    )
    inp = group(ig, "input")
    inp.add_argument(
        "--map",
        type=map_file,
        default=None,
        help="map (.pgm read as the planner reads cave.pgm, or Nav2 .yaml) or map dataset; default: cave-map",
    )
    inp.add_argument("--start", type=finite_float, nargs=2, default=(10.0, 2.0), metavar=("X", "Y"), help="start (default: 10 2)")
    _sweep_output(ig, report_only=False)
    fn = group(ig, "planner")
    fn.add_argument(
        "--functions",
        action=ListAction,
        metavar="NAME",
        default=["ogmi", "crmi", "ucrmi", "gpvr", "ugpvr"],
        help="information functions (default: ogmi crmi ucrmi gpvr ugpvr)",
    )
    fn.add_argument("--mode", choices=("reference", "clean"), default="reference", help="planner and function quirks")
    fn.add_argument("--ogmi", choices=("fsmi", "iig_mi", "julian"), default="fsmi", help="what OGMI means (default: exact FSMI)")
    fn.add_argument("--ucrmi-particles", type=positive_int, default=100, help="UCRMI pose particles per node (default: 100)")
    run = group(ig, "run control")
    run.add_argument("--runs", type=positive_int, default=20, help="runs (seeds) per function (default: 20)")
    run.add_argument("--max-seconds", type=positive_float, default=600.0, help="wall-clock guard per run (default: 600)")
    _workers(ig, threads=False)
    deprecated_alias(ig, "--particles", "--ucrmi-particles")
    add_executor_options(ig)
    ig.set_defaults(func=cmd_experiment)


def _add_explore(exp: argparse._SubParsersAction) -> None:  # type: ignore[type-arg]
    ex = exp.add_parser(
        "explore",
        help="exploration runs over worlds, functions, UCRMI alphas and seeds",
        description="Runs crlam explore for every world x function (x alpha for UCRMI) x seed in spawn workers "
        "(resumable); writes runs.csv, coverage.png (explored area, map error and pose error against distance), "
        "pose_error.png and report.md. Poses come from RBPF-CLAM unless --known-poses.",
    )
    inp = group(ex, "world")
    inp.add_argument(
        "--worlds",
        nargs="+",
        type=world_arg,
        metavar="WORLD",
        default=["office"],
        help="museum | office | map files (default: office)",
    )
    _sweep_output(ex, report_only=False)
    fn = group(ex, "planner")
    fn.add_argument(
        "--functions",
        action=ListAction,
        metavar="NAME",
        default=["crmi", "ucrmi", "fsmi", "frontier"],
        help="information functions (default: crmi ucrmi fsmi frontier)",
    )
    fn.add_argument(
        "--alphas",
        action=ListAction,
        metavar="ALPHA",
        type=finite_float,
        default=[0.0, 0.25, 0.5, 0.75, 1.0],
        help="UCRMI weights of the map term (default: 0 0.25 0.5 0.75 1)",
    )
    fn.add_argument("--budget", type=positive_float, default=60.0, help="travel budget per run in metres (default: 60)")
    flt = group(ex, "filter")
    flt.add_argument("--slam-particles", type=positive_int, default=30, help="RBPF-CLAM particles (default: 30)")
    flt.add_argument("--known-poses", action="store_true", help="no SLAM: the robot knows its pose")
    run = group(ex, "run control")
    run.add_argument("--runs", type=positive_int, default=3, help="seeds per setting (default: 3)")
    _workers(ex, threads=False)
    deprecated_alias(ex, "--particles", "--slam-particles")
    add_executor_options(ex)
    ex.set_defaults(func=cmd_experiment)


def add_parser(sub: argparse._SubParsersAction) -> argparse.ArgumentParser:  # type: ignore[type-arg]
    """Add ``experiment`` (``table1``, ``real-logs``, ``iig``, ``explore``, ``stress``) to ``sub``."""
    p: argparse.ArgumentParser = sub.add_parser(
        "experiment",
        help="run a paper experiment (resumable) and write its table and figures",
        description="Runs an experiment as a resumable sweep of runs in spawn worker processes on this machine "
        "or on a Dask cluster (--executor dask); rerunning the same command with --resume skips finished runs "
        "(after checking that the folder's runs were made with the same settings), --force starts the folder anew.",
    )
    exp = p.add_subparsers(dest="experiment", metavar="EXPERIMENT")
    exp.required = True
    _add_table1(exp)
    _add_real_logs(exp)
    _add_iig(exp)
    _add_explore(exp)
    _add_stress(exp)
    return p


def _cmd_stress(args: argparse.Namespace, out: Path, sweep_options: dict[str, Any]) -> int:
    from crlam.experiments.stress import run_stress
    from crlam.experiments.stress_variants import StressSettings
    from crlam.slam.presets import load_config_file, resolve

    if args.config is not None:
        stored = load_config_file(args.config)
        base = resolve(stored.preset, stored.settings | slam_overrides(args))
    else:
        base = resolve(args.preset or DEFAULT_PRESET, slam_overrides(args))
    settings = StressSettings(
        odom_shift_s=args.odom_shift,
        heading_error_factor=args.heading_error_factor,
        turn_rate=args.turn_rate,
        no_return_fraction=args.no_return_fraction,
        seed=args.stress_seed,
    )
    print_settings(args, base_settings=base, executor=sweep_options["executor"].describe())
    res = run_stress(
        args.log,
        out,
        relations=args.relations,
        reference=args.reference,
        variants=args.variants,
        seeds=args.runs,
        base=base,
        settings=settings,
        max_scans=args.max_scans,
        tolerance=args.tolerance,
        threads=args.threads,
        report_only=args.report_only,
        **sweep_options,
    )
    print(res.files["table"].read_text())
    return 0 if not res.errors else 1


def _add_stress(exp: argparse._SubParsersAction) -> None:  # type: ignore[type-arg]
    from crlam.experiments.stress_variants import STRESS_VARIANTS

    st = exp.add_parser(
        "stress",
        help="the default SLAM on stress variants of a CARMEN log, against the unstressed run",
        description="Writes stress variants of a CARMEN log (odometry stamps shifted, the odometry's heading error "
        "tripled in turns, every second beam, 10 %% of the readings made no-returns, a laser turned 180 deg or "
        "mounted upside down without the log saying so; exact definitions in the documentation, "
        "docs/results/stress.md), runs the SLAM settings on each and on the log itself with several seeds, and "
        "writes table.md: every seed's error, the worst seed against the unstressed mean, pass when within "
        "--tolerance.",
    )
    inp = group(st, "input")
    inp.add_argument("log", type=input_file, help="CARMEN log (plain, .gz or .bz2) or a dataset name (intel, aces)")
    ev = inp.add_mutually_exclusive_group(required=True)
    ev.add_argument("--relations", type=input_file, help="Kuemmerle relations file or dataset name (intel-relations)")
    ev.add_argument("--reference", type=input_file, help="ground-truth TUM trajectory (position RMSE)")
    inp.add_argument("--max-scans", type=positive_int, default=None, help="only the first N scans of the log")
    _sweep_output(st, report_only=True)
    grid = group(st, "run control", "the grid of runs")
    grid.add_argument(
        "--variants",
        action=ListAction,
        choices=list_choices(STRESS_VARIANTS),
        default=list(STRESS_VARIANTS),
        help=f"stress variants (default: all: {' '.join(STRESS_VARIANTS)}); the unstressed run is always added",
    )
    grid.add_argument("--runs", type=positive_int, default=3, help="seeds per variant (default: 3)")
    grid.add_argument(
        "--tolerance", type=positive_float, default=1.5, help="pass: every seed within this factor of the unstressed mean"
    )
    sizes = group(st, "stresses", "the sizes of the stresses")
    sizes.add_argument("--odom-shift", type=finite_float, default=0.15, metavar="S", help="odom_shift: seconds (default: 0.15)")
    sizes.add_argument(
        "--heading-error-factor",
        type=nonnegative_float,
        default=3.0,
        help="turn_heading: factor on the odometry's heading error in turns (default: 3)",
    )
    sizes.add_argument(
        "--turn-rate", type=nonnegative_float, default=0.2, help="turn_heading: a turn is faster than this, rad/s (default: 0.2)"
    )
    sizes.add_argument(
        "--no-return-fraction", type=nonnegative_float, default=0.1, help="no_returns: fraction of readings (default: 0.1)"
    )
    sizes.add_argument("--stress-seed", type=int, default=0, help="seed of the no-returns' draw (default: 0)")
    _workers(st, threads=True)
    settings = group(st, "settings", "a preset or a stored configuration; every flag of the groups below overrides it")
    source = settings.add_mutually_exclusive_group()
    add_preset_option(source, DEFAULT_PRESET)
    source.add_argument("--config", metavar="FILE", help="the [slam] settings of FILE, a run folder's config.toml")
    add_slam_flags(st, (*_SWEEP_FLAGS, *_REAL_LOG_FLAGS, "--particles", "--max-range", "--time-offset"))
    add_executor_options(st)
    st.set_defaults(func=cmd_experiment)
