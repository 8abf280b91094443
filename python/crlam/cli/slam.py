"""``crlam slam``: RBPF-CLAM (or RBPF-OGM) on a CARMEN log or a ROS bag, written as a run folder."""

from __future__ import annotations

import argparse
from pathlib import Path
from typing import TYPE_CHECKING, Any

from crlam.cli.conventions import add_output_options, group, input_file, print_settings
from crlam.cli.live import add_foxglove_options, hold_for_clients, open_live_view, slam_live_feed
from crlam.cli.options import (
    SLAM_FLAGS,
    add_bag_options,
    add_odometry_options,
    add_preset_option,
    add_slam_flags,
    bag_options,
    laser_mount_mode,
    positive_int,
    slam_overrides,
    staged_output,
    stored_input_options,
)
from crlam.slam.presets import DEFAULT_PRESET

if TYPE_CHECKING:
    from crlam.slam import SlamConfig

__all__ = ["add_parser", "cmd_slam", "slam_config_of", "slam_input_of"]

#: The metrics ``crlam slam`` prints when the run was evaluated.
_EVALUATIONS = tuple(
    f"{what}{suffix}"
    for what in ("reference", "relations")
    for suffix in ("", "_best_path", "_best_path_means", "_max_weight", "_mode", "_smoothed", "_smoothed_means")
)


def slam_config_of(args: argparse.Namespace) -> tuple[SlamConfig, int | None]:
    """``crlam slam``'s configuration and scan limit: the preset (``--preset``, default robust) or
    the settings of ``--config FILE``, with every SLAM flag given on top."""
    from crlam.slam.presets import load_config_file, resolve

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
    from crlam.slam.presets import load_config_file

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
    prior = None
    saved_settings = False
    if args.continue_from is not None:
        from crlam.slam.prior import load_slam_prior

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
    print_settings(args, slam_settings=config, input_options=input_options | {"odometry": odometry, "max_scans": max_scans})
    with open_live_view(args, "crlam slam") as view:
        feed = slam_live_feed(args, view)
        res = _run(args, config, max_scans, input_options, odometry, prior, feed)
        if feed is not None and feed.publish_final():
            print(f"foxglove: final map published on {view.url}", flush=True)
            if args.foxglove_wait:
                hold_for_clients(view, f"the run is written to {args.out}")
    m = res.metrics
    print(f"odometry: {m['input']['odometry']} ({m['input']['odometry_choice']})")
    deviations = [d.split(" = ", 1)[0] for d in m["deviations_from_paper"]]
    print(f"preset {config.preset or '(none)'}; differs from the paper in: {', '.join(deviations) or 'nothing'}")
    frame = m.get("map_frame") or {}
    if frame.get("turn_deg"):
        print(f"map frame: the grid turned by {frame['turn_deg']:.1f} deg onto the first scan's walls")
    if frame.get("sub_cell"):
        print(f"sub-cell geometry: on (sub_cell = {config.sub_cell}; chord causes and hit means)")
    print(
        f"{m['n_scans']} scans ({m['n_processed']} processed) in {m['wall_time_s']:.1f} s, "
        f"{m['scans_per_s']:.2f} scans/s, peak RSS {m['filter_peak_rss_mb']:.0f} MB filtering, "
        f"{m['command_peak_rss_mb']:.0f} MB with the outputs -> {args.out}"
    )
    for key in _EVALUATIONS:
        if key in m:
            print(f"{key}: " + ", ".join(f"{k}={v:.4g}" for k, v in m[key].items() if isinstance(v, float)))
    return 0


def _run(
    args: argparse.Namespace,
    config: SlamConfig,
    max_scans: int | None,
    input_options: dict[str, Any],
    odometry: str,
    prior: Any,
    feed: Any,
) -> Any:
    """The run into a staged ``--out`` (the folder appears whole once the run is written)."""
    from crlam.experiments.slam_run import run_slam_log

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
            verbose=args.verbose,
            laser_mount=laser_mount_mode(args),
            live_feed=feed,
        )
    return res


def add_parser(sub: argparse._SubParsersAction) -> argparse.ArgumentParser:  # type: ignore[type-arg]
    """Add ``slam`` to ``sub``."""
    p: argparse.ArgumentParser = sub.add_parser(
        "slam",
        help="run RBPF-CLAM (or RBPF-OGM) on a CARMEN log or a ROS bag and write a run folder",
        description="Runs a Rao-Blackwellized particle filter on a log and writes config.toml, trajectory.tum "
        "(the estimate to use: one pose per scan, sorted by time), estimates/ (the other estimates), README.txt (what "
        "each file holds), metrics.json, map.pgm/yaml, belief.npz and figures. The settings are a "
        "named preset (--preset, default robust) or a run folder's config.toml (--config); every SLAM flag given "
        "overrides them.",
    )
    inp = group(p, "input")
    inp.add_argument(
        "log",
        type=input_file,
        help="CARMEN log (plain, .gz or .bz2; - reads standard input), ROS bag (folder with metadata.yaml, .bag or "
        ".mcap) or a dataset name (intel, aces; see crlam data list)",
    )
    inp.add_argument(
        "--max-scans", type=positive_int, default=None, help="stop after this many scans (with --config: the file's, if any)"
    )
    out = add_output_options(p, out="run folder")
    out.add_argument(
        "--mcap",
        action="store_true",
        help="also write run.mcap (ROS 2 messages for Foxglove or ros2 bag play): /scan, /tf (map -> odom -> "
        "base_link), /tf_static, /particles (PoseArray), /path, /map and /map_confidence (OccupancyGrid)",
    )
    settings = group(p, "settings", "a preset or a stored configuration; every flag of the groups below overrides it")
    source = settings.add_mutually_exclusive_group()
    add_preset_option(source, DEFAULT_PRESET)
    source.add_argument(
        "--config",
        metavar="FILE",
        help="start from the [slam] settings (and [run] max_scans) of FILE, a run folder's config.toml, instead of a "
        "preset: re-runs that configuration; flags given beside it still override it",
    )
    settings.add_argument(
        "--continue",
        dest="continue_from",
        metavar="DIR",
        help="continue a saved crlam slam run: every particle starts with DIR's map, around DIR's final estimate (its "
        "covariance), and the run goes on mapping LOG (which takes up where DIR's log ended); DIR's settings unless "
        "--preset or --config is given; DIR is only read",
    )
    add_slam_flags(p, list(SLAM_FLAGS))
    ev = group(p, "evaluation")
    ev.add_argument("--reference", type=input_file, help="ground-truth TUM trajectory: report MAE x, y, theta and position RMSE")
    ev.add_argument(
        "--relations",
        type=input_file,
        help="Kuemmerle relations file or dataset name (intel-relations): report the relations metric",
    )
    add_bag_options(p)
    add_odometry_options(p)
    add_foxglove_options(p)
    p.set_defaults(func=cmd_slam)
    return p
