"""``crlam map``: a confidence-rich map from a log or a ROS bag whose poses are trusted."""

from __future__ import annotations

import argparse
from pathlib import Path

from crlam.cli.conventions import add_output_options, deprecated_alias, group, input_file, print_settings
from crlam.cli.options import (
    BATCH_KERNEL_HELP,
    BATCH_KERNELS,
    CAUSE_KERNELS,
    add_bag_options,
    bag_options,
    positive_float,
    positive_int,
    staged_output,
)

__all__ = ["add_parser", "cmd_map"]


def _mapping_config(args: argparse.Namespace):  # type: ignore[no-untyped-def]
    from crlam.mapping import MappingConfig

    return MappingConfig(
        resolution=args.resolution,
        max_range=args.max_range,
        model=args.crm_model,
        levels=args.levels,
        scan_update=args.scan_update,
        batch_kernel=args.batch_kernel,
        hits_first=args.hits_first,
        cause_kernel=args.cause_kernel,
        beam_stride=args.map_stride,
    )


def cmd_map(args: argparse.Namespace) -> int:
    from crlam.experiments.known_poses import map_log
    from crlam.io.run_folder import moved

    config = _mapping_config(args)
    print_settings(args, mapping_settings=config)
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
            no_return=args.no_return,
        )
    print(f"mapped {run.n_scans} scans in {run.wall_time_s:.1f} s ({run.n_scans / max(run.wall_time_s, 1e-9):.0f} scans/s)")
    for name, path in files.items():
        print(f"  {name:12s} {moved(path, stage, Path(args.out))}")
    return 0


def add_map_options(p: argparse.ArgumentParser) -> None:
    """The CRM settings of ``crlam map`` (group ``map and sensor``)."""
    g = group(p, "map and sensor")
    g.add_argument("--resolution", type=positive_float, default=0.2, help="cell size in metres (default: 0.2)")
    g.add_argument(
        "--max-range", type=positive_float, default=8.0, help="z_max in metres; longer readings are no-returns (default: 8)"
    )
    g.add_argument(
        "--crm-model",
        choices=("ijrr", "mixture", "authors_code"),
        default="ijrr",
        help="sensor cause model of the CRM update (default: ijrr)",
    )
    g.add_argument(
        "--levels",
        choices=("midpoints", "endpoints", "r1_right"),
        default="midpoints",
        help="occupancy level placement (default: midpoints)",
    )
    g.add_argument(
        "--scan-update", choices=("batch", "sequential"), default="batch", help="how the beams of a scan combine (default: batch)"
    )
    g.add_argument(
        "--cause-kernel",
        choices=CAUSE_KERNELS,
        default="midpoint",
        help="where a cause sits in its cell: chord midpoint (spec default) or spread along the chord",
    )
    g.add_argument("--batch-kernel", choices=BATCH_KERNELS, default="windowed", help=BATCH_KERNEL_HELP)
    g.add_argument(
        "--hits-first",
        action=argparse.BooleanOptionalAction,
        default=False,
        help="batch updates: a cell that a beam of the scan makes more occupied ignores the scan's beams that pass "
        "through it to readings far beyond (default: off, every factor, as the spec)",
    )
    g.add_argument("--map-stride", type=positive_int, default=1, help="every n-th beam for the map update (default: 1)")
    g.add_argument(
        "--no-return",
        choices=("z_max", "drop"),
        default="z_max",
        help="what a no-return (inf, NaN, 0, below range_min, at or above range_max) does: the z_max atom, which "
        "clears its beam to z_max (default, the spec), or left out, never clearing a cell (drop: crlam slam's "
        "default preset)",
    )
    deprecated_alias(p, "--model", "--crm-model")
    deprecated_alias(p, "--beam-stride", "--map-stride")


def add_parser(sub: argparse._SubParsersAction) -> argparse.ArgumentParser:  # type: ignore[type-arg]
    """Add ``map`` to ``sub``."""
    p: argparse.ArgumentParser = sub.add_parser(
        "map",
        help="build a confidence-rich map from a log or a ROS bag with trusted poses",
        description="Maps a CARMEN log (plain, .gz or .bz2) or a ROS bag (odometry poses) whose poses are trusted and "
        "writes map.pgm/yaml, belief.npz, ogm.pgm/yaml, map.png and mapping.json.",
    )
    inp = group(p, "input")
    inp.add_argument(
        "log",
        type=input_file,
        help="CARMEN log (- reads standard input), e.g. ../shared/data/corrected/intel-corrected.log.gz, a dataset name "
        "(intel-corrected; see crlam data list), or a ROS bag (folder with metadata.yaml, .bag or .mcap)",
    )
    inp.add_argument(
        "--poses",
        choices=("log", "odometry"),
        default="log",
        help="which pose field to trust: the scan's pose field or its odometry field (default: log)",
    )
    inp.add_argument("--max-scans", type=positive_int, default=None, help="stop after this many scans")
    inp.add_argument("--skip-malformed", action="store_true", help="skip (and count) malformed lines instead of stopping")
    add_output_options(p)
    add_map_options(p)
    add_bag_options(p)
    p.set_defaults(func=cmd_map)
    return p
