"""``crlam simulate``: a robot in a world, written as a CARMEN log with its ground truth."""

from __future__ import annotations

import argparse
import json
from pathlib import Path

from crlam.cli.conventions import add_output_options, group, print_settings, world_arg
from crlam.cli.options import positive_int, staged_output

__all__ = ["add_parser", "cmd_simulate"]


def cmd_simulate(args: argparse.Namespace) -> int:
    from crlam.experiments.simulate import simulate_to_folder
    from crlam.io.run_folder import moved

    print_settings(args)
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


def add_parser(sub: argparse._SubParsersAction) -> argparse.ArgumentParser:  # type: ignore[type-arg]
    """Add ``simulate`` to ``sub``."""
    p: argparse.ArgumentParser = sub.add_parser(
        "simulate",
        help="simulate a robot in a world and write a CARMEN log and ground truth",
        description="Writes log.clf (CARMEN), groundtruth.tum, world.pgm/yaml and simulation.json. Same seed, same bytes.",
    )
    inp = group(p, "input")
    inp.add_argument(
        "--world",
        type=world_arg,
        default="office",
        help="museum, office, a PGM/PNG/Nav2-YAML path or a map dataset (cave-map) (default: office)",
    )
    sensor = group(p, "sensor")
    sensor.add_argument(
        "--sensor",
        choices=("paper", "sick"),
        default="paper",
        help="paper = 1079 beams over 270 deg, 8 m; sick = 180 beams over 180 deg, 80 m (default: paper)",
    )
    add_output_options(p)
    run = group(p, "run control")
    run.add_argument("--scans", type=positive_int, default=500, help="number of scans (default: 500)")
    run.add_argument("--seed", type=int, default=0, help="random seed (default: 0)")
    p.set_defaults(func=cmd_simulate)
    return p
