"""``crlam eval``: trajectory accuracy by the relations metric or against a reference.

Errors are raised as :class:`~crlam.errors.CrlamError` (or ``FileNotFoundError``) for the main
entry point to print.
"""

from __future__ import annotations

import argparse
import json
import math
import os
import sys
import textwrap
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any, Literal

import numpy as np
from numpy.typing import NDArray

from crlam.cli.conventions import add_output_options, check_file_output, deprecated_alias, group, input_file, print_settings, say
from crlam.cli.options import positive_float
from crlam.errors import ConfigError, DataFormatError

if TYPE_CHECKING:
    from crlam.eval.trajectory import ScanIndex

__all__ = ["add_parser", "cmd_eval", "load_trajectory"]

_WIDTH = 100


@dataclass(eq=False)
class LoadedTrajectory:
    """A trajectory file read for evaluation.

    Attributes
    ----------
    stamps : ndarray, shape (n,)
        Seconds, file order.
    poses : ndarray, shape (n, 3)
        ``(x, y, theta)`` (m, m, rad); for a CARMEN log, the scans' pose field.
    fmt : str
        ``"tum"`` or ``"carmen"``.
    scans : ScanIndex or None
        The per-scan index of a CARMEN log (needed to align it to a raw log).
    """

    stamps: NDArray[np.float64]
    poses: NDArray[np.float64]
    fmt: str
    scans: ScanIndex | None = None


def _is_carmen(path: str | os.PathLike[str]) -> bool:
    """A CARMEN log starts (after comments) with a message name; a TUM file with a number."""
    from crlam.io.carmen import open_binary

    with open_binary(path) as fh:
        for _, raw in zip(range(1000), fh):
            tokens = raw.split()
            if tokens and not tokens[0].startswith(b"#"):
                return tokens[0][:1].isalpha()
    return False


def load_trajectory(path: str | os.PathLike[str]) -> LoadedTrajectory:
    """Read a TUM file, or a CARMEN log (each laser scan's ipc stamp and pose field)."""
    if _is_carmen(path):
        from crlam.eval.trajectory import index_scans

        scans = index_scans(path)
        return LoadedTrajectory(scans.stamps, scans.poses, "carmen", scans)
    from crlam.io.tum import read_tum

    traj = read_tum(path)
    return LoadedTrajectory(traj.timestamps, traj.poses, "tum")


def _wrap(label: str, text: str) -> str:
    return textwrap.fill(text, width=_WIDTH, initial_indent=f"  {label:<11s} ", subsequent_indent=" " * 14)


def _fmt(v: float) -> str:
    return "nan" if math.isnan(v) else f"{v:.4g}"


def _json_safe(obj: Any) -> Any:
    # NaN (a sample std of one value) is not valid JSON: write null instead.
    if isinstance(obj, float) and not math.isfinite(obj):
        return None
    if isinstance(obj, dict):
        return {k: _json_safe(v) for k, v in obj.items()}
    return obj


def cmd_eval(args: argparse.Namespace) -> int:
    """Evaluate a trajectory with the relations metric or against a reference trajectory."""
    from crlam.eval.trajectory import (
        GMAPPING_UPDATES,
        align_to_raw,
        fill_trajectory,
        index_scans,
        reference_errors,
        relations_error,
    )
    from crlam.io.relations import read_relations
    from crlam.io.run_folder import staged_file

    if args.tolerance < 0 or not math.isfinite(args.tolerance):
        raise ConfigError(f"--tolerance must be a finite number >= 0, got {args.tolerance}")
    if args.relations and args.align != "none":
        raise ConfigError("--align applies to --reference: the relations metric does not change under a rigid motion")
    output = check_file_output(args)
    print_settings(args)
    traj = load_trajectory(args.trajectory)
    report: dict[str, Any] = {"trajectory": str(args.trajectory), "trajectory_format": traj.fmt, "raw_log": args.raw_log}
    lines = [_wrap("trajectory", f"{args.trajectory} ({traj.fmt.upper()}, {traj.stamps.shape[0]} poses)")]
    stamps, poses = traj.stamps, traj.poses
    if args.raw_log:
        raw = index_scans(args.raw_log)
        if traj.scans is not None:
            al = align_to_raw(traj.scans, raw, tolerance=args.tolerance)
            stamps, poses = al.stamps, al.poses
            report["alignment"] = {"rule": al.rule, "n_by_stamp": al.n_by_stamp, "n_by_ranges": al.n_by_ranges}
            lines.append(_wrap("alignment", al.rule))
        filled = fill_trajectory(
            stamps,
            poses,
            raw,
            tolerance=args.tolerance,
            backfill=not args.no_backfill,
            fill=args.fill,
            updates=GMAPPING_UPDATES if args.fill_updates is None else tuple(args.fill_updates),
        )
        stamps, poses = filled.stamps, filled.poses
        report["fill"] = {
            "rule": filled.rule,
            "n_scans": len(filled),
            "n_processed": filled.n_processed,
            "n_filled": int(filled.filled.sum()),
            "n_omitted": filled.n_omitted,
            "n_unmatched_estimates": filled.n_unmatched_estimates,
            "backfill": not args.no_backfill,
            "fill": args.fill,
        }
        lines.append(_wrap("fill rule", filled.rule))
        if filled.n_unmatched_estimates:
            lines.append(_wrap("warning", f"{filled.n_unmatched_estimates} estimated poses match no scan of the raw log"))
    if args.relations:
        rel = read_relations(args.relations)
        # Without backfill the scans before the first processed one have no pose: skip their relations.
        on_missing: Literal["raise", "skip"] = "skip" if (args.skip_missing or args.no_backfill) else "raise"
        try:
            errs = relations_error(stamps, poses, rel, on_missing=on_missing, tolerance=args.tolerance)
        except DataFormatError as exc:
            hint = "" if args.raw_log else " or give --raw-log to fill the scans the trajectory lacks"
            raise DataFormatError(f"{exc}; on the command line: --skip-missing{hint}") from exc
        summary = errs.summary()
        report.update(metric="relations", relations=str(args.relations), summary=summary)
        lines.insert(0, "relations metric (Kuemmerle et al. 2009): E = delta_ref^-1 (+) P(t1)^-1 (+) P(t2)")
        lines.append(
            _wrap("relations", f"{args.relations}: {len(rel)} relations, {errs.n} evaluated, {errs.n_missing} skipped (no pose)")
        )
        lines += ["", f"  {'error':<16s} {'mean':>10s} {'std':>10s}"]
        for key, label in (
            ("trans", "|trans| (m)"),
            ("rot", "|rot| (deg)"),
            ("trans2", "trans^2 (m^2)"),
            ("rot2", "rot^2 (deg^2)"),
        ):
            unit = {"trans": "m", "rot": "deg", "trans2": "m2", "rot2": "deg2"}[key]
            mean, std = summary[f"{key}_mean_{unit}"], summary[f"{key}_std_{unit}"]
            lines.append(f"  {label:<16s} {_fmt(mean):>10s} {_fmt(std):>10s}")
    else:
        ref = load_trajectory(args.reference)
        turn, poses = _odometry_frame(Path(args.trajectory), poses)
        if turn:
            report["map_frame_turn_deg"] = turn
            lines.append(_wrap("map frame", f"turned back by {-turn:.2f} deg into the odometry's frame (the run's metrics.json)"))
        res = reference_errors(stamps, poses, ref.stamps, ref.poses, tolerance=args.tolerance, align=args.align)
        summary = res.summary()
        ape = res.ape()
        report.update(metric="reference", reference=str(args.reference), align=args.align, summary=summary, ape=ape)
        if res.alignment is None:
            lines.insert(0, "errors against a reference trajectory (same frame, matched stamps, no alignment)")
        else:
            report["alignment"] = res.alignment.to_dict()
            a = res.alignment
            lines.insert(0, "errors against a reference trajectory (matched stamps, estimate aligned by SE(2) least squares)")
            lines.append(_wrap("alignment", f"rotation {math.degrees(a.theta):.4f} deg, translation ({a.tx:.4f}, {a.ty:.4f}) m"))
        lines.append(_wrap("reference", f"{args.reference}: {res.n} poses matched, {res.n_unmatched} estimated poses unmatched"))
        lines += [
            "",
            f"  MAE x (m)          {_fmt(summary['mae_x_m'])}",
            f"  MAE y (m)          {_fmt(summary['mae_y_m'])}",
            f"  MAE theta (deg)    {_fmt(summary['mae_theta_deg'])}  ({_fmt(summary['mae_theta_rad'])} rad)",
            f"  RMSE position (m)  {_fmt(summary['rmse_position_m'])}",
            "",
            "  APE, translation part (m; evo's statistics)",
            "  " + "  ".join(f"{k[4:-2]} {_fmt(v)}" for k, v in ape.items()),
        ]
    if args.quiet:
        lines = lines[lines.index("") + 1 :]  # the table only
    print("\n".join(lines))
    text = json.dumps(_json_safe(report), indent=2) + "\n"
    if args.verbose:
        print(f"crlam eval: report\n{text}", end="", file=sys.stderr)
    if output is not None:
        with staged_file(output) as stage:
            stage.write_text(text, encoding="utf-8")
        say(args, f"\nwritten {output}")
    return 0


def add_parser(subparsers: Any) -> argparse.ArgumentParser:
    """Add ``eval`` to ``subparsers`` (the object ``ArgumentParser.add_subparsers`` returns)."""
    p: argparse.ArgumentParser = subparsers.add_parser(
        "eval",
        help="trajectory accuracy: relations metric (Kuemmerle et al. 2009) or errors against a reference",
        description="Evaluate a trajectory (TUM file, or a CARMEN log whose scans' pose field is used) with the relations "
        "metric or against a reference trajectory, print a table and optionally write JSON. With --raw-log every scan "
        "of the raw log gets a pose first: processed scans keep theirs, the others take the last processed pose "
        "(in file order) carried by the raw-odometry increment; a CARMEN trajectory whose stamps are not the raw "
        "ipc stamps (the GMapping-corrected logs) is matched to the raw scans by identical readings. Every file "
        "argument also takes a dataset name (aces-corrected, aces-relations, aces; see crlam data list) and - for "
        "standard input.",
    )
    inp = group(p, "input")
    inp.add_argument(
        "trajectory",
        type=input_file,
        help="TUM file or CARMEN log (e.g. ../shared/data/corrected/aces-corrected.log.gz, or aces-corrected)",
    )
    inp.add_argument(
        "--raw-log", type=input_file, help="raw CARMEN log or ROS bag whose scans' odometry fills the scans the trajectory lacks"
    )
    metric = group(p, "metric", "one of --relations and --reference")
    g = metric.add_mutually_exclusive_group(required=True)
    g.add_argument("--relations", type=input_file, help=".relations file (t1 t2 x y z roll pitch yaw)")
    g.add_argument(
        "--reference", type=input_file, help="reference trajectory (TUM or CARMEN) in the same frame, matched by stamp"
    )
    metric.add_argument(
        "--align",
        choices=("none", "se2"),
        default="none",
        help="with --reference: 'se2' first moves the estimate by the rigid motion that best fits it to the reference "
        "(least squares, evo's --align in the plane); 'none' compares the poses as they are (default)",
    )
    match = group(p, "matching")
    match.add_argument(
        "--no-backfill",
        action="store_true",
        help="leave out the scans before the first processed one instead of filling them backwards; relations on them "
        "are skipped and counted (this is how the README oracles were measured)",
    )
    match.add_argument(
        "--fill",
        choices=("odometry", "interpolate"),
        default="odometry",
        help="with --raw-log: a scan the trajectory lacks gets the last processed pose carried by the raw odometry "
        "(odometry, the default and the data README's rule) or also the share of the next processed pose's correction "
        "to that prediction reached so far (interpolate, crlam slam's default; see docs/method/rbpf-clam.md)",
    )
    match.add_argument(
        "--fill-updates",
        type=positive_float,
        nargs=2,
        default=None,
        metavar=("M", "RAD"),
        help="with --fill interpolate: the update triggers that measure the share, max(travelled / M, turned / RAD) "
        "(default: GMapping's 1 0.5; only the ratio matters)",
    )
    match.add_argument("--skip-missing", action="store_true", help="skip (and count) relations whose stamps have no pose")
    match.add_argument(
        "--tolerance", type=float, default=1e-6, help="stamp matching tolerance after exact lookup, s (default: 1e-6)"
    )
    add_output_options(p, out="write the summary, the rules used and the inputs to this JSON file", required=False)
    deprecated_alias(p, "--json", "--out")
    p.set_defaults(func=cmd_eval)
    return p


def _odometry_frame(trajectory: Path, poses: NDArray[np.float64]) -> tuple[float, NDArray[np.float64]]:
    """A trajectory of a ``crlam slam`` run folder whose map frame is turned (``--grid-alignment
    walls``), turned back into the odometry's frame, where a reference that starts where the
    odometry starts lives: (the turn in deg, the poses). The run's ``metrics.json`` sits beside
    the file or one folder up (``estimates/``); without one, or without a turn, (0, poses)."""
    from crlam.experiments.resume import load_json_dict
    from crlam.slam.grid_alignment import frame_from_record, from_map_frame

    if trajectory.suffix != ".tum" or not trajectory.is_file():
        return 0.0, poses
    for folder in (trajectory.parent, trajectory.parent.parent):
        metrics = load_json_dict(folder / "metrics.json")
        if metrics is not None and isinstance(metrics.get("map_frame"), dict):
            frame = frame_from_record(metrics["map_frame"])
            return math.degrees(float(frame[2])), from_map_frame(frame, poses)
    return 0.0, poses
