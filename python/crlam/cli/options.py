"""Argument types, help texts and option groups shared by the ``crlam`` subcommands."""

from __future__ import annotations

import argparse
import math
from collections.abc import Callable, Sequence
from typing import Any, TypeVar

__all__ = [
    "BATCH_KERNELS",
    "BATCH_KERNEL_HELP",
    "CAUSE_KERNELS",
    "CAUSE_KERNEL_HELP",
    "LATTICE_STEP_HELP",
    "MATCH_RANGE_HELP",
    "MATCH_STRIDE_HELP",
    "MOTION_DRAWS",
    "MOTION_DRAWS_HELP",
    "OGM_MAPS",
    "OGM_MAP_HELP",
    "PROPOSALS",
    "TEMPERING_BEAMS_HELP",
    "SCAN_MATCH_WEIGHT_HELP",
    "MOTION_NOISE_HELP",
    "PROPOSAL_HELP",
    "PROPOSAL_POSE_HELP",
    "SIGMA_RANGE_HELP",
    "WEIGHT_SMOOTHING_HELP",
    "add_bag_options",
    "add_odometry_options",
    "add_preset_option",
    "FROM_PRESET",
    "add_slam_flags",
    "bag_options",
    "slam_overrides",
    "stored_input_options",
    "staged_output",
    "finite_float",
    "match_range",
    "time_offset",
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


def finite_float(text: str) -> float:
    v = _parse(text, float, "a number")
    if not math.isfinite(v):
        raise argparse.ArgumentTypeError(f"must be a finite number, got {text}")
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


def time_offset(text: str) -> str | float:
    """``--time-offset``: ``auto``, ``off`` or seconds (:func:`crlam.slam.time_offset.parse_time_offset`)."""
    from crlam.slam.time_offset import parse_time_offset

    return parse_time_offset(text)


def match_range(text: str) -> str | float:
    """``--match-range``: ``z_max``, ``full`` or a range in metres."""
    if text in ("z_max", "full"):
        return text
    try:
        v = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"not z_max, full or a range in metres: {text!r}") from None
    if not (v > 0 and math.isfinite(v)):
        raise argparse.ArgumentTypeError(f"a range must be a finite number > 0, got {text}")
    return v


CAUSE_KERNELS = ("midpoint", "chord")
BATCH_KERNELS = ("windowed", "full_ray")
BATCH_KERNEL_HELP = (
    "how a batch scan computes each beam: windowed (default; likelihoods near the reading, the cells before it "
    "as pass counts) or full_ray (every cell: the reference); they agree to rounding"
)
OGM_MAPS = ("log_odds", "hit_rate", "gmapping")
OGM_MAP_HELP = (
    "RBPF-OGM cells: log_odds (paper preset; a match needs its companion cell seen free), hit_rate (GMapping's "
    "counting cells, occupied above a 0.1 hit rate; a companion passes unless occupied) or gmapping (hit_rate "
    "cells that also keep the mean of their hits, to which matches are measured, as GMapping's) (default: the preset's)"
)
MOTION_DRAWS = ("per_update", "per_scan")
MOTION_DRAWS_HELP = (
    "when RBPF-OGM draws its odometry noise: per processed scan (per_update, paper preset) or at every scan of the log "
    "on its own increment, as GMapping does (per_scan) (default: the preset's)"
)
WEIGHT_SMOOTHING_HELP = (
    "RBPF-OGM weight smoothing, GMapping's ogain: log-weights are divided by ogain x particles before N_eff, "
    "resampling and the weighted mean (0 = plain weights; paper: 3, GMapping's; default: the preset's)"
)
CAUSE_KERNEL_HELP = "RBPF-CLAM: a cause at its chord midpoint (spec, paper) or spread along the chord (default: the preset's)"
MOTION_NOISE_HELP = (
    "the odometry model's parameters as given (model) or GMapping's fitted to the log's own odometry and scans before "
    "the run (estimate; needs --motion gmapping; --motion-params overrides it) (default: the preset's)"
)
SCAN_MATCH_WEIGHT_HELP = (
    "RBPF-CLAM scan_match: weigh by the CRM predictive likelihood (crm, the paper's model) or by GMapping's endpoint "
    "lattice normaliser (endpoint) (default: the preset's)"
)
TEMPERING_BEAMS_HELP = (
    "a scan whose weight uses n beams is tempered by tau * n / B, so a scan weighs the same whatever the laser's "
    "beam count (paper: unset, tau for every scan; default: the preset's)"
)
PROPOSALS = ("odometry", "likelihood_mode", "scan_match")
PROPOSAL_HELP = (
    "RBPF-CLAM: odometry (paper), the CRM improved proposal (likelihood_mode) or GMapping's endpoint scan match on the "
    "CRM weighed by the CRM likelihood (scan_match) (default: the preset's)"
)
PROPOSAL_POSE_HELP = (
    "improved proposals (RBPF-CLAM likelihood_mode, RBPF-OGM): draw the pose from the Gaussian fitted around the "
    "match (sample, paper) or keep the match, as GMapping's code does (match) (default: the preset's)"
)
MATCH_RANGE_HELP = (
    "RBPF-CLAM scan_match: the readings the endpoint matcher uses: below z_max (z_max, paper), every reading that "
    "returned at its measured range (full), or those below a range in metres; the weight scores those beyond z_max "
    "with the endpoint likelihood; the map update and the CRM likelihood use z_max either way; no-returns are never "
    "used (default: the preset's)"
)
MATCH_STRIDE_HELP = (
    "RBPF-CLAM likelihood_mode: climb to the mode on every n-th beam (paper: 3; default: the preset's); the lattice "
    "and the weights use every beam"
)
LATTICE_STEP_HELP = (
    "RBPF-CLAM likelihood_mode: spacing (m, rad) of the 3x3x3 lattice around the mode that the Gaussian is fitted "
    "to and the weight sums (paper: 0.05 0.025; default: the preset's; GMapping samples at 0.01 0.005)"
)
SIGMA_RANGE_HELP = (
    "RBPF-CLAM range noise sigma_r in m; its hit sigma is sqrt(sigma_r^2 + cell^2/12) (paper: 0.01, the spec's; "
    "default: the preset's)"
)

#: How every SLAM flag's help ends: the flag overrides the preset, whose value is the default.
FROM_PRESET = "default: the preset's"

#: The SLAM flags of ``crlam slam`` and the experiments: flag -> (help group, add_argument keywords).
#: Every one defaults to None (not given: the preset's value stays); :func:`slam_overrides` reads them.
SLAM_FLAGS: dict[str, tuple[str, dict[str, Any]]] = {
    "--method": ("filter", dict(choices=("clam", "ogm"), help=f"filter (paper: clam; {FROM_PRESET})")),
    "--particles": ("filter", dict(type=positive_int, help=f"number of particles (paper: 100; {FROM_PRESET})")),
    "--seed": ("filter", dict(type=nonnegative_int, help=f"random seed ({FROM_PRESET}; 0 unless it sets one)")),
    "--proposal": ("filter", dict(choices=PROPOSALS, help=PROPOSAL_HELP)),
    "--proposal-pose": ("filter", dict(choices=("sample", "match"), help=PROPOSAL_POSE_HELP)),
    "--match-stride": ("filter", dict(type=positive_int, help=MATCH_STRIDE_HELP)),
    "--lattice-step": ("filter", dict(type=positive_float, nargs=2, metavar=("DXY", "DTHETA"), help=LATTICE_STEP_HELP)),
    "--motion-outlier": (
        "filter",
        dict(
            type=nonnegative_float,
            metavar="EPS",
            help="RBPF-CLAM likelihood_mode: probability that an odometry increment is an outlier; the climb's motion "
            "density gets a floor of log EPS, so a large likelihood gain (a loop closure) can move the pose however "
            "tight the motion model (paper: 0, off; default: the preset's)",
        ),
    ),
    "--weight-stride": ("filter", dict(type=positive_int, help=f"every n-th beam for the weights (paper: 1; {FROM_PRESET})")),
    "--tempering": ("filter", dict(type=positive_float, help=f"weight tempering tau (paper: 1; {FROM_PRESET})")),
    "--tempering-beams": ("filter", dict(type=positive_float, metavar="B", help=TEMPERING_BEAMS_HELP)),
    "--scan-match-weight": ("filter", dict(choices=("crm", "endpoint"), help=SCAN_MATCH_WEIGHT_HELP)),
    "--match-range": ("filter", dict(type=match_range, metavar="z_max|full|M", help=MATCH_RANGE_HELP)),
    "--hit-means": (
        "filter",
        dict(
            action=argparse.BooleanOptionalAction,
            help="RBPF-CLAM scan_match: keep the mean of the hits of each cell and match to it instead of the cell's "
            f"centre, as GMapping does (paper: off; {FROM_PRESET})",
        ),
    ),
    "--match-climb": (
        "filter",
        dict(
            choices=("score", "posterior"),  # crlam.slam.MATCH_CLIMBS
            help="RBPF-CLAM scan_match: the hill climb before the lattice maximises GMapping's endpoint score (score) "
            "or the endpoint log-likelihood plus the log motion density, the lattice's own function (posterior), so "
            f"that directions the scan leaves free (along a corridor) stay where the odometry puts them ({FROM_PRESET})",
        ),
    ),
    "--degeneracy": (
        "filter",
        dict(
            choices=("off", "remap"),  # crlam.slam.DEGENERACIES
            help="RBPF-CLAM scan_match: along a direction the scan leaves free (a featureless corridor's axis), "
            "keep the odometry's prediction in the match and read the CRM weight there (remap: solution remapping) "
            f"or not (off: the paper's) ({FROM_PRESET})",
        ),
    ),
    "--match-min-score": (
        "filter",
        dict(
            type=nonnegative_float,
            metavar="S",
            help="RBPF-CLAM scan_match: a scan match counts only when its endpoint score (about one per well-matched "
            f"beam) exceeds S, else the particle follows the odometry (GMapping's minimumScore; paper: 0; {FROM_PRESET})",
        ),
    ),
    "--front-end": (
        "filter",
        dict(
            choices=("none", "correlative"),  # crlam.slam.FRONT_ENDS
            help="RBPF-CLAM scan_match: correlative searches a wide window around the odometry's guess on the best "
            "particle's map (branch and bound) and a confident match corrects the increment every particle starts "
            f"from; none uses the odometry as given (paper: none; {FROM_PRESET})",
        ),
    ),
    "--front-end-window": (
        "filter",
        dict(
            type=positive_float,
            nargs=2,
            metavar=("M", "RAD"),
            help=f"half-widths of the correlative front end's search, translation and heading ({FROM_PRESET})",
        ),
    ),
    "--linear-update": (
        "filter",
        dict(
            type=nonnegative_float,
            help=f"process a scan after this travel in m (paper: 0, every scan; GMapping's default is 1; {FROM_PRESET})",
        ),
    ),
    "--angular-update": (
        "filter",
        dict(
            type=nonnegative_float,
            help=f"... or this rotation in rad (paper: 0, every scan; GMapping's default is 0.5; {FROM_PRESET})",
        ),
    ),
    "--ogm-map": ("filter", dict(choices=OGM_MAPS, help=OGM_MAP_HELP)),
    "--ogm-motion-draws": ("filter", dict(choices=MOTION_DRAWS, help=MOTION_DRAWS_HELP)),
    "--ogm-weight-smoothing": ("filter", dict(type=nonnegative_float, help=WEIGHT_SMOOTHING_HELP)),
    "--resolution": (
        "map and sensor",
        dict(type=positive_float, help=f"cell size in metres (paper: 0.2; {FROM_PRESET})"),
    ),
    "--max-range": (
        "map and sensor",
        dict(type=positive_float, help=f"z_max in metres; with --map-range readings the least z_max (paper: 8; {FROM_PRESET})"),
    ),
    "--map-range": (
        "map and sensor",
        dict(
            choices=("fixed", "readings"),  # crlam.preflight.map_range.MAP_RANGES
            help="z_max: fixed (--max-range) or readings: the range within which 90 %% of the log's returns lie, "
            f"rounded up to a metre, between --max-range and 20 m; metrics.json records the choice ({FROM_PRESET})",
        ),
    ),
    "--grid-alignment": (
        "map and sensor",
        dict(
            choices=("none", "walls"),  # crlam.slam.grid_alignment.GRID_ALIGNMENTS
            help="the map's frame: the first odometry pose's (none, paper) or that frame turned about the first pose "
            "so that the grid runs along the walls of the first scan (walls); estimates are written in the map's "
            f"frame, metrics.json records the turn ({FROM_PRESET})",
        ),
    ),
    "--sub-cell": (
        "map and sensor",
        dict(
            choices=("off", "on", "unaligned"),  # crlam.slam.grid_alignment.SUB_CELL_CHOICES
            help="RBPF-CLAM's sub-cell geometry (--cause-kernel chord --hit-means, about twice the filter's time): "
            "off (paper, robust), on, or unaligned: only when the grid does not run along the first scan's walls "
            f"(--grid-alignment none, a continued run, or a first scan with no rectilinear walls) ({FROM_PRESET})",
        ),
    ),
    "--map-stride": (
        "map and sensor",
        dict(type=positive_int, help=f"every n-th beam for the map update (paper: 1; {FROM_PRESET})"),
    ),
    "--sigma-range": ("map and sensor", dict(type=nonnegative_float, help=SIGMA_RANGE_HELP)),
    "--cause-kernel": ("map and sensor", dict(choices=CAUSE_KERNELS, help=CAUSE_KERNEL_HELP)),
    "--batch-kernel": ("map and sensor", dict(choices=BATCH_KERNELS, help=f"{BATCH_KERNEL_HELP} ({FROM_PRESET})")),
    "--hits-first": (
        "map and sensor",
        dict(
            action=argparse.BooleanOptionalAction,
            help="RBPF-CLAM batch map updates: a cell that a beam of the scan makes more occupied ignores the scan's "
            f"beams that pass through it to readings far beyond (paper: off; {FROM_PRESET})",
        ),
    ),
    "--no-return": (
        "map and sensor",
        dict(
            choices=("drop", "z_max"),
            help="what a no-return (inf, NaN, 0, below range_min, at or above range_max) does: left out, it never "
            f"clears a cell (drop), or the z_max atom that clears its beam to z_max (z_max: paper; {FROM_PRESET})",
        ),
    ),
    "--body-mask": (
        "map and sensor",
        dict(
            choices=("auto", "off"),
            help="leave out the beams that read the robot's own body, found in the first scans (auto) or use every "
            f"beam (off: paper; {FROM_PRESET})",
        ),
    ),
    "--motion": (
        "motion model",
        dict(
            choices=("gaussian", "thrun", "gmapping"),
            help=f"odometry noise model (paper: gaussian; {FROM_PRESET}); gmapping is GMapping's own model",
        ),
    ),
    "--motion-params": (
        "motion model",
        dict(
            type=float,
            nargs="+",
            metavar="P",
            help="3 sigmas (gaussian), 4 alphas (thrun; RBPF-OGM's thrun default is 0.04 0.01 0.01 0.04) or srr srt "
            f"str stt (gmapping; default 0.1 0.2 0.1 0.2) ({FROM_PRESET}; unset there: the model's own)",
        ),
    ),
    "--motion-noise": ("motion model", dict(choices=("model", "estimate"), help=MOTION_NOISE_HELP)),
    "--mode-bandwidth": (
        "estimates",
        dict(
            type=positive_float,
            nargs=2,
            metavar=("DXY", "DTHETA"),
            help="kernel bandwidths (m, rad) of the mode-seeking estimate written to estimates/mode.tum (the weighted "
            "mean of the densest group of particles; it does not change the filter; paper: 0.05 0.025; default: the "
            "preset's)",
        ),
    ),
    "--smoothing-lag": (
        "estimates",
        dict(
            type=nonnegative_int,
            metavar="L",
            help="lineage smoother written to estimates/smoothed.tum: weigh each processed scan's particle ancestors "
            "with the weights L processed scans later (default: the preset's; unset there: the final weights, full "
            "smoothing)",
        ),
    ),
    "--time-offset": (
        "motion input",
        dict(
            type=time_offset,
            metavar="auto|off|S",
            help="offset in seconds of the odometry's stamps against the laser's (positive: the odometry is stamped "
            "later): auto estimates it from the scans' turns against the odometry's and re-attaches each scan's "
            "odometry at its corrected stamp when the estimate is clearly identified (else the odometry stays as "
            "logged, and the run says why); off leaves the odometry as logged; a number applies it; metrics.json "
            f"records the estimate ({FROM_PRESET}; robust: auto, paper: off)",
        ),
    ),
    "--loop-closing": (
        "loop closing",
        dict(
            choices=("off", "graph"),
            help="graph: a pose graph over the processed scans, closed by wide-window matches against scans mapped "
            "long ago; a correction beyond 0.4 m or 2 deg re-anchors the particles on the map rebuilt at the corrected "
            "poses, and the trajectory is then the graph's (RBPF-CLAM only); off: the particles alone close loops "
            f"(robust: graph, paper: off; {FROM_PRESET})",
        ),
    ),
    "--fill": (
        "estimates",
        dict(
            choices=("interpolate", "odometry"),
            help="pose of a scan the update triggers skip: the last processed estimate plus the raw odometry since "
            "then (odometry, as it stands online) or also the share of the next processed scan's correction reached "
            "so far (interpolate); it does not change the filter (default: the preset's)",
        ),
    ),
}


def add_slam_flags(parser: argparse.ArgumentParser, names: Sequence[str], **changes: dict[str, Any]) -> None:
    """Adds the SLAM flags ``names`` (keys of :data:`SLAM_FLAGS`, in that order) to their help
    groups; ``changes`` maps a flag's argparse name (``motion_params``) to keywords that replace
    the shared ones for this command."""
    from crlam.cli.conventions import group

    for name in names:
        title, spec = SLAM_FLAGS[name]
        spec = {**spec, "default": None, **changes.get(name[2:].replace("-", "_"), {})}
        group(parser, title).add_argument(name, **spec)


def add_preset_option(parser: argparse._ActionsContainer, default: str) -> None:
    """``--preset NAME``: the named settings (:mod:`crlam.slam.presets`) that the SLAM flags override."""
    from crlam.slam.presets import list_presets, preset_description

    names = list_presets()
    parser.add_argument(
        "--preset",
        choices=names,
        default=None,
        metavar="NAME",
        help=f"named SLAM settings ({'; '.join(f'{n}: {preset_description(n)}' for n in names)}); every SLAM flag "
        f"given overrides the preset's value, every one not given keeps it (default: {default}; the values are in "
        "the package's crlam/slam/presets/NAME.toml)",
    )


def slam_overrides(args: argparse.Namespace) -> dict[str, Any]:
    """The SLAM settings given on the command line: every :class:`crlam.slam.SlamConfig` field whose
    flag was typed (flags not typed are None and keep the preset's value); lists become tuples."""
    from dataclasses import fields

    from crlam.slam import SlamConfig

    out: dict[str, Any] = {}
    for f in fields(SlamConfig):
        value = getattr(args, f.name, None)
        if f.name != "preset" and value is not None:
            out[f.name] = tuple(value) if isinstance(value, list) else value
    return out


def add_bag_options(p: argparse.ArgumentParser) -> None:
    """The ROS bag options of the commands that read a log (``crlam map``, ``crlam slam``)."""
    g = p.add_argument_group(
        "ROS bag input",
        "used when LOG is a ROS bag (a folder with metadata.yaml, a .bag or a .mcap file); by default the "
        "topics and the laser mount are detected (the single LaserScan topic, the Odometry topic or /tf, "
        "the base -> laser transform of /tf_static)",
    )
    g.add_argument("--scan-topic", default=None, help="LaserScan (or MultiEchoLaserScan) topic (default: the only one)")
    g.add_argument(
        "--odom-topic",
        default=None,
        help="nav_msgs/Odometry topic, or /tf for the odom -> base transforms (default: the only Odometry topic, "
        "/odom among several, else /tf)",
    )
    g.add_argument(
        "--base-frame",
        default=None,
        help="the robot's base frame, whose pose the odometry gives: with odometry from /tf, the child of odom to "
        "follow (default: the odometry's child frame)",
    )
    g.add_argument(
        "--laser-mount",
        nargs="+",
        default=None,
        metavar="X Y YAW | auto | data",
        help="laser pose in the base frame (m, m, rad), replacing the one of /tf_static; or 'auto' (crlam slam's "
        "default: the data's mount checked against the odometry, and replaced by the one the scans show when they "
        "disagree: yaw, upside down, offset) or 'data' (the data's mount, unchecked)",
    )
    g.add_argument("--upside-down", action="store_true", help="the laser is mounted upside down: mirror its bearings")
    g.add_argument("--odom-frame", default=None, help="the odometry frame, parent of the base frame in /tf (default: odom)")
    g.add_argument(
        "--echo",
        choices=("first", "last", "strongest"),
        default=None,
        help="which return of a MultiEchoLaserScan beam is its range (default: first)",
    )


#: The bag options of :func:`add_bag_options` and :func:`add_odometry_options` (argparse names).
_BAG_OPTION_NAMES = ("scan_topic", "odom_topic", "base_frame", "odom_frame", "laser_mount", "echo", "imu_topic")


def add_odometry_options(p: argparse.ArgumentParser) -> None:
    """``--odometry`` and ``--imu-topic`` of ``crlam slam``: the motion input."""
    from crlam.cli.conventions import group

    g = group(p, "motion input")
    g.add_argument(
        "--odometry",
        choices=("auto", "wheel", "scan_match"),
        default=None,
        help="the motion input: the log's odometry (wheel), scan-matching odometry from the scans themselves, with "
        "a bag's IMU yaw rate where it has one (scan_match; the log's odometry is not read), or scan_match when the "
        "input has no odometry, else wheel (auto, the default); config.toml records which was used",
    )
    g.add_argument("--imu-topic", default=None, help="sensor_msgs/Imu topic for scan-matching odometry (default: the only one)")


def bag_options(args: argparse.Namespace) -> dict[str, Any]:
    """The bag options given on the command line (only those given, so a CARMEN log takes none)."""
    out: dict[str, Any] = {}
    for name in _BAG_OPTION_NAMES:
        value = getattr(args, name, None)
        if name == "laser_mount" and value is not None:
            value = _mount_values(value)
        if value is not None:
            out[name] = value
    if getattr(args, "upside_down", False):
        out["upside_down"] = True
    return out


def laser_mount_mode(args: argparse.Namespace) -> str:
    """``crlam slam``'s mount mode: ``given`` (``--laser-mount X Y YAW`` or ``--upside-down``),
    else ``auto`` (the default) or ``data`` as ``--laser-mount`` says."""
    value = getattr(args, "laser_mount", None)
    if getattr(args, "upside_down", False) or (value is not None and _mount_values(value) is not None):
        return "given"
    return "auto" if value is None else str(value[0]).lower()


def _mount_values(value: Any) -> list[float] | None:
    """``--laser-mount``'s three numbers, or None for ``auto`` / ``data``."""
    from crlam.errors import ConfigError

    items = [str(v) for v in value]
    if len(items) == 1 and items[0].lower() in ("auto", "data"):
        return None
    try:
        numbers = [float(v) for v in items]
    except ValueError:
        numbers = []
    if len(numbers) != 3:
        raise ConfigError(f"--laser-mount takes X Y YAW (m, m, rad), 'auto' or 'data' (got {' '.join(items)})")
    return numbers


def stored_input_options(table: dict[str, Any]) -> tuple[dict[str, Any], str | None]:
    """The bag options and the odometry choice that a run folder's ``config.toml`` ``[input]``
    table records, for ``crlam slam --config``: the topics, frames and echo that were used, the
    IMU topic, and the laser mount when it was given (a mount found in the bag is found again);
    the odometry as given, or ``auto`` again when it was chosen from the input.
    An empty value (no odometry topic with scan-matching odometry) is left out."""
    out: dict[str, Any] = {}
    if table.get("format") == "rosbag":
        for name in ("scan_topic", "odom_topic", "base_frame", "odom_frame", "echo", "imu_topic"):
            value = table.get(name)
            if isinstance(value, str) and value:
                out[name] = value
        if table.get("mount_source") == "user":
            out["laser_mount"] = [float(v) for v in table.get("laser_mount", [])]
            if table.get("upside_down"):
                out["upside_down"] = True
        if table.get("odometry") == "scan_match":
            out.pop("odom_topic", None)
    odometry = table.get("odometry")
    if str(table.get("odometry_choice", "")).startswith("auto"):
        odometry = "auto"  # chosen from the input: chosen again the same way
    return out, odometry if isinstance(odometry, str) else None


def _limit_value(text: str) -> int:
    from crlam.errors import ConfigError
    from crlam.limits import parse_limit

    try:
        return parse_limit(text)
    except ConfigError as e:
        raise argparse.ArgumentTypeError(str(e)) from None


def add_limit_options(parser: argparse.ArgumentParser) -> None:
    """The resource-limit flags (:mod:`crlam.limits`), given to every subcommand that does work."""
    from crlam.limits import DEFAULTS, env_name

    g = parser.add_argument_group(
        "resource limits",
        "inputs that would need more than these are refused with an error before the memory is taken; "
        "the environment variables CRLAM_MAX_* set them too (values like 1e8 are accepted)",
    )
    helps = {
        "map_cells": "cells of a map or of a dense copy of it",
        "particles": "particles of a filter or pose belief",
        "image_pixels": "pixels of a map image, checked before decoding",
        "archive_bytes": "uncompressed bytes of a .npz archive (belief.npz, tree.npz), checked before decompressing",
        "download_bytes": "bytes of a download whose size is not known in advance",
        "readings": "range readings (scans x beams) a simulated log holds in memory",
    }
    for name, text in helps.items():
        g.add_argument(
            "--max-" + name.replace("_", "-"),
            dest="limit_" + name,
            type=_limit_value,
            default=None,
            metavar="N",
            help=f"{text} (default: {getattr(DEFAULTS, name):,}; {env_name(name)})",
        )


def add_limit_options_everywhere(parser: argparse.ArgumentParser) -> None:
    """:func:`add_limit_options` on every leaf subcommand of ``parser``."""
    subs = [a for a in parser._actions if isinstance(a, argparse._SubParsersAction)]
    if not subs:
        add_limit_options(parser)
        return
    for action in subs:
        for child in dict.fromkeys(action.choices.values()):
            add_limit_options_everywhere(child)


def apply_limit_options(args: argparse.Namespace) -> None:
    """Puts the limits given on the command line in force (for this process and its workers)."""
    from crlam.limits import set_limits

    given = {k[len("limit_") :]: v for k, v in vars(args).items() if k.startswith("limit_") and v is not None}
    if given:
        set_limits(**given)


def staged_output(args: argparse.Namespace, out: str | None = None):  # type: ignore[no-untyped-def]
    """The staging folder of the command's ``--out`` (see :mod:`crlam.io.run_folder`), after the
    up-front check: a context manager yielding the folder to write into."""
    from crlam.io.run_folder import check_output, staged_folder

    path = check_output(out if out is not None else args.out, force=getattr(args, "force", False))
    return staged_folder(path, command=f"crlam {args.command}")
