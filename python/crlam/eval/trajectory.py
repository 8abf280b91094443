"""Trajectory accuracy: the relations metric of Kuemmerle et al. (2009) and reference metrics.

Stamps are matched **by value** through a dict keyed by the parsed float (with a small tolerance
as a fallback for stamps that went through a lossy print), never by position: CARMEN logs are
not time sorted (Intel has 631 backward steps). On Intel and ACES every relation stamp equals
the ``ipc_timestamp`` of a raw FLASER line exactly (both are printed with 6 decimals), so the
fallback is never used there. :func:`fill_trajectory` gives every raw scan a pose for runs that
processed only some scans (the rule is stated in its docstring and in ``FilledTrajectory.rule``).
"""

from __future__ import annotations

import hashlib
import math
import os
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from typing import Literal

import numpy as np
from numpy.typing import ArrayLike, NDArray

from crlam.errors import DataFormatError
from crlam.eval.align import Se2Alignment, align_se2, ape_statistics
from crlam.io.logs import read_scans_any
from crlam.io.relations import Relations
from crlam.pose import between, compose, wrap_angle
from crlam.slam.fill import fill_skipped

__all__ = [
    "DEFAULT_TOLERANCE",
    "FilledTrajectory",
    "LogAlignment",
    "ReferenceErrors",
    "RelationsErrors",
    "ScanIndex",
    "aggregate_runs",
    "align_to_raw",
    "fill_trajectory",
    "index_scans",
    "reference_errors",
    "relations_error",
]

FloatArray = NDArray[np.float64]
IntArray = NDArray[np.int64]
BoolArray = NDArray[np.bool_]

DEFAULT_TOLERANCE = 1e-6
"""Stamp matching tolerance (s) used after an exact lookup fails: far below the 10 ms or more
between two scans of a laser log, far above the rounding of a stamp printed with 9 decimals."""
#: GMapping's default update triggers (m, rad): the share measure of ``fill_trajectory(fill="interpolate")``.
GMAPPING_UPDATES = (1.0, 0.5)


def _std(x: FloatArray) -> float:
    # Sample standard deviation (ddof=1), undefined (NaN) for fewer than two values.
    return float(np.std(x, ddof=1)) if x.shape[0] > 1 else math.nan


class _StampIndex:
    """Lookup of a stamp in an unsorted stamp array: exact dict first, then nearest within
    ``tolerance`` through a sorted *copy* (the trajectory itself is never reordered)."""

    def __init__(self, stamps: FloatArray, poses: FloatArray | None, tolerance: float) -> None:
        self.tolerance = float(tolerance)
        self.exact: dict[float, int] = {}
        # Stamps that occur twice with different poses: looking them up is an error.
        self.ambiguous: set[float] = set()
        for i, t in enumerate(stamps.tolist()):
            j = self.exact.setdefault(t, i)
            if j != i and (poses is None or not np.array_equal(poses[i], poses[j])):
                self.ambiguous.add(t)
        self.order = np.argsort(stamps, kind="stable")
        self.sorted = stamps[self.order]

    def find(self, t: float) -> int:
        """Index of stamp ``t``, or -1 when no stamp lies within the tolerance."""
        i = self.exact.get(t)
        if i is None and self.tolerance > 0 and self.sorted.shape[0]:
            k = int(np.searchsorted(self.sorted, t))
            best = min((c for c in (k - 1, k) if 0 <= c < self.sorted.shape[0]), key=lambda c: abs(self.sorted[c] - t))
            if abs(self.sorted[best] - t) <= self.tolerance:
                i = int(self.order[best])
                t = float(self.sorted[best])
        if i is None:
            return -1
        if t in self.ambiguous:
            raise DataFormatError(
                f"stamp {t:.6f} occurs more than once in the trajectory with different poses", field="timestamp"
            )
        return i


@dataclass(eq=False)
class ScanIndex:
    """Per-scan fields of a CARMEN log, in file order (laser scans only, no ODOM lines).

    Attributes
    ----------
    path : str
    stamps : ndarray, shape (n,)
        ``ipc_timestamp`` (s), not sorted.
    poses, odom : ndarray, shape (n, 3)
        The scans' pose and odometry fields (m, m, rad).
    lines : ndarray of int64, shape (n,)
        1-based line numbers.
    digests : list of bytes, length n
        BLAKE2b-128 of the parsed ranges: identical readings give identical digests, whatever
        the stamps (this finds the raw scan a corrected log's scan came from).
    """

    path: str
    stamps: FloatArray
    poses: FloatArray
    odom: FloatArray
    lines: IntArray
    digests: list[bytes] = field(repr=False)

    def __len__(self) -> int:
        return int(self.stamps.shape[0])


def index_scans(path: str | os.PathLike[str], *, on_error: Literal["raise", "skip"] = "raise") -> ScanIndex:
    """Read the per-scan fields of a CARMEN log (FLASER, RLASER, ROBOTLASER1/2) in file order.

    Raises
    ------
    DataFormatError
        On a malformed line (unless ``on_error="skip"``) or when the log holds no laser scan.
    """
    rows = [
        (s.timestamp, s.pose, s.odom, s.line, hashlib.blake2b(s.ranges.tobytes(), digest_size=16).digest())
        for s in read_scans_any(path, on_error=on_error)
    ]
    if not rows:
        raise DataFormatError("no laser scans (FLASER, ROBOTLASER1, ...) in the log", path=str(path))
    stamps, poses, odom, lines, digests = zip(*rows)
    return ScanIndex(
        path=str(path),
        stamps=np.array(stamps, dtype=np.float64),
        poses=np.array(poses, dtype=np.float64).reshape(-1, 3),
        odom=np.array(odom, dtype=np.float64).reshape(-1, 3),
        lines=np.array(lines, dtype=np.int64),
        digests=list(digests),
    )


@dataclass(eq=False)
class FilledTrajectory:
    """A pose for every scan of a raw log, in the log's file order.

    Attributes
    ----------
    stamps, poses : ndarray, shapes (n,) and (n, 3)
        The scans' ``ipc_timestamp`` (s, not sorted) and poses (m, m, rad).
    filled : ndarray of bool, shape (n,)
        True where the pose was carried by raw odometry, False where it is an estimated pose.
    rule : str
        One sentence stating the fill rule and its counts, for reports.
    source, lines : ndarray of int64, shape (n,)
        Index into the estimate of a processed scan's pose (-1 if filled); raw-log line.
    n_unmatched_estimates : int
        Estimated poses whose stamp matches no scan of the raw log (ignored).
    n_omitted : int
        Scans before the first processed one left out because ``backfill=False``.
    """

    stamps: FloatArray
    poses: FloatArray
    filled: BoolArray
    rule: str
    source: IntArray
    lines: IntArray
    n_unmatched_estimates: int = 0
    n_omitted: int = 0

    def __len__(self) -> int:
        return int(self.stamps.shape[0])

    @property
    def n_processed(self) -> int:
        """Scans that kept an estimated pose."""
        return int(np.count_nonzero(~self.filled))


def _as_estimate(stamps: ArrayLike, poses: ArrayLike, what: str) -> tuple[FloatArray, FloatArray]:
    t = np.asarray(stamps, dtype=np.float64).reshape(-1)
    p = np.asarray(poses, dtype=np.float64)
    if p.shape != (t.shape[0], 3):
        raise DataFormatError(f"{what}: poses must have shape ({t.shape[0]}, 3), got {p.shape}", field="poses")
    if not (np.all(np.isfinite(t)) and np.all(np.isfinite(p))):
        raise DataFormatError(f"{what}: non-finite stamps or poses", field="poses")
    return t, p


def fill_trajectory(
    stamps_est: ArrayLike,
    poses_est: ArrayLike,
    raw_log: str | os.PathLike[str] | ScanIndex,
    *,
    tolerance: float = DEFAULT_TOLERANCE,
    backfill: bool = True,
    fill: str = "odometry",
    updates: tuple[float, float] = GMAPPING_UPDATES,
) -> FilledTrajectory:
    """Give every laser scan of a raw log a pose, from an estimate that covers only some scans.

    Parameters
    ----------
    stamps_est : array_like, shape (m,)
        Estimated stamps (s), the raw log's ``ipc_timestamp`` of the processed scans; any order.
    poses_est : array_like, shape (m, 3)
        Estimated poses (m, m, rad).
    raw_log : str, PathLike or ScanIndex
        The raw CARMEN log (its scans' ``odom`` fields are the raw odometry), or its index.
    tolerance : float
        A scan is processed when its stamp equals an estimated stamp exactly or within this (s).
    backfill : bool
        Fill the scans before the first processed one backwards from it (default). With False
        they are left out (``n_omitted``), as in the README oracles.
    fill : {"odometry", "interpolate"}
        The rule for the scans after the first processed one (:mod:`crlam.slam.fill`): the last
        processed pose carried by the raw odometry (default, the data README's rule), or that
        plus the share of the next processed pose's correction to the odometry's prediction,
        the share measured with the update triggers ``updates``.
    updates : tuple of float
        (linear m, angular rad) update triggers that measure the share of ``interpolate``;
        default GMapping's 1 m / 0.5 rad (only their ratio matters).

    Raises
    ------
    DataFormatError
        When no estimated stamp matches a scan stamp (e.g. logger stamps instead of ipc stamps).
    """
    t_est, p_est = _as_estimate(stamps_est, poses_est, "estimate")
    raw = raw_log if isinstance(raw_log, ScanIndex) else index_scans(raw_log)
    index = _StampIndex(t_est, p_est, tolerance)
    source = np.array([index.find(t) for t in raw.stamps.tolist()], dtype=np.int64)
    processed = source >= 0
    if not processed.any():
        raise DataFormatError(
            f"none of the {t_est.shape[0]} estimated stamps matches a scan ipc_timestamp of the raw log "
            f"(within {tolerance:g} s); are they logger stamps or from another log?",
            path=raw.path,
        )
    n = len(raw)
    poses = np.empty((n, 3))
    poses[processed] = p_est[source[processed]]
    # anchor[i]: last processed scan at or before i in file order (-1 before the first one).
    anchor = np.maximum.accumulate(np.where(processed, np.arange(n), -1))
    first = int(np.argmax(processed))
    fwd = ~processed & (anchor >= 0)
    a = anchor[fwd]
    poses[fwd] = compose(poses[a], between(raw.odom[a], raw.odom[fwd]))
    if fill != "odometry":
        after = slice(first, n)
        done = processed[after]
        poses[after] = fill_skipped(poses[after][done], done, raw.odom[after], raw.stamps[after], fill, updates[0], updates[1])
    keep = np.ones(n, dtype=bool)
    if backfill:
        # The increment from the first processed scan back to an earlier one: the same rule.
        poses[:first] = compose(poses[first], between(raw.odom[first], raw.odom[:first]))
    else:
        keep[:first] = False
    matched = set(t_est[source[processed]].tolist())
    before = (
        f"the {first} scans before the first processed one are filled backwards from it the same way"
        if backfill
        else f"the {first} scans before the first processed one are left out"
    )
    rule = (
        f"{int(processed.sum())} of {n} scans of {os.path.basename(raw.path)} take the estimated pose of their "
        f"ipc_timestamp (exact match, else within {tolerance:g} s); each of the other {int(fwd.sum())} takes the pose "
        "of the last processed scan before it in file order composed with the raw-odometry increment "
        f"between(odom_last_processed, odom_now) of the scans' odom fields"
        + (
            ""
            if fill == "odometry"
            else f", plus the share of the next processed pose's correction to that odometry prediction reached so far "
            f"(max of travelled / {updates[0]:g} m and turned / {updates[1]:g} rad, over the same at the next processed "
            "scan; none after the last processed scan)"
        )
        + f"; {before}."
    )
    return FilledTrajectory(
        stamps=raw.stamps[keep].copy(),
        poses=poses[keep],
        filled=~processed[keep],
        rule=rule,
        source=source[keep],
        lines=raw.lines[keep].copy(),
        n_unmatched_estimates=sum(1 for t in t_est.tolist() if t not in matched),
        n_omitted=int(n - keep.sum()),
    )


@dataclass(eq=False)
class LogAlignment:
    """The scans of a CARMEN log (e.g. a corrected log) expressed on the raw log's stamps.

    Attributes
    ----------
    stamps, poses : ndarray, shapes (k,) and (k, 3)
        ``ipc_timestamp`` (s) of the raw scan each log scan matched, and the log scans' pose
        field (m, m, rad); log file order.
    n_by_stamp, n_by_ranges : int
        Scans matched by their stamp, and (failing that) by identical range readings.
    rule : str
        One sentence saying how the scans were matched.
    """

    stamps: FloatArray
    poses: FloatArray
    n_by_stamp: int
    n_by_ranges: int
    rule: str


def align_to_raw(log: ScanIndex, raw: ScanIndex, *, tolerance: float = DEFAULT_TOLERANCE) -> LogAlignment:
    """Match each scan of ``log`` to the raw-log scan it came from.

    A scan whose ``ipc_timestamp`` equals (within ``tolerance``) a raw scan stamp is that scan,
    provided the readings agree too. Otherwise the raw scan with identical ranges is used: the
    GMapping-corrected logs stamp their scans with the raw *logger* timestamp printed with 6
    significant digits (up to 5 ms off on Intel, where scans can be 11 ms apart), so stamps
    cannot identify them but the readings do. Among raw scans with identical readings the first
    one after the previous match in file order is taken.

    Raises
    ------
    DataFormatError
        Naming the line of the first log scan that matches no raw scan.
    """
    index = _StampIndex(raw.stamps, None, tolerance)
    by_digest: dict[bytes, list[int]] = {}
    for i, d in enumerate(raw.digests):
        by_digest.setdefault(d, []).append(i)
    stamps = np.empty(len(log))
    n_stamp = n_ranges = 0
    previous = -1
    for k in range(len(log)):
        try:
            i = index.find(float(log.stamps[k]))
        except DataFormatError:  # several raw scans share this stamp: let the readings decide
            i = -1
        candidates = by_digest.get(log.digests[k], [])
        # A stamp match counts only if the readings agree too (or no raw scan has these readings,
        # e.g. a SLAM output that rewrote them): a corrected log's logger stamps can equal an
        # unrelated raw ipc stamp by coincidence (3 times on ACES).
        if i >= 0 and (not candidates or i in candidates):
            n_stamp += 1
        elif candidates:
            i = next((c for c in candidates if c > previous), candidates[0])
            n_ranges += 1
        else:
            raise DataFormatError(
                f"scan stamped {log.stamps[k]:.6f} matches no scan of the raw log {raw.path} (neither stamp nor ranges)",
                path=log.path,
                line=int(log.lines[k]),
            )
        stamps[k] = raw.stamps[i]
        previous = i
    rule = (
        f"the {len(log)} scans of {os.path.basename(log.path)} were matched to scans of {os.path.basename(raw.path)}: "
        f"{n_stamp} by ipc_timestamp, {n_ranges} by identical range readings; each takes its raw scan's ipc_timestamp "
        "and keeps its own pose field"
    )
    return LogAlignment(stamps=stamps, poses=log.poses.copy(), n_by_stamp=n_stamp, n_by_ranges=n_ranges, rule=rule)


@dataclass(eq=False)
class RelationsErrors:
    """Per-relation errors of a trajectory against reference relations.

    Attributes
    ----------
    t1, t2 : ndarray, shape (n,)
        Stamps (s) of the evaluated relations.
    errors : ndarray, shape (n, 3)
        ``E = delta_ref^-1 ⊕ delta_est`` per relation (m, m, rad).
    trans, rot : ndarray, shape (n,)
        ``|translation(E)|`` (m) and ``|angle(E)|`` (deg); ``trans2``, ``rot2`` are their squares.
    n_missing : int
        Relations skipped because a stamp has no pose (``on_missing="skip"``).
    missing_stamps : ndarray, shape (k,)
        The distinct stamps (s) that had no pose, in order of first use.
    """

    t1: FloatArray
    t2: FloatArray
    errors: FloatArray
    trans: FloatArray
    rot: FloatArray
    n_missing: int = 0
    missing_stamps: FloatArray = field(default_factory=lambda: np.zeros(0))

    @property
    def n(self) -> int:
        """Relations evaluated."""
        return int(self.trans.shape[0])

    @property
    def trans2(self) -> FloatArray:
        """Squared translational errors (m²), shape (n,)."""
        return self.trans**2

    @property
    def rot2(self) -> FloatArray:
        """Squared rotational errors (deg²), shape (n,)."""
        return self.rot**2

    def summary(self) -> dict[str, float]:
        """Counts, and mean and sample std (ddof=1) of trans (m), rot (deg), trans² (m²), rot² (deg²)."""
        out: dict[str, float] = {"n": self.n, "n_missing": self.n_missing}
        for name, unit, x in (
            ("trans", "m", self.trans),
            ("rot", "deg", self.rot),
            ("trans2", "m2", self.trans2),
            ("rot2", "deg2", self.rot2),
        ):
            out[f"{name}_mean_{unit}"] = float(np.mean(x))
            out[f"{name}_std_{unit}"] = _std(x)
        return out


def relations_error(
    stamps: ArrayLike,
    poses: ArrayLike,
    relations: Relations,
    *,
    on_missing: Literal["raise", "skip"] = "raise",
    tolerance: float = DEFAULT_TOLERANCE,
) -> RelationsErrors:
    """The relations metric of Kuemmerle et al. (2009).

    For each relation ``(t1, t2, delta_ref)``: ``delta_est = P(t1)^-1 ⊕ P(t2)``, the error is
    ``E = delta_ref^-1 ⊕ delta_est``; the metric is ``|translation(E)|`` and ``|angle(E)|``.

    Parameters
    ----------
    stamps, poses : array_like, shapes (m,) and (m, 3)
        Trajectory (s; m, m, rad), any order; stamps are looked up by exact value, then
        within ``tolerance`` (s).
    relations : Relations
    on_missing : {"raise", "skip"}
        A relation whose stamp has no pose raises (default) or is skipped and counted.

    Raises
    ------
    DataFormatError
        Naming the first missing stamp (``on_missing="raise"``); when no relation is left.
    """
    if on_missing not in ("raise", "skip"):
        raise ValueError(f"on_missing must be 'raise' or 'skip', got {on_missing!r}")
    t, p = _as_estimate(stamps, poses, "trajectory")
    index = _StampIndex(t, p, tolerance)
    i1 = np.array([index.find(x) for x in relations.t1.tolist()], dtype=np.int64)
    i2 = np.array([index.find(x) for x in relations.t2.tolist()], dtype=np.int64)
    ok = (i1 >= 0) & (i2 >= 0)
    missing = [x for a, b in zip(relations.t1[~ok].tolist(), relations.t2[~ok].tolist()) for x in (a, b) if index.find(x) < 0]
    if missing and on_missing == "raise":
        k = int(np.argmin(ok))
        raise DataFormatError(
            f"relation {k} refers to stamp {missing[0]:.6f}, which has no pose in the trajectory "
            f"(within {tolerance:g} s); {int((~ok).sum())} relations are affected (skip them with on_missing='skip')",
            field="t1" if i1[k] < 0 else "t2",
        )
    if not ok.any():
        raise DataFormatError(f"none of the {len(relations)} relations has poses for both stamps")
    delta_est = between(p[i1[ok]], p[i2[ok]])
    err = between(relations.delta[ok], delta_est)
    return RelationsErrors(
        t1=relations.t1[ok].copy(),
        t2=relations.t2[ok].copy(),
        errors=err,
        trans=np.hypot(err[:, 0], err[:, 1]),
        rot=np.degrees(np.abs(err[:, 2])),
        n_missing=int((~ok).sum()),
        missing_stamps=np.array(list(dict.fromkeys(missing)), dtype=np.float64),
    )


@dataclass(eq=False)
class ReferenceErrors:
    """Per-pose errors of an estimate against a reference trajectory in the same frame.

    Attributes
    ----------
    stamps : ndarray, shape (k,)
        Matched stamps (s), estimate order.
    errors : ndarray, shape (k, 3)
        ``(x_est - x_ref, y_est - y_ref, wrap(theta_est - theta_ref))`` (m, m, rad).
    n_unmatched : int
        Estimated poses without a reference pose at their stamp (ignored).
    alignment : Se2Alignment or None
        The rigid motion applied to the estimate before the errors were taken (``align="se2"``).
    """

    stamps: FloatArray
    errors: FloatArray
    n_unmatched: int = 0
    alignment: Se2Alignment | None = None

    @property
    def n(self) -> int:
        """Matched poses."""
        return int(self.stamps.shape[0])

    def summary(self) -> dict[str, float]:
        """MAE of x, y (m) and theta (rad and deg), and RMSE of position
        ``sqrt(mean(dx² + dy²))`` (m) — the paper's "average RMSE"."""
        dx, dy, dth = self.errors[:, 0], self.errors[:, 1], self.errors[:, 2]
        mae_th = float(np.mean(np.abs(dth)))
        return {
            "n": self.n,
            "n_unmatched": self.n_unmatched,
            "mae_x_m": float(np.mean(np.abs(dx))),
            "mae_y_m": float(np.mean(np.abs(dy))),
            "mae_theta_rad": mae_th,
            "mae_theta_deg": math.degrees(mae_th),
            "rmse_position_m": float(np.sqrt(np.mean(dx**2 + dy**2))),
        }

    def ape(self) -> dict[str, float]:
        """evo's APE statistics of the translation part (:func:`crlam.eval.align.ape_statistics`)."""
        return ape_statistics(self.errors[:, :2])


def reference_errors(
    stamps_est: ArrayLike,
    poses_est: ArrayLike,
    stamps_ref: ArrayLike,
    poses_ref: ArrayLike,
    *,
    tolerance: float = DEFAULT_TOLERANCE,
    align: Literal["none", "se2"] = "none",
) -> ReferenceErrors:
    """Errors of estimated poses against reference poses at the same stamps.

    ``stamps_est`` (m,) / ``poses_est`` (m, 3) and ``stamps_ref`` (r,) / ``poses_ref`` (r, 3)
    are in s and (m, m, rad); stamps match exactly or, failing that, within ``tolerance`` (s).
    Estimated poses without a reference are counted; none at all raises DataFormatError.
    ``align="none"`` compares the poses as they are (the two trajectories share the world frame,
    as a simulation's ground truth does); ``"se2"`` first moves the estimate by the rigid motion
    that best fits its matched positions to the reference's (:func:`crlam.eval.align.align_se2`,
    evo's ``--align`` in the plane). A stamp estimated twice with different poses raises
    DataFormatError too (identical repeated rows count once).
    """
    t_est, p_est = _as_estimate(stamps_est, poses_est, "estimate")
    t_ref, p_ref = _as_estimate(stamps_ref, poses_ref, "reference")
    # A stamp estimated twice with different poses would be scored twice against one reference
    # pose; repeated identical rows are scored once.
    own = _StampIndex(t_est, p_est, 0.0)
    if own.ambiguous:
        first = min(own.ambiguous)
        rows = np.flatnonzero(t_est == first)[:2].tolist()
        raise DataFormatError(
            f"estimate: {len(own.ambiguous)} stamps occur more than once with different poses (first: {first:.6f} at rows "
            f"{rows[0]} and {rows[1]})",
            field="timestamp",
        )
    keep = np.zeros(t_est.shape[0], dtype=bool)
    keep[sorted(own.exact.values())] = True
    t_est, p_est = t_est[keep], p_est[keep]
    index = _StampIndex(t_ref, p_ref, tolerance)
    j = np.array([index.find(x) for x in t_est.tolist()], dtype=np.int64)
    ok = j >= 0
    if not ok.any():
        raise DataFormatError(f"none of the {t_est.shape[0]} estimated stamps has a reference pose (within {tolerance:g} s)")
    if align not in ("none", "se2"):
        raise ValueError(f"align must be 'none' or 'se2', got {align!r}")
    matched_est, matched_ref = p_est[ok], p_ref[j[ok]]
    alignment = None
    if align == "se2":
        alignment = align_se2(matched_est[:, :2], matched_ref[:, :2])
        matched_est = alignment.apply(matched_est)
    d = matched_est - matched_ref
    d[:, 2] = wrap_angle(d[:, 2])
    return ReferenceErrors(stamps=t_est[ok].copy(), errors=d, n_unmatched=int((~ok).sum()), alignment=alignment)


def aggregate_runs(summaries: Sequence[Mapping[str, object]]) -> dict[str, dict[str, float]]:
    """Mean and sample std (ddof=1, NaN for one run) over runs of every numeric metric.

    ``summaries`` are ``summary()`` dicts of several runs; keys present in all of them are
    aggregated into ``{metric: {"mean": ..., "std": ..., "n_runs": ...}}``.
    """
    if not summaries:
        raise ValueError("aggregate_runs needs at least one summary")
    keys = [k for k in summaries[0] if all(k in s for s in summaries)]
    out: dict[str, dict[str, float]] = {}
    for k in keys:
        values = [s[k] for s in summaries]
        if not all(isinstance(v, (int, float)) and not isinstance(v, bool) for v in values):
            continue
        x = np.array(values, dtype=np.float64)
        out[k] = {"mean": float(np.mean(x)), "std": _std(x), "n_runs": len(values)}
    return out
