"""``crlam demo``: the main job on built-in data (simulate, map, SLAM, figures and a report)."""

from __future__ import annotations

import argparse
from pathlib import Path

from crlam.cli.conventions import add_output_options, group, print_settings
from crlam.cli.options import positive_int, staged_output

__all__ = ["add_parser", "cmd_demo"]


def cmd_demo(args: argparse.Namespace) -> int:
    from crlam.experiments.demo import run_demo
    from crlam.io.run_folder import moved

    print_settings(args)
    with staged_output(args) as stage:
        report = run_demo(stage, n_scans=args.scans, seed=args.seed, progress=not args.quiet, quick=args.quick)
    print(f"demo written to {args.out}; open {moved(report, stage, Path(args.out))}")
    return 0


def add_parser(sub: argparse._SubParsersAction) -> argparse.ArgumentParser:  # type: ignore[type-arg]
    """Add ``demo`` to ``sub``."""
    p: argparse.ArgumentParser = sub.add_parser(
        "demo",
        help="simulate the museum world, map it and write figures and a report",
        description="The main job on built-in data: simulate the 90 m x 90 m museum-like world with the paper's "
        "LIDAR, build the confidence-rich map (and the log-odds baseline) with known poses, and write "
        "figures and report.md.",
    )
    add_output_options(p, default="demo-out")
    run = group(p, "run control")
    run.add_argument(
        "--scans", type=positive_int, default=None, help="number of scans to simulate (default: 4000; 300 with --quick)"
    )
    run.add_argument(
        "--quick",
        action="store_true",
        help="a short run of every step (300 scans, few particles, a 10 m exploration) that still writes the figures "
        "and report.md: checks an installation in seconds",
    )
    run.add_argument("--seed", type=int, default=0, help="random seed (default: 0)")
    p.set_defaults(func=cmd_demo)
    return p
