"""``crlam localize``: Monte Carlo localization of a log or a ROS bag on a saved map."""

from __future__ import annotations

import argparse
import math
from typing import Any

from crlam.cli.conventions import add_output_options, group, input_file, map_file, print_settings
from crlam.cli.live import add_foxglove_options, hold_for_clients, open_live_view, slam_live_feed
from crlam.cli.options import (
    add_bag_options,
    bag_options,
    nonnegative_float,
    nonnegative_int,
    positive_float,
    positive_int,
    staged_output,
    time_offset,
)

__all__ = ["add_parser", "cmd_localize", "localize_config_of"]


def localize_config_of(args: argparse.Namespace) -> Any:
    """The :class:`crlam.localize.LocalizeConfig` of the command line's flags."""
    from crlam.localize import LocalizeConfig

    given: dict[str, Any] = {}
    for name in (
        "min_particles",
        "max_particles",
        "kld_err",
        "alpha_slow",
        "alpha_fast",
        "tempering",
        "max_beams",
        "model",
        "max_range",
        "motion",
        "linear_update",
        "angular_update",
        "resample_threshold",
        "min_cluster",
        "keep_ratio",
        "min_bin",
        "place_xy",
        "spread_particles",
        "spread_climb",
        "convergence_odds",
        "free_threshold",
        "tail_tolerance",
        "seed",
    ):
        v = getattr(args, name)
        if v is not None:
            given[name] = v
    # The flags shared with crlam slam keep slam's names: --weight-stride, --sigma-range.
    if args.weight_stride is not None:
        given["beam_stride"] = args.weight_stride
    if args.sigma_range is not None:
        given["sigma_hit"] = args.sigma_range
    if args.motion_params is not None:
        given["motion_params"] = tuple(args.motion_params)
    if args.model_param:
        given["model_params"] = tuple(args.model_param)
    if args.skip_no_returns:
        given["skip_no_returns"] = True
    return LocalizeConfig(**given)


def _model_param(text: str) -> tuple[str, float]:
    name, sep, value = text.partition("=")
    try:
        v = float(value)
    except ValueError:
        v = math.nan
    if not sep or not name or not math.isfinite(v):
        raise argparse.ArgumentTypeError(f"expected NAME=VALUE with a finite number, got {text!r}")
    return name.strip(), v


def _initial(args: argparse.Namespace) -> tuple[Any, Any]:
    import numpy as np

    from crlam.errors import ConfigError

    if args.initial_pose is None:
        if args.initial_cov is not None:
            raise ConfigError("--initial-cov needs --initial-pose")
        return None, None
    if args.global_:
        raise ConfigError("--global starts without a pose: drop --initial-pose (or --global)")
    pose = np.array(args.initial_pose, dtype=np.float64)
    if args.initial_cov is None:
        return pose, None
    c = np.array(args.initial_cov, dtype=np.float64)
    if c.size == 3:
        return pose, np.diag(c)
    if c.size == 9:
        return pose, c.reshape(3, 3)
    raise ConfigError(f"--initial-cov takes 3 variances (xx yy aa) or the 9 entries of a 3 x 3 matrix, got {c.size} values")


def cmd_localize(args: argparse.Namespace) -> int:
    from crlam.localize.map import Nav2Prior

    config = localize_config_of(args)
    pose, cov = _initial(args)
    prior = Nav2Prior(
        occupied_mean=args.nav2_occupied,
        free_mean=args.nav2_free,
        unknown_mean=args.nav2_unknown,
        free_thresh=args.nav2_free_thresh,
    )
    print_settings(args, localize_settings=config, initial_pose=pose, initial_cov=cov)
    if args.trials:
        from crlam.experiments.localize_trials import run_global_trials

        if args.foxglove is not None:
            from crlam.errors import ConfigError

            raise ConfigError("--foxglove shows one localization as it runs, not --trials: drop one of them")

        if pose is not None:
            from crlam.errors import ConfigError

            raise ConfigError("--trials runs global localizations: drop --initial-pose")
        summary = run_global_trials(
            args.log,
            args.map,
            args.out,
            config,
            n_trials=args.trials,
            max_travel=args.trial_travel,
            target_travel=args.target_travel,
            trial_seed=args.trial_seed,
            reference=args.reference,
            nav2_prior=prior,
            bag_options=bag_options(args),
            progress=not args.quiet,
            resume=args.resume,
            force=args.force,
        )
        print(
            f"{summary['n_trials']} global localizations: {summary['n_converged_correct']} converged to the reference, "
            f"{summary['n_within_target']} within {args.target_travel:g} m of travel "
            f"({100 * summary['fraction_within_target']:.0f} %) -> {args.out}"
        )
        return 0
    from crlam.experiments.localize_run import run_localize_log

    if args.resume:
        from crlam.errors import ConfigError

        raise ConfigError("--resume continues --trials; a single localization is run whole (--force replaces it)")
    if pose is None:
        print("no --initial-pose: global localization (particles over the map's free space)")
    with open_live_view(args, "crlam localize") as view:
        feed = slam_live_feed(args, view)
        with staged_output(args) as stage:
            res = run_localize_log(
                args.log,
                args.map,
                stage,
                config,
                initial_pose=pose,
                initial_cov=cov,
                nav2_prior=prior,
                relations=args.relations,
                reference=args.reference,
                max_scans=args.max_scans,
                progress=not args.quiet,
                bag_options=bag_options(args),
                time_offset=args.time_offset,
                live_feed=feed,
            )
        if feed is not None and feed.publish_final():
            print(f"foxglove: final path published on {view.url}", flush=True)
            if args.foxglove_wait:
                hold_for_clients(view, f"the run is written to {args.out}")
    m = res.metrics
    print(
        f"{m['n_scans']} scans ({m['n_processed']} processed) in {m['wall_time_s']:.1f} s, {m['scans_per_s']:.1f} scans/s "
        f"(the log: {m['n_scans'] / max(m['log_duration_s'], 1e-9):.1f} scans/s); particles mean "
        f"{m['particles'].get('mean', math.nan):.0f}, max {m['particles'].get('max', math.nan):.0f} -> {args.out}"
    )
    conv = m["convergence"]
    if conv is None:
        print("did not converge")
    else:
        print(f"converged at scan {conv['scan_index']}, {conv['time_s']:.1f} s and {conv['distance_m']:.2f} m after the start")
    ep = m["endpoints_within_0.1m"]
    print(
        "beam endpoints within 0.1 m of an occupied cell: "
        + ", ".join(f"{k.replace('_', ' ')} {v:.3f}" for k, v in ep.items() if v is not None)
    )
    for key in ("relations", "reference"):
        if key in m:
            print(f"{key}: " + ", ".join(f"{k}={v:.4g}" for k, v in m[key].items() if isinstance(v, float)))
    return 0


def add_parser(sub: argparse._SubParsersAction) -> argparse.ArgumentParser:  # type: ignore[type-arg]
    """Add ``localize`` to ``sub``."""
    p: argparse.ArgumentParser = sub.add_parser(
        "localize",
        help="Monte Carlo localization of a log or a ROS bag on a saved map (a crlam run folder, belief.npz or Nav2 map.yaml)",
        description="AMCL's algorithm (KLD-adaptive particle count, random particles when the scans stop fitting the "
        "map, clusters) weighing each scan with the CRM predictive likelihood. With --initial-pose the particles start "
        "around it, else (--global) over the map's free space, and the run reports when the estimate converges. Writes "
        "config.toml, trajectory.tum (one pose per scan), particles.csv, metrics.json and localization.png.",
    )
    inp = group(p, "input")
    inp.add_argument(
        "log",
        type=input_file,
        help="CARMEN log (plain, .gz or .bz2; - reads standard input), ROS bag (folder with metadata.yaml, .bag or "
        ".mcap) or a dataset name (intel, aces; see crlam data list)",
    )
    inp.add_argument(
        "--map",
        required=True,
        type=map_file,
        help="a crlam map/slam run folder, its belief.npz, or a Nav2 map.yaml (or a dataset name)",
    )
    inp.add_argument("--max-scans", type=positive_int, default=None, help="stop after this many scans")
    add_output_options(p, out="run folder (with --trials: the trials' folder)", replace="resume")
    start = group(p, "start")
    start.add_argument(
        "--initial-pose", type=float, nargs=3, default=None, metavar=("X", "Y", "YAW"), help="map frame (m, m, rad)"
    )
    start.add_argument(
        "--initial-cov",
        type=float,
        nargs="+",
        default=None,
        metavar="C",
        help="its covariance: 3 variances (m^2 m^2 rad^2) or the 9 entries of a 3 x 3 matrix (default: 0.25 0.25 0.0685, AMCL's)",
    )
    start.add_argument("--global", dest="global_", action="store_true", help="no initial pose: particles over the free space")
    start.add_argument(
        "--trials",
        type=positive_int,
        default=None,
        metavar="N",
        help="N global localizations from random scans of the log (the same N for a --trial-seed), each until it "
        "converges and holds, or --trial-travel metres; writes trials.csv and a summary (--resume continues them)",
    )
    start.add_argument(
        "--trial-travel", type=positive_float, default=30.0, help="travel after which a trial stops (m, default 30)"
    )
    start.add_argument(
        "--target-travel",
        type=positive_float,
        default=10.0,
        help="the trials' target: converged within this travel (m, default 10)",
    )
    start.add_argument("--trial-seed", type=nonnegative_int, default=0, help="seed of the trials' start scans (default 0)")
    f = group(p, "filter", "defaults: AMCL's where it has one")
    # AMCL's min_particles / max_particles; --max-particles is the resource limit of every command.
    f.add_argument(
        "--kld-min-particles", dest="min_particles", type=positive_int, default=None, help="KLD lower bound (default 100)"
    )
    f.add_argument(
        "--kld-max-particles",
        dest="max_particles",
        type=positive_int,
        default=None,
        help="KLD upper bound and the particles of a global start (default 5000)",
    )
    f.add_argument("--kld-err", type=positive_float, default=None, help="KLD epsilon (default 0.01)")
    f.add_argument(
        "--alpha-slow", type=nonnegative_float, default=None, help="recovery: long-term rate (default 0.001; 0 0: off)"
    )
    f.add_argument("--alpha-fast", type=nonnegative_float, default=None, help="recovery: short-term rate (default 0.1)")
    f.add_argument("--tempering", type=positive_float, default=None, help="weight tempering tau (default 10)")
    f.add_argument("--weight-stride", type=positive_int, default=None, help="every n-th beam of the weights (default 1)")
    f.add_argument(
        "--max-beams",
        type=nonnegative_int,
        default=None,
        help="at most this many beams, spread evenly (default 60, AMCL's laser_max_beams; 0: all)",
    )
    f.add_argument(
        "--model",
        choices=("crm", "crm-exact", "likelihood_field", "beam"),
        default=None,
        help="measurement model: crm (default: the CRM likelihood, each beam's log within "
        "2 x --tail-tolerance + 1e-7, --max-beams beams), "
        "crm-exact (every beam to rounding), likelihood_field or beam (AMCL's, nav2 defaults; m >= 0.5 is an obstacle)",
    )
    f.add_argument(
        "--model-param",
        type=_model_param,
        action="append",
        default=None,
        metavar="NAME=VALUE",
        help="a parameter of AMCL's model (likelihood_field: z_hit z_rand sigma_hit max_dist; beam: z_hit z_short "
        "z_max z_rand sigma_hit lambda_short); repeatable",
    )
    f.add_argument(
        "--resample-threshold", type=nonnegative_float, default=None, help="resample when N_eff < this x n (default 0.5)"
    )
    f.add_argument(
        "--min-cluster",
        type=nonnegative_int,
        default=None,
        help="particles every competing cluster keeps through resampling, with its weight (0: off; see crlam.localize)",
    )
    f.add_argument(
        "--min-bin",
        type=nonnegative_int,
        default=None,
        help="particles every plausible pose bin keeps through resampling while the set is spread (0: off)",
    )
    f.add_argument(
        "--place-xy",
        type=nonnegative_float,
        default=None,
        help="while spread, keep --min-cluster per place of this size (m, 90 deg), not per cluster (default 2; 0: off)",
    )
    f.add_argument(
        "--spread-particles",
        type=nonnegative_int,
        default=None,
        help="most particles while the set is spread (a global start draws this many; 0: --max-particles)",
    )
    f.add_argument(
        "--spread-climb",
        action=argparse.BooleanOptionalAction,
        default=None,
        help="while spread, move each particle to the nearby pose where the scan's endpoints fit the map best "
        "before weighing it (default: on)",
    )
    f.add_argument(
        "--keep-ratio",
        type=positive_float,
        default=None,
        help="a cluster competes while its weight is at least this x the heaviest's (default 1e-3)",
    )
    f.add_argument(
        "--convergence-odds",
        type=positive_float,
        default=None,
        help="convergence needs the heaviest cluster this many times as heavy as the next one",
    )
    f.add_argument(
        "--free-threshold", type=nonnegative_float, default=None, help="free cells: expected occupancy <= this (default 0.25)"
    )
    f.add_argument(
        "--tail-tolerance",
        type=positive_float,
        default=None,
        help="relative likelihood a beam walk, and its hit window, may leave out (1e-6)",
    )
    f.add_argument("--seed", type=nonnegative_int, default=None, help="random seed (default 0)")
    s = group(p, "sensor")
    s.add_argument("--max-range", type=positive_float, default=None, help="z_max in m (default: the map's, at most the laser's)")
    s.add_argument("--sigma-range", type=positive_float, default=None, help="range noise sigma in m (default: the map's)")
    s.add_argument(
        "--skip-no-returns",
        action="store_true",
        help="leave no-returns out of the likelihood (AMCL does): for lasers that report failed readings as no-returns",
    )
    m = group(p, "motion model")
    m.add_argument("--motion", choices=("gaussian", "thrun", "gmapping"), default=None, help="odometry model (default gmapping)")
    m.add_argument("--motion-params", type=float, nargs="+", default=None, help="its parameters (default: its own)")
    m.add_argument(
        "--linear-update",
        type=nonnegative_float,
        default=None,
        help="process after this travel in m (default 0.005: every scan while moving)",
    )
    m.add_argument("--angular-update", type=nonnegative_float, default=None, help="... or this rotation in rad (default 0.005)")
    m.add_argument(
        "--time-offset",
        type=time_offset,
        default="auto",
        metavar="auto|off|S",
        help="offset in s of the odometry's stamps against the laser's: auto estimates it from the log and re-attaches "
        "each scan's odometry at its corrected stamp when clearly identified; off leaves the odometry as logged; a "
        "number applies it (default: auto; metrics.json records it)",
    )
    n = group(p, "Nav2 map as a CRM prior", "for a .yaml map")
    n.add_argument("--nav2-occupied", type=positive_float, default=0.9, help="expected occupancy of an occupied cell (0.9)")
    n.add_argument("--nav2-free", type=positive_float, default=0.01, help="expected occupancy of a free cell (0.01)")
    n.add_argument(
        "--nav2-unknown",
        type=positive_float,
        default=0.5,
        help="expected occupancy of an unknown cell (0.5: the uniform pmf; AMCL's beam model stops at unknown cells "
        "from 0.5 up); a scale or raw value q in (0, 1) gets free + q (occupied - free)",
    )
    n.add_argument(
        "--nav2-free-thresh",
        type=nonnegative_float,
        default=None,
        help="read the image with this free_thresh instead of the YAML's (e.g. 0.196, map_saver's, when a YAML's 0.25 "
        "makes the unknown grey 205 free)",
    )
    e = group(p, "evaluation")
    e.add_argument("--relations", type=input_file, help="Kuemmerle relations file: report the relations metric")
    e.add_argument(
        "--reference", type=input_file, help="TUM trajectory in the map's frame: report errors against it (and judge --trials)"
    )
    add_bag_options(p)
    add_foxglove_options(p)
    p.set_defaults(func=cmd_localize)
    return p
