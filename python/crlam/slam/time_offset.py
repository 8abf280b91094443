"""The offset between a log's laser stamps and its odometry stamps, estimated from the log itself,
and the odometry re-attached to each scan at its corrected stamp.

Convention
----------
The offset ``d`` (s) is the odometry's stamp minus the laser's stamp of the same instant: the
robot's pose when the scan stamped ``t`` was taken is the odometry's pose stamped ``t + d``. A
laser whose stamps run 0.13 s behind the odometry's has ``d = +0.13``; odometry stamps shifted
later by 0.15 s give ``d = +0.15``.

Estimate (:func:`estimate_time_offset`)
---------------------------------------
1. Scan-matching odometry (:class:`crlam.slam.scan_odometry.ScanMatchOdometry`, which never reads the
   log's odometry) gives each scan a heading ``a(t)`` in the laser's time. To bound the cost, at
   most ``max_scans`` scans are matched, in ``segments`` runs of consecutive scans spread evenly
   over the log (a fresh front end each; the runs are matched in parallel on the core's threads,
   :func:`match_threads`, with the same result on any number). A scan the front end could not match, and a scan whose
   stamp is out of order with its neighbours in file order (Intel's log has such stamps), starts
   no pair and ends none.
2. The odometry's heading ``o(s)`` is the log's odometry records (CARMEN ``ODOM`` lines, a bag's
   odometry messages) in file order, without the records whose stamp is out of order with both
   neighbours, heading unwrapped, linear in between. A log without odometry records uses the
   odometry fields of its scans.
3. Each scan ``i`` pairs with the first scan ``j`` at least ``baseline_s`` later (at most twice
   that) in its run: the scans turned ``a_ij = a(t_j) - a(t_i)``, the odometry
   ``b_ij(d) = o(t_j + d) - o(t_i + d)``. For every candidate ``d`` on a grid of step ``step_s``
   over ``[-search_s, search_s]`` the cost is the least-squares misfit
   ``C(d) = min_k sum (a_ij - k b_ij(d))^2``: the heading scale ``k`` absorbs a mis-scaled
   odometry heading, and its sign a mirrored (upside-down) laser. This is the cross-correlation of
   the two heading-change signals, written for irregular stamps. Pairs whose residual at the
   first minimum exceeds four robust standard deviations (1.4826 MAD; failed matches, wheel
   slips) are dropped and the curve computed again.
4. Sub-sample refinement: the vertex of the parabola through the grid minimum and its two
   neighbours.
5. Confidence: a block bootstrap. The pairs are cut into ``blocks`` contiguous blocks (their
   residuals are correlated within a turn), the blocks are resampled with replacement
   ``bootstrap`` times (seeded) and the refined minimum is found for each; the 95 % interval is
   their 2.5 and 97.5 percentiles.

The estimate is **identified** only when all hold: the grid minimum lies at least
two steps inside the search range; the bootstrap interval's half-width is at most
``max_halfwidth_s``; the heading scale's magnitude is within [0.5, 2] (the scans turn with the
odometry, either way round); and the fit explains at least half of the scans' heading changes
(``1 - C / sum a^2 >= 0.5``). It is **applied** when identified and at least ``min_apply_s``
(0.05 s) in magnitude: the estimate's own error reaches 0.033 s (0.023 s on a simulated log whose
laser and odometry are synchronous; Intel's first 3,000 scans -0.033 s, its whole log -0.002 s,
each with a bootstrap interval that excludes the other), so a smaller estimate is not told apart
from that error, and re-attaching would only trade the
logger's choice of odometry record for the interpolation.
Otherwise the run uses the odometry as the log attaches it (nothing re-interpolated) and says
why.

Application
-----------
:func:`crlam.preflight.odometry_retime.retime_odometry` gives each scan the odometry series interpolated at
``t + d`` (see that module). ``auto`` applies the estimate only when it is identified and at
least ``min_apply_s``; a number given is always applied (0 included); ``off`` never.
"""

from __future__ import annotations

import math
import os
import sys
from collections.abc import Iterable
from dataclasses import asdict, dataclass, field, replace
from typing import Any

import numpy as np
from numpy.typing import NDArray

from crlam.errors import ConfigError
from crlam.io.carmen_types import LaserScan, OdometryReading
from crlam.preflight.odometry_retime import RegularStamps, RetimeStats, interpolate_pose, locally_ordered, retime_odometry
from crlam.slam.config import MAX_TIME_OFFSET, TIME_OFFSET_CHOICES, valid_time_offset

__all__ = [
    "TIME_OFFSET_CHOICES",
    "RetimeStats",
    "TimeOffsetEstimate",
    "TimeOffsetSettings",
    "apply_time_offset",
    "estimate_time_offset",
    "interpolate_pose",
    "log_stamps",
    "parse_time_offset",
    "report",
    "resolve_time_offset",
    "retime_odometry",
    "valid_time_offset",
]

Array = NDArray[np.float64]


def parse_time_offset(text: str) -> str | float:
    """``--time-offset``'s value: ``auto``, ``off`` or seconds (argparse type)."""
    import argparse

    if text in TIME_OFFSET_CHOICES:
        return text
    try:
        v = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected auto, off or a number of seconds, got {text!r}") from None
    if not valid_time_offset(v):
        raise argparse.ArgumentTypeError(f"a time offset must be finite and within +-{MAX_TIME_OFFSET:g} s, got {text!r}")
    return v


@dataclass(frozen=True)
class TimeOffsetSettings:
    """Settings of :func:`estimate_time_offset` (see the module documentation).

    Attributes
    ----------
    search_s : float
        Candidate offsets span ``[-search_s, search_s]`` (s).
    step_s : float
        Grid step of the candidates (s).
    baseline_s : float
        A pair's scans are at least this far apart (s); at most twice that.
    max_scans : int
        Scans matched at most (the estimate's cost).
    segments : int
        Runs of consecutive scans the matched scans are split into, spread over the log.
    blocks : int
        Contiguous blocks of pairs for the bootstrap.
    bootstrap : int
        Bootstrap resamples.
    max_halfwidth_s : float
        The 95 % interval's half-width (s) above which the estimate is not identified.
    min_apply_s : float
        An identified estimate smaller than this (s) in magnitude is not applied: the odometry
        stays as the log attaches it.
    seed : int
        Seed of the bootstrap's draws.
    """

    search_s: float = 0.5
    step_s: float = 0.01
    baseline_s: float = 1.0
    max_scans: int = 1600
    segments: int = 8
    blocks: int = 40
    bootstrap: int = 300
    max_halfwidth_s: float = 0.025
    min_apply_s: float = 0.05
    seed: int = 0

    def __post_init__(self) -> None:
        for name in ("search_s", "step_s", "baseline_s", "max_halfwidth_s"):
            v = getattr(self, name)
            if not (isinstance(v, (int, float)) and math.isfinite(v) and v > 0):
                raise ConfigError(f"TimeOffsetSettings.{name}: must be a finite number > 0 (got {v!r})")
        if not (isinstance(self.min_apply_s, (int, float)) and 0 <= self.min_apply_s < self.search_s):
            raise ConfigError(f"TimeOffsetSettings.min_apply_s: must be in [0, search_s) (got {self.min_apply_s!r})")
        if self.step_s * 4 > self.search_s:
            raise ConfigError("TimeOffsetSettings: search_s must span at least 4 grid steps")
        for name in ("max_scans", "segments", "blocks", "bootstrap"):
            v = getattr(self, name)
            if not (isinstance(v, int) and v >= 1):
                raise ConfigError(f"TimeOffsetSettings.{name}: must be an integer >= 1 (got {v!r})")


@dataclass
class TimeOffsetEstimate:
    """What :func:`estimate_time_offset` found (``metrics.json`` ``time_offset``).

    Attributes
    ----------
    setting : str or float
        What was asked: ``auto``, ``off`` or a number of seconds.
    applied_s : float
        The offset applied to the odometry (s): the estimate when identified, the number given,
        else 0.
    retimed : bool
        Whether each scan's odometry was re-attached at its corrected stamp (identified or
        given); False: the odometry as the log attaches it.
    estimate_s : float or None
        The refined minimum (s); None when nothing could be estimated.
    ci95_s : tuple of float or None
        Bootstrap 95 % interval (s).
    identified : bool
        Whether the estimate passed every test (module documentation).
    reason : str
        Why it was or was not identified / applied.
    heading_scale : float or None
        Fitted scale of the odometry's heading changes onto the scans' (negative: the scans
        turn against the odometry, a mirrored laser).
    explained : float or None
        ``1 - C / sum a^2`` at the estimate.
    residual_rad : float or None
        Robust standard deviation of the pairs' heading residuals (rad).
    n_scans_matched, n_pairs, n_outliers, n_odometry : int
        Scans matched, pairs used, pairs dropped as outliers, odometry samples used.
    odometry_source : str
        ``odometry records`` or ``scan odometry fields``.
    n_stamps_out_of_order : int
        Odometry records left out of the heading series because their stamp is out of order.
    settings : dict
        The :class:`TimeOffsetSettings` used.
    retime : RetimeStats or None
        What the re-attachment did (filled while the run reads the log).
    stamps : RegularStamps or None
        The stamps the re-attachment reads where the log's are bursty
        (:mod:`crlam.preflight.odometry_retime`); set when the odometry is re-attached (from
        the estimate's own pass over the log, or for a given offset by :func:`log_stamps`); not
        in :meth:`to_dict` (``retime`` says which were fitted).
    """

    setting: str | float
    applied_s: float = 0.0
    retimed: bool = False
    estimate_s: float | None = None
    ci95_s: tuple[float, float] | None = None
    identified: bool = False
    reason: str = ""
    heading_scale: float | None = None
    explained: float | None = None
    residual_rad: float | None = None
    n_scans_matched: int = 0
    n_pairs: int = 0
    n_outliers: int = 0
    n_odometry: int = 0
    odometry_source: str = ""
    n_stamps_out_of_order: int = 0
    settings: dict[str, Any] = field(default_factory=dict)
    retime: RetimeStats | None = None
    stamps: RegularStamps | None = field(default=None, repr=False)

    def to_dict(self) -> dict[str, Any]:
        d = asdict(replace(self, stamps=None))
        del d["stamps"]
        d["retime"] = None if self.retime is None else self.retime.to_dict()
        d["ci95_s"] = None if self.ci95_s is None else [float(v) for v in self.ci95_s]
        return d


# -- heading series ---------------------------------------------------------------------------


def _heading_series(stamps: Array, headings: Array) -> tuple[Array, Array, int]:
    """(sorted strictly increasing stamps, unwrapped headings, records left out) of an odometry
    series in file order."""
    t = np.asarray(stamps, dtype=np.float64)
    h = np.asarray(headings, dtype=np.float64)
    ok = locally_ordered(t) & np.isfinite(t) & np.isfinite(h)
    dropped = int((~ok).sum())
    t, h = t[ok], np.unwrap(h[ok])
    order = np.argsort(t, kind="stable")
    t, h = t[order], h[order]
    keep = np.concatenate([[True], np.diff(t) > 0]) if len(t) else np.zeros(0, dtype=bool)
    return t[keep], h[keep], dropped


@dataclass
class _Run:
    """One run of consecutive matched scans: stamps, unwrapped matched headings, usable flags."""

    stamps: list[float] = field(default_factory=list)
    headings: list[float] = field(default_factory=list)
    matched: list[bool] = field(default_factory=list)


def _segment_starts(n_total: int | None, settings: TimeOffsetSettings) -> tuple[list[int], int]:
    """First scan index of each run and the run length."""
    if n_total is None or n_total <= settings.max_scans:
        return [0], settings.max_scans
    length = max(settings.max_scans // settings.segments, 2)
    k = settings.segments
    span = n_total - length
    return [round(span * i / max(k - 1, 1)) for i in range(k)], length


def match_threads() -> int:
    """Threads for work split by Python (the segments of the estimate): the core's own thread
    count (``RAYON_NUM_THREADS``, else every core), so that ``RAYON_NUM_THREADS=1`` keeps a run on
    one core."""
    env = os.environ.get("RAYON_NUM_THREADS", "").strip()
    if env.isdigit() and int(env) > 0:
        return int(env)
    return os.cpu_count() or 1


def _match_segment(scans: list[tuple[Array, Array, Array, float]]) -> _Run:
    """Scan-matching odometry over one segment's scans (angles, ranges, laser offset, stamp), with
    a fresh front end: the run's stamps, unwrapped headings and which scans matched."""
    from crlam.slam.scan_odometry import ScanMatchOdometry, ScanOdometryConfig

    front = ScanMatchOdometry(ScanOdometryConfig())
    run = _Run()
    for angles, ranges, offset, stamp in scans:
        before = front.stats.n_matched
        pose = front.step(angles, ranges, offset, stamp)
        matched = front.stats.n_matched > before or front.stats.n_scans == 1
        heading = float(pose[2])
        if run.headings:  # unwrapped against the run's previous heading
            heading = run.headings[-1] + math.remainder(heading - run.headings[-1], 2.0 * math.pi)
        run.stamps.append(stamp)
        run.headings.append(heading)
        run.matched.append(matched)
    return run


def _collect(
    records: Iterable[object], n_total: int | None, settings: TimeOffsetSettings
) -> tuple[list[_Run], Array, Array, Array, Array, Array]:
    """Match the scans of the runs; collect the odometry records' and the scans' odometry
    (stamp, heading) series, and every scan's stamp (for :class:`RegularStamps`). The runs' scans
    are read in one pass over the records and matched
    afterwards, each run on its own thread (:func:`match_threads`; the matcher releases the GIL):
    the runs are independent, so the result does not depend on the thread count."""
    from concurrent.futures import ThreadPoolExecutor

    starts, length = _segment_starts(n_total, settings)
    segments: list[list[tuple[Array, Array, Array, float]]] = []
    odo_t: list[float] = []
    odo_h: list[float] = []
    att_t: list[float] = []
    att_h: list[float] = []
    scan_t: list[float] = []
    current: list[tuple[Array, Array, Array, float]] | None = None
    k = -1
    seg = 0
    for rec in records:
        if isinstance(rec, OdometryReading):
            odo_t.append(rec.timestamp)
            odo_h.append(float(rec.pose[2]))
            continue
        if not isinstance(rec, LaserScan):
            continue
        k += 1
        if n_total is not None and k >= n_total:
            break
        scan_t.append(float(rec.timestamp))
        if np.all(np.isfinite(rec.odom)):
            att_t.append(rec.timestamp)
            att_h.append(float(rec.odom[2]))
        if seg < len(starts) and k == starts[seg]:
            current = []
            segments.append(current)
            seg += 1
        if current is None:
            continue
        if len(current) >= length:
            current = None
            continue
        ranges = np.where(rec.ranges >= rec.max_range, np.inf, rec.ranges)
        current.append((rec.angles, ranges, rec.laser_offset, rec.timestamp))
    workers = max(1, min(match_threads(), len(segments)))
    if workers == 1:
        runs = [_match_segment(scans) for scans in segments]
    else:
        with ThreadPoolExecutor(max_workers=workers) as pool:
            runs = list(pool.map(_match_segment, segments))
    return (
        runs,
        np.array(odo_t, dtype=np.float64),
        np.array(odo_h, dtype=np.float64),
        np.array(att_t, dtype=np.float64),
        np.array(att_h, dtype=np.float64),
        np.array(scan_t, dtype=np.float64),
    )


def _pairs(runs: list[_Run], baseline: float) -> tuple[Array, Array, Array]:
    """(t_i, t_j, a_ij) of every pair (module documentation, step 3), run after run."""
    ti: list[float] = []
    tj: list[float] = []
    a: list[float] = []
    for run in runs:
        t = np.array(run.stamps, dtype=np.float64)
        h = np.array(run.headings, dtype=np.float64)
        usable = np.array(run.matched, dtype=bool) & locally_ordered(t)
        idx = np.flatnonzero(usable)
        if len(idx) < 2:
            continue
        tu, hu = t[idx], h[idx]
        # Failed matches inside a pair's span break it: count them cumulatively.
        failed = np.concatenate([[0], np.cumsum(~np.array(run.matched, dtype=bool))])
        for p in range(len(idx)):
            q = int(np.searchsorted(tu, tu[p] + baseline, side="left"))
            if q >= len(idx) or q <= p or tu[q] - tu[p] > 2.0 * baseline:
                continue
            if failed[idx[q] + 1] - failed[idx[p]] > 0:
                continue
            ti.append(float(tu[p]))
            tj.append(float(tu[q]))
            a.append(float(hu[q] - hu[p]))
    return np.array(ti), np.array(tj), np.array(a)


def _block_curves(a: Array, b: Array, blocks: int) -> tuple[Array, Array, Array]:
    """Per-block sums (blocks,), (blocks, G), (blocks, G) of a^2, a*b, b^2."""
    edges = np.linspace(0, len(a), min(blocks, len(a)) + 1).astype(int)
    saa = np.add.reduceat(a * a, edges[:-1])
    sab = np.add.reduceat(a[:, None] * b, edges[:-1], axis=0)
    sbb = np.add.reduceat(b * b, edges[:-1], axis=0)
    return saa, sab, sbb


def _cost(saa: float | Array, sab: Array, sbb: Array) -> Array:
    with np.errstate(divide="ignore", invalid="ignore"):
        c = saa - np.where(sbb > 0, sab * sab / sbb, 0.0)
    return np.asarray(c, dtype=np.float64)


def _refine(grid: Array, cost: Array) -> tuple[float, int]:
    """Refined minimum (parabola through the grid minimum and its neighbours) and its index."""
    g = int(np.argmin(cost))
    if 0 < g < len(grid) - 1:
        c0, c1, c2 = cost[g - 1], cost[g], cost[g + 1]
        den = c0 - 2.0 * c1 + c2
        if den > 0:
            shift = 0.5 * (c0 - c2) / den
            return float(grid[g] + max(-1.0, min(1.0, shift)) * (grid[1] - grid[0])), g
    return float(grid[g]), g


def estimate_time_offset(
    records: Iterable[object],
    settings: TimeOffsetSettings | None = None,
    *,
    n_scans: int | None = None,
) -> TimeOffsetEstimate:
    """Estimate the laser-to-odometry stamp offset of a log (module documentation).

    Parameters
    ----------
    records : iterable
        The log's records in file order (:func:`crlam.io.logs.open_log`): laser scans and
        odometry readings; others are ignored.
    settings : TimeOffsetSettings, optional
    n_scans : int, optional
        The log's scan count (:func:`crlam.io.logs.count_scans`), to spread the matched runs
        over the whole log; without it the first ``max_scans`` scans are matched.

    Returns
    -------
    TimeOffsetEstimate
        ``applied_s`` is the estimate when identified, else 0.
    """
    s = settings or TimeOffsetSettings()
    est = TimeOffsetEstimate(setting="auto", settings=asdict(s))
    runs, odo_t, odo_h, att_t, att_h, scan_t = _collect(records, n_scans, s)
    est.n_scans_matched = sum(len(r.stamps) for r in runs)
    if len(odo_t) >= 2:
        est.odometry_source = "odometry records"
        t_o, h_o, est.n_stamps_out_of_order = _heading_series(odo_t, odo_h)
    else:
        est.odometry_source = "scan odometry fields"
        t_o, h_o, est.n_stamps_out_of_order = _heading_series(att_t, att_h)
    est.n_odometry = len(t_o)
    if len(t_o) < 2:
        est.reason = "not identified: the log has no odometry to compare the scans with"
        return est
    ti, tj, a = _pairs(runs, s.baseline_s)
    n_grid = int(round(s.search_s / s.step_s))
    grid = s.step_s * np.arange(-n_grid, n_grid + 1, dtype=np.float64)
    inside = (ti - s.search_s >= t_o[0]) & (tj + s.search_s <= t_o[-1])
    ti, tj, a = ti[inside], tj[inside], a[inside]
    if len(a) < 2 * s.blocks:
        est.n_pairs = len(a)
        est.reason = f"not identified: {len(a)} scan pairs with odometry around them (at least {2 * s.blocks} needed)"
        return est
    b = np.interp(tj[:, None] + grid[None, :], t_o, h_o) - np.interp(ti[:, None] + grid[None, :], t_o, h_o)
    keep = np.ones(len(a), dtype=bool)
    for _ in range(2):
        saa, sab, sbb = float(a[keep] @ a[keep]), a[keep] @ b[keep], np.sum(b[keep] ** 2, axis=0)
        g = int(np.argmin(_cost(saa, sab, sbb)))
        k = sab[g] / sbb[g] if sbb[g] > 0 else 0.0
        r = a - k * b[:, g]
        sigma = 1.4826 * float(np.median(np.abs(r[keep] - np.median(r[keep]))))
        keep = np.abs(r) <= 4.0 * max(sigma, 1e-4)
    a, b = a[keep], b[keep]
    est.n_pairs, est.n_outliers = int(keep.sum()), int((~keep).sum())
    saa_b, sab_b, sbb_b = _block_curves(a, b, s.blocks)
    cost = _cost(float(saa_b.sum()), sab_b.sum(axis=0), sbb_b.sum(axis=0))
    d_hat, g = _refine(grid, cost)
    sbb_g = float(sbb_b.sum(axis=0)[g])
    k = float(sab_b.sum(axis=0)[g] / sbb_g) if sbb_g > 0 else 0.0
    saa = float(saa_b.sum())
    est.estimate_s, est.heading_scale = d_hat, k
    est.explained = float(1.0 - cost[g] / saa) if saa > 0 else 0.0
    est.residual_rad = float(1.4826 * np.median(np.abs(a - k * b[:, g] - np.median(a - k * b[:, g]))))
    rng = np.random.default_rng(s.seed)
    nb = len(saa_b)
    boots = np.empty(s.bootstrap)
    for i in range(s.bootstrap):
        pick = rng.integers(0, nb, nb)
        boots[i] = _refine(grid, _cost(float(saa_b[pick].sum()), sab_b[pick].sum(axis=0), sbb_b[pick].sum(axis=0)))[0]
    lo, hi = (float(v) for v in np.percentile(boots, [2.5, 97.5]))
    est.ci95_s = (lo, hi)
    half = 0.5 * (hi - lo)
    why = []
    if g < 2 or g > len(grid) - 3:
        why.append(f"the best offset lies at the edge of the search range +-{s.search_s:g} s")
    if half > s.max_halfwidth_s:
        why.append(f"the 95 % interval is +-{half:.3f} s wide (at most +-{s.max_halfwidth_s:g} s)")
    if not 0.5 <= abs(k) <= 2.0:
        why.append(f"the scans' heading changes are {k:.2f} times the odometry's (magnitude 0.5..2 needed)")
    if est.explained < 0.5:
        why.append(f"the fit explains {est.explained:.0%} of the scans' heading changes (50 % needed)")
    if why:
        est.reason = "not identified: " + "; ".join(why)
        return est
    est.identified = True
    found = f"identified: {d_hat:+.3f} s, 95 % interval [{lo:+.3f}, {hi:+.3f}] s, from {est.n_pairs} scan pairs"
    if abs(d_hat) < s.min_apply_s:
        est.reason = f"{found}; smaller than {s.min_apply_s:g} s: not applied, the odometry as the log attaches it"
        return est
    est.retimed = True
    est.applied_s = d_hat
    est.reason = found
    est.stamps = RegularStamps.of(scan_t, odo_t)
    return est


def report(estimate: TimeOffsetEstimate) -> None:
    """One line on stderr saying what the time offset is and why."""
    print(f"time offset: {estimate.applied_s:+.3f} s applied ({estimate.setting}): {estimate.reason}", file=sys.stderr)


def resolve_time_offset(
    setting: str | float,
    log_path: str | os.PathLike[str],
    *,
    bag_options: dict[str, Any] | None = None,
    max_scans: int | None = None,
    odometry: str = "wheel",
    settings: TimeOffsetSettings | None = None,
) -> TimeOffsetEstimate:
    """The offset a run applies for the setting ``auto``, ``off`` or seconds (``SlamConfig.time_offset``).

    ``auto`` estimates it from the log (its first ``max_scans`` scans; a separate pass over the
    log, :func:`estimate_time_offset`); with scan-matching odometry (``odometry="scan_match"``)
    there is no odometry to shift and nothing is done.
    """
    if not valid_time_offset(setting):
        raise ConfigError(f"time_offset must be 'auto', 'off' or seconds within +-{MAX_TIME_OFFSET:g}, got {setting!r}")
    if odometry == "scan_match":
        return TimeOffsetEstimate(setting=setting, reason="not applicable: the motion input is scan-matching odometry")
    if setting == "off":
        return TimeOffsetEstimate(setting=setting, reason="off: the odometry as the log attaches it to each scan")
    from crlam.io.logs import count_scans, open_log

    if not isinstance(setting, str):
        est = TimeOffsetEstimate(
            setting=setting,
            applied_s=float(setting),
            retimed=True,
            reason="given",
            odometry_source=_odometry_source(open_log(log_path, **(bag_options or {}))),
        )
    else:
        n = count_scans(log_path, max_scans, bag_options=bag_options)
        est = estimate_time_offset(open_log(log_path, **(bag_options or {})), settings, n_scans=n)
        est.setting = setting
    if est.retimed and est.stamps is None:  # a number given: no estimate pass read the stamps
        est.stamps = log_stamps(open_log(log_path, **(bag_options or {})))
    return est


def log_stamps(records: Iterable[object]) -> RegularStamps:
    """The stamps the re-attachment reads for a log (its records in file order, as the run reads
    them): fitted for each of the scans' and the odometry records' series that is bursty."""
    scans: list[float] = []
    odometry: list[float] = []
    for rec in records:
        if isinstance(rec, LaserScan):
            scans.append(float(rec.timestamp))
        elif isinstance(rec, OdometryReading):
            odometry.append(float(rec.timestamp))
    return RegularStamps.of(np.array(scans, dtype=np.float64), np.array(odometry, dtype=np.float64))


def _odometry_source(records: Iterable[object], probe_scans: int = 200) -> str:
    """``odometry records`` when an odometry record comes before the ``probe_scans``-th scan's
    successor, else ``scan odometry fields``."""
    n = 0
    for rec in records:
        if isinstance(rec, OdometryReading):
            return "odometry records"
        if isinstance(rec, LaserScan):
            n += 1
            if n > probe_scans:
                break
    return "scan odometry fields"


def apply_time_offset(records: Iterable[object], estimate: TimeOffsetEstimate) -> Iterable[object]:
    """``records`` with the odometry re-attached at the corrected stamps (:func:`retime_odometry`)
    when the estimate says so (``retimed``), else as they are; ``estimate.retime`` gets the
    re-attachment's counts."""
    if not estimate.retimed:
        return records
    estimate.retime = RetimeStats()
    return retime_odometry(
        records, estimate.applied_s, source=estimate.odometry_source, stats=estimate.retime, stamps=estimate.stamps
    )
