"""``crlam convert``: a CARMEN log to a ROS 2 bag (MCAP storage), or a ROS bag to a CARMEN log."""

from __future__ import annotations

import argparse

from crlam.cli_options import add_bag_options, add_force_option, bag_options

__all__ = ["add_convert_parser", "cmd_convert"]


def cmd_convert(args: argparse.Namespace) -> int:
    from crlam.io.convert import convert
    from crlam.run_folder import check_output, staged_file

    out = check_output(args.output, force=args.force, what="output")
    with staged_file(out) as stage:
        summary = convert(args.input, stage, **bag_options(args))
    print(summary.describe().replace(str(stage), str(out)).replace(str(stage.parent), str(out.parent)))
    return 0


def add_convert_parser(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser(
        "convert",
        help="convert a CARMEN log to a ROS 2 bag (MCAP) or a ROS bag to a CARMEN log",
        description="The direction follows IN. A CARMEN log becomes a ROS 2 bag with MCAP storage (OUT: a new "
        "folder, or a single file if OUT ends in .mcap): sensor_msgs/LaserScan on /scan, nav_msgs/Odometry on /odom "
        "(each scan's own odometry at the scan's stamp, and the ODOM records), base_link -> laser on /tf_static. A ROS "
        "bag (a folder with metadata.yaml, a .bag or a .mcap file) becomes a CARMEN log (OUT: plain, .gz or .bz2), "
        "read as crlam slam reads it: scans with their odometry, and every odometry reading as an ODOM line.",
    )
    p.add_argument("input", metavar="IN", help="CARMEN log or ROS bag")
    p.add_argument("output", metavar="OUT", help="ROS 2 bag folder or .mcap file (from a CARMEN log); CARMEN log (from a bag)")
    add_force_option(p)
    add_bag_options(p)
    p.set_defaults(func=cmd_convert)
