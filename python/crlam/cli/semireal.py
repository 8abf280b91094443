"""``crlam semireal``: the real scans of a GMapping-corrected log with a drifting odometry of our
own, written as a CARMEN log with its ground truth."""

from __future__ import annotations

import argparse
import json
from pathlib import Path

from crlam.cli.conventions import add_output_options, group, input_file, print_settings
from crlam.cli.options import finite_float, nonnegative_float, positive_float, positive_int, staged_output

__all__ = ["add_parser", "cmd_semireal"]


def cmd_semireal(args: argparse.Namespace) -> int:
    from crlam.experiments.semireal import SemiRealSettings, write_semireal

    settings = SemiRealSettings(
        seed=args.seed,
        trans_scale=args.trans_scale,
        trans_noise=args.trans_noise,
        rot_scale=args.rot_scale,
        heading_bias=args.heading_bias,
        rot_noise=args.rot_noise,
        rot_per_trans=args.rot_per_trans,
        turn_rate=args.turn_rate,
        turn_slip=args.turn_slip,
        laser_lag=args.laser_lag,
        stamps=args.stamps,
        speed=args.speed,
        turn_speed=args.turn_speed,
    )
    print_settings(args)
    with staged_output(args) as stage:
        summary = write_semireal(args.log, stage, settings, max_scans=args.max_scans)
    summary["files"] = {k: str(Path(args.out) / v) for k, v in summary["files"].items()}
    print(json.dumps(summary, indent=2))
    return 0


def add_parser(sub: argparse._SubParsersAction) -> argparse.ArgumentParser:  # type: ignore[type-arg]
    """Add ``semireal`` to ``sub``."""
    p: argparse.ArgumentParser = sub.add_parser(
        "semireal",
        help="real scans at GMapping-corrected poses with a drifting odometry: a log with ground truth",
        description="Reads a GMapping-corrected CARMEN log (e.g. the data folder's corrected/*-corrected.log.gz, or a "
        "dataset name such as aces-corrected), keeps its scans and takes its corrected poses as the ground truth, "
        "draws a drifting odometry (scale errors, noise, a heading bias per metre, slip in turns) and optionally a "
        "laser lag, and writes log.clf, groundtruth.tum, odometry.tum and semireal.json. Same seed, same bytes.",
    )
    inp = group(p, "input")
    inp.add_argument("log", type=input_file, help="a GMapping-corrected CARMEN log (plain, .gz or .bz2) or a dataset name")
    inp.add_argument("--max-scans", type=positive_int, default=None, help="only the first N scans")
    inp.add_argument(
        "--stamps",
        choices=("auto", "log", "synthetic"),
        default="auto",
        help="the scans' stamps: the log's, or made from the motion at --speed/--turn-speed; auto: the log's when "
        "they increase strictly (default: auto)",
    )
    inp.add_argument("--speed", type=positive_float, default=0.5, help="synthetic stamps: speed, m/s (default: 0.5)")
    inp.add_argument("--turn-speed", type=positive_float, default=0.8, help="synthetic stamps: turn rate, rad/s (default: 0.8)")
    odo = group(p, "odometry", "per scan-to-scan step of true travel d (m) and turn a (rad)")
    odo.add_argument("--trans-scale", type=finite_float, default=0.02, help="translation scale error (default: 0.02)")
    odo.add_argument("--trans-noise", type=nonnegative_float, default=0.03, help="translation noise, m per m (default: 0.03)")
    odo.add_argument("--rot-scale", type=finite_float, default=0.02, help="heading scale error (default: 0.02)")
    odo.add_argument("--heading-bias", type=finite_float, default=0.005, help="heading drift, rad per m (default: 0.005)")
    odo.add_argument("--rot-noise", type=nonnegative_float, default=0.03, help="heading noise, rad per rad (default: 0.03)")
    odo.add_argument("--rot-per-trans", type=nonnegative_float, default=0.005, help="heading noise, rad per m (default: 0.005)")
    odo.add_argument(
        "--turn-rate", type=nonnegative_float, default=0.2, help="a step turning faster is a turn, rad/s (default: 0.2)"
    )
    odo.add_argument(
        "--turn-slip", type=nonnegative_float, default=0.1, help="slip in turns: extra noise per rad and per m (default: 0.1)"
    )
    odo.add_argument(
        "--laser-lag",
        type=nonnegative_float,
        default=0.0,
        help="the laser stamps each scan this many seconds late; the log's time offset is then minus this (default: 0)",
    )
    odo.add_argument("--seed", type=int, default=0, help="random seed (default: 0)")
    add_output_options(p)
    p.set_defaults(func=cmd_semireal)
    return p
