"""``crlam diagnose likelihood-bias``: where the scan likelihood peaks around reference poses."""

from __future__ import annotations

import argparse
import math
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from crlam.cli.conventions import add_output_options, deprecated_alias, group, input_file, print_settings
from crlam.cli.options import positive_float, positive_int, staged_output

if TYPE_CHECKING:
    from crlam.experiments.known_poses import KnownPoseScan

__all__ = ["add_parser", "cmd_likelihood_bias", "reference_pose_scans"]


def reference_pose_scans(
    log: str, tum: str, *, tolerance: float, max_scans: int | None = None
) -> tuple[list[KnownPoseScan], int]:
    """The log's scans with the reference trajectory's pose at each scan's stamp (composed with
    the laser offset); scans without a reference pose within ``tolerance`` (s) are left out and
    counted. Returns ``(scans, n_without_reference)``."""
    from crlam.eval.trajectory import _StampIndex
    from crlam.experiments.known_poses import KnownPoseScan, mapping_ranges
    from crlam.io.logs import read_scans_any
    from crlam.io.tum import read_tum
    from crlam.pose import compose

    ref = read_tum(tum)
    index = _StampIndex(ref.timestamps, ref.poses, tolerance)
    scans: list[KnownPoseScan] = []
    missing = 0
    for n, rec in enumerate(read_scans_any(log)):
        if max_scans is not None and n >= max_scans:
            break
        i = index.find(rec.timestamp)
        if i < 0:
            missing += 1
            continue
        pose = np.asarray(compose(ref.poses[i], rec.laser_offset), dtype=np.float64)
        scans.append(KnownPoseScan(pose, rec.angles, mapping_ranges(rec), rec.timestamp))
    return scans, missing


def cmd_likelihood_bias(args: argparse.Namespace) -> int:
    """Build the map online from the reference poses and write the argmax offsets."""
    import itertools

    from crlam.errors import ConfigError
    from crlam.eval.likelihood_bias import LineSearchGrid, likelihood_bias, save_likelihood_bias
    from crlam.experiments.known_poses import known_pose_scans
    from crlam.io.logs import open_log
    from crlam.mapping import MappingConfig

    if (args.reference is None) == (not args.log_poses):
        raise ConfigError("give either --reference TRAJ.tum or --log-poses")
    from crlam.io.run_folder import moved

    output = staged_output(args)  # the output is checked before the run, written after it
    missing = 0
    if args.log_poses:
        scans = list(itertools.islice(known_pose_scans(open_log(args.log), "log"), args.max_scans))
    else:
        scans, missing = reference_pose_scans(args.log, args.reference, tolerance=args.tolerance, max_scans=args.max_scans)
    if len(scans) <= args.warmup:
        print(f"crlam diagnose: {args.log}: {len(scans)} scans with a reference pose, need more than --warmup {args.warmup}")
        return 2
    mapping = MappingConfig(
        resolution=args.resolution,
        max_range=args.max_range,
        cause_kernel=args.cause_kernel,
        sigma_range=args.sigma_range,
        origin=tuple(args.origin),
    )
    grid = LineSearchGrid(
        xy_half=args.xy_half,
        xy_step=args.xy_step,
        heading_half=math.radians(args.heading_half),
        heading_step=math.radians(args.heading_step),
    )
    print_settings(args, mapping_settings=mapping, search_grid=grid)
    result = likelihood_bias(
        scans, mapping, every=args.every, warmup=args.warmup, grid=grid, model=args.crm_model, progress=not args.quiet
    )
    result.settings.update(
        {"log": str(args.log), "reference": args.reference or "the log's pose fields", "scans_without_reference": missing}
    )
    with output as stage:
        paths = save_likelihood_bias(result, stage, title=f"{Path(args.log).name}: scan likelihood argmax ({len(result)} scans)")
    s = result.summary()
    if missing:
        print(f"{missing} scans had no reference pose within {args.tolerance} s: left out of the map and the evaluation")
    print(f"{len(result)} scans evaluated of {len(scans)} mapped ({s['n_moving']} moving)")
    for axis, key, unit in (("along", "all", "m"), ("lateral", "all", "m"), ("heading", "all_deg", "deg")):
        st = s[axis][key]
        print(f"{axis:<8s}mean {st['mean']:+.4f} {unit}  median {st['median']:+.4f} {unit}  std {st['std']:.4f} {unit}")
    edges = {a: s[a]["n_at_edge"] for a in ("along", "lateral", "heading") if s[a]["n_at_edge"]}
    if edges:
        print(f"argmax on the end of the search grid (widen it): {edges}")
    for key, p in paths.items():
        print(f"  {key:<8s} {moved(p, stage, Path(args.out))}")
    return 0


def add_parser(sub: argparse._SubParsersAction) -> argparse.ArgumentParser:  # type: ignore[type-arg]
    """Add ``diagnose`` (``likelihood-bias``) to ``sub``."""
    p = sub.add_parser(
        "diagnose",
        help="diagnostics of the models (where the scan likelihood peaks)",
        description="Diagnostics of the models against reference poses.",
    )
    d = p.add_subparsers(dest="diagnostic", metavar="DIAGNOSTIC")
    d.required = True
    lb = d.add_parser(
        "likelihood-bias",
        help="where the CRM scan likelihood peaks around reference poses",
        description="Builds the CRM online from reference poses and, at every n-th scan, searches along the "
        "heading, sideways and in heading for the maximum of the scan's likelihood under the map of the scans "
        "before it. A consistent offset is a drift every filter weighting by this likelihood inherits. Writes "
        "summary.json, samples.csv and histograms.png.",
    )
    inp = group(lb, "input")
    inp.add_argument(
        "log",
        type=input_file,
        help="CARMEN log (plain, .gz or .bz2; - reads standard input), ROS bag (topics and mount detected) or dataset name",
    )
    inp.add_argument("--max-scans", type=positive_int, default=None, help="only the first N scans")
    ref = group(lb, "reference poses", "one of --reference and --log-poses")
    ref.add_argument(
        "--reference", type=input_file, default=None, help="TUM trajectory of the robot, matched to the scans by stamp"
    )
    ref.add_argument("--log-poses", action="store_true", help="use the log's own pose fields (e.g. a corrected log)")
    ref.add_argument("--tolerance", type=float, default=1e-6, help="stamp matching tolerance in s (default: 1e-6)")
    m = group(lb, "map and sensor")
    m.add_argument("--resolution", type=positive_float, default=0.2, help="cell size in m (default: 0.2)")
    m.add_argument("--max-range", type=positive_float, default=8.0, help="z_max in m (default: 8)")
    m.add_argument("--cause-kernel", choices=("midpoint", "chord"), default="midpoint", help="cause kernel (default: midpoint)")
    m.add_argument("--sigma-range", type=float, default=0.01, help="range noise sigma_r in m (default: 0.01)")
    m.add_argument(
        "--origin", type=float, nargs=2, default=(0.0, 0.0), metavar=("X", "Y"), help="grid origin in m (default: 0 0)"
    )
    m.add_argument("--crm-model", choices=("mixture", "ijrr"), default="mixture", help="likelihood model (default: mixture)")
    search = group(lb, "search")
    search.add_argument("--every", type=positive_int, default=5, help="evaluate every n-th scan (default: 5)")
    search.add_argument("--warmup", type=positive_int, default=20, help="first scan evaluated (default: 20)")
    search.add_argument("--xy-half", type=positive_float, default=0.2, help="half-width of the x/y searches in m (default: 0.2)")
    search.add_argument("--xy-step", type=positive_float, default=0.01, help="step of the x/y searches in m (default: 0.01)")
    search.add_argument(
        "--heading-half", type=positive_float, default=1.5, help="half-width of the heading search in deg (default: 1.5)"
    )
    search.add_argument(
        "--heading-step", type=positive_float, default=0.05, help="step of the heading search in deg (default: 0.05)"
    )
    add_output_options(lb)
    deprecated_alias(lb, "--model", "--crm-model")
    lb.set_defaults(func=cmd_likelihood_bias)
    return p
