"""``crlam convert``: a CARMEN log to a ROS 2 bag (MCAP storage), or a ROS bag to a CARMEN log."""

from __future__ import annotations

import argparse

from crlam.cli.conventions import add_output_options, group, input_file, print_settings, say, warn
from crlam.cli.options import add_bag_options, bag_options

__all__ = ["add_parser", "cmd_convert"]


def cmd_convert(args: argparse.Namespace) -> int:
    from crlam.errors import ConfigError
    from crlam.io.convert import convert
    from crlam.io.run_folder import check_output, staged_file

    target = args.out
    if args.legacy_output is not None:
        if target is not None:
            raise ConfigError(f"two outputs: {args.legacy_output} and -o {target}; give -o/--out only")
        warn(f"the positional OUT is deprecated; use -o {args.legacy_output}")
        target = args.legacy_output
    if target is None:
        raise ConfigError("give the output with -o/--out")
    out = check_output(target, force=args.force, what="output")
    print_settings(args, bag_options=bag_options(args))
    with staged_file(out) as stage:
        summary = convert(args.input, stage, **bag_options(args))
    text = summary.describe().replace(str(stage), str(out)).replace(str(stage.parent), str(out.parent))
    if args.quiet:
        print(out)
    else:
        say(args, text)
    return 0


def add_parser(sub: argparse._SubParsersAction) -> argparse.ArgumentParser:  # type: ignore[type-arg]
    """Add ``convert`` to ``sub``."""
    p: argparse.ArgumentParser = sub.add_parser(
        "convert",
        help="convert a CARMEN log to a ROS 2 bag (MCAP) or a ROS bag to a CARMEN log",
        description="The direction follows IN. A CARMEN log becomes a ROS 2 bag with MCAP storage (--out: a new "
        "folder, or a single file if it ends in .mcap): sensor_msgs/LaserScan on /scan, nav_msgs/Odometry on /odom "
        "(each scan's own odometry at the scan's stamp, and the ODOM records), base_link -> laser on /tf_static. A ROS "
        "bag (a folder with metadata.yaml, a .bag or a .mcap file) becomes a CARMEN log (--out: plain, .gz or .bz2), "
        "read as crlam slam reads it: scans with their odometry, and every odometry reading as an ODOM line.",
    )
    group(p, "input").add_argument(
        "input", metavar="IN", type=input_file, help="CARMEN log (- reads standard input), ROS bag or dataset name"
    )
    add_output_options(
        p,
        out="ROS 2 bag folder or .mcap file (from a CARMEN log); CARMEN log (from a bag)",
        required=False,
    )
    # The older form `crlam convert IN OUT`: still read, with a deprecation warning.
    legacy = p.add_argument("legacy_output", nargs="?", default=None, metavar="OUT", help=argparse.SUPPRESS)
    legacy.target = next(a for a in p._actions if "--out" in a.option_strings)  # type: ignore[attr-defined]  # the renames table
    add_bag_options(p)
    p.set_defaults(func=cmd_convert)
    return p
