"""Argument types, help texts and option groups shared by the ``crlam`` subcommands."""

from __future__ import annotations

import argparse
from collections.abc import Callable
from typing import TypeVar

__all__ = [
    "BATCH_KERNELS",
    "BATCH_KERNEL_HELP",
    "CAUSE_KERNELS",
    "CAUSE_KERNEL_HELP",
    "LATTICE_STEP_HELP",
    "MATCH_STRIDE_HELP",
    "MOTION_DRAWS",
    "MOTION_DRAWS_HELP",
    "OGM_MAPS",
    "OGM_MAP_HELP",
    "PROPOSALS",
    "PROPOSAL_HELP",
    "PROPOSAL_POSE_HELP",
    "SIGMA_RANGE_HELP",
    "WEIGHT_SMOOTHING_HELP",
    "add_estimate_options",
    "add_likelihood_mode_options",
    "add_map_options",
    "nonnegative_float",
    "nonnegative_int",
    "positive_float",
    "positive_int",
]


_Number = TypeVar("_Number", int, float)


def _parse(text: str, kind: Callable[[str], _Number], what: str) -> _Number:
    """``kind(text)``, with argparse's error naming the value when it is not ``what``."""
    try:
        return kind(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"not {what}: {text!r}") from None


def positive_float(text: str) -> float:
    v = _parse(text, float, "a number")
    if not (v > 0 and v != float("inf")):
        raise argparse.ArgumentTypeError(f"must be a finite number > 0, got {text}")
    return v


def nonnegative_float(text: str) -> float:
    v = _parse(text, float, "a number")
    if not (v >= 0 and v != float("inf")):
        raise argparse.ArgumentTypeError(f"must be a finite number >= 0, got {text}")
    return v


def positive_int(text: str) -> int:
    v = _parse(text, int, "an integer")
    if v <= 0:
        raise argparse.ArgumentTypeError(f"must be > 0, got {text}")
    return v


def nonnegative_int(text: str) -> int:
    v = _parse(text, int, "an integer")
    if v < 0:
        raise argparse.ArgumentTypeError(f"must be >= 0, got {text}")
    return v


CAUSE_KERNELS = ("midpoint", "chord")
BATCH_KERNELS = ("windowed", "full_ray")
BATCH_KERNEL_HELP = (
    "how a batch scan computes each beam: windowed (default; likelihoods near the reading, the cells before it "
    "as pass counts) or full_ray (every cell: the reference); they agree to rounding"
)
OGM_MAPS = ("log_odds", "hit_rate", "gmapping")
OGM_MAP_HELP = (
    "RBPF-OGM cells: log_odds (default; a match needs its companion cell seen free), hit_rate (GMapping's "
    "counting cells, occupied above a 0.1 hit rate; a companion passes unless occupied) or gmapping (hit_rate "
    "cells that also keep the mean of their hits, to which matches are measured, as GMapping's)"
)
MOTION_DRAWS = ("per_update", "per_scan")
MOTION_DRAWS_HELP = (
    "when RBPF-OGM draws its odometry noise: per processed scan (per_update, default) or at every scan of the log "
    "on its own increment, as GMapping does (per_scan)"
)
WEIGHT_SMOOTHING_HELP = (
    "RBPF-OGM weight smoothing, GMapping's ogain: log-weights are divided by ogain x particles before N_eff, "
    "resampling and the weighted mean (default: 3, GMapping's; 0 = plain weights)"
)
CAUSE_KERNEL_HELP = "RBPF-CLAM: a cause at its chord midpoint (spec default) or spread along the chord"
PROPOSALS = ("odometry", "likelihood_mode", "scan_match")
PROPOSAL_HELP = "RBPF-CLAM: odometry (paper) or the CRM improved proposal (default: odometry)"
PROPOSAL_POSE_HELP = (
    "improved proposals (RBPF-CLAM likelihood_mode, RBPF-OGM): draw the pose from the Gaussian fitted around the "
    "match (sample, default) or keep the match, as GMapping's code does (match)"
)
MATCH_STRIDE_HELP = (
    "RBPF-CLAM likelihood_mode: climb to the mode on every n-th beam (default: 3); the lattice and the weights use every beam"
)
LATTICE_STEP_HELP = (
    "RBPF-CLAM likelihood_mode: spacing (m, rad) of the 3x3x3 lattice around the mode that the Gaussian is fitted "
    "to and the weight sums (default: 0.05 0.025; GMapping samples at 0.01 0.005)"
)
SIGMA_RANGE_HELP = "RBPF-CLAM range noise sigma_r in m; its hit sigma is sqrt(sigma_r^2 + cell^2/12) (default: 0.01, the spec's)"


def add_likelihood_mode_options(parser: argparse.ArgumentParser) -> None:
    """``--lattice-step DXY DTHETA`` and ``--motion-outlier EPS`` of the likelihood-mode proposal, shared by
    ``slam`` and the experiments."""
    parser.add_argument(
        "--lattice-step", type=positive_float, nargs=2, default=[0.05, 0.025], metavar=("DXY", "DTHETA"), help=LATTICE_STEP_HELP
    )
    parser.add_argument(
        "--motion-outlier",
        type=nonnegative_float,
        default=0.0,
        metavar="EPS",
        help="RBPF-CLAM likelihood_mode: probability that an odometry increment is an outlier; the climb's motion "
        "density gets a floor of log EPS, so a large likelihood gain (a loop closure) can move the pose however "
        "tight the motion model (default: 0, off)",
    )


def add_estimate_options(parser: argparse.ArgumentParser) -> None:
    """``--mode-bandwidth DXY DTHETA`` and ``--smoothing-lag L``: the estimates recorded next to the weighted mean."""
    parser.add_argument(
        "--mode-bandwidth",
        type=positive_float,
        nargs=2,
        default=[0.05, 0.025],
        metavar=("DXY", "DTHETA"),
        help="kernel bandwidths (m, rad) of the mode-seeking estimate written to trajectory_mode.tum (the weighted mean of "
        "the densest group of particles; it does not change the filter; default: 0.05 0.025)",
    )
    parser.add_argument(
        "--smoothing-lag",
        type=nonnegative_int,
        default=None,
        metavar="L",
        help="lineage smoother written to trajectory_smoothed.tum: weigh each processed scan's particle ancestors with "
        "the weights L processed scans later (default: the final weights, full smoothing)",
    )


def add_map_options(p: argparse.ArgumentParser) -> None:
    g = p.add_argument_group("map settings")
    g.add_argument("--resolution", type=positive_float, default=0.2, help="cell size in metres (default: 0.2)")
    g.add_argument(
        "--max-range", type=positive_float, default=8.0, help="z_max in metres; longer readings are no-returns (default: 8)"
    )
    g.add_argument(
        "--model",
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
    g.add_argument("--beam-stride", type=positive_int, default=1, help="use every n-th beam (default: 1)")
