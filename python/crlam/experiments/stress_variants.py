"""Stress variants of a recorded log: the same scans with one thing made harder, each defined
exactly, written as CARMEN logs (``crlam experiment stress``).

Every variant starts from the log's records in file order (:func:`load_records`) and changes one
thing. The odometry of the result is one ``ODOM`` line per scan, stamped as the variant says,
holding the pose the scan's record carries (so the log's odometry records and its scans'
odometry fields agree); the scans' odometry fields are the variant's odometry.

``odom_shift``
    Odometry stamps shifted later by ``odom_shift_s`` (0.15 s): the ``ODOM`` line of scan ``k``
    is stamped ``t_k + 0.15`` and holds the scan's original odometry pose; the scan's own
    odometry field becomes the original odometry interpolated at ``t_k - 0.15`` (what a logger on
    the shifted clock attaches; a scan whose stamp is out of order with its neighbours gets its
    own pose moved by the odometry's motion from ``t_k`` to ``t_k - 0.15``). The true offset
    (:mod:`crlam.slam.time_offset`) is ``+0.15 s``.
``turn_heading``
    The odometry's heading error tripled in turns. The reference heading change of each
    scan-to-scan step is scan-matching odometry's (:class:`crlam.slam.scan_odometry.ScanMatchOdometry`,
    which does not read the odometry); the odometry's heading error of the step is
    ``e = dtheta_odom - dtheta_ref``. In the steps that turn faster than ``turn_rate``
    (0.2 rad/s by the reference) the step's heading change becomes ``dtheta_odom + 2 e`` (its
    error three times what it was); its translation, in the robot frame, is kept. The odometry is
    integrated again from the first pose.
``half_beams``
    Every second beam (beams 0, 2, 4, ...; the increment doubled).
``no_returns``
    ``no_return_fraction`` (10 %) of all readings, drawn uniformly with the variant's seed,
    replaced by no-returns (the scan's maximum range).
``mount_yaw``
    The laser turned by 180 deg on the robot and the log not saying so: each beam is reported at
    its bearing minus pi in the laser frame (``angle_min`` shifted by pi, ranges unchanged), the
    stated laser offset unchanged. Written as ``ROBOTLASER1`` (FLASER cannot state a start angle).
``mount_flip``
    The laser mounted upside down and the log not saying so: each beam is reported at the
    negated bearing (the scan's bearings mirrored, ranges reversed). ``ROBOTLASER1`` as well.
"""

from __future__ import annotations

import math
import os
from collections.abc import Callable
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from crlam.errors import ConfigError, DataFormatError
from crlam.io.carmen_types import CarmenRecord, LaserScan, OdometryReading
from crlam.io.carmen_writer import write_carmen
from crlam.pose import between, compose

__all__ = ["STRESS_VARIANTS", "StressSettings", "build_variant", "load_records", "odometry_series", "write_variant"]

Array = NDArray[np.float64]

#: The variants, in the order of the results table.
STRESS_VARIANTS = ("odom_shift", "turn_heading", "half_beams", "no_returns", "mount_yaw", "mount_flip")


@dataclass(frozen=True)
class StressSettings:
    """The sizes of the stresses (module documentation).

    Attributes
    ----------
    odom_shift_s : float
        ``odom_shift``: seconds the odometry's stamps move later.
    heading_error_factor : float
        ``turn_heading``: the factor on the odometry's heading error in turns.
    turn_rate : float
        ``turn_heading``: steps turning faster than this (rad/s, reference) are turns.
    no_return_fraction : float
        ``no_returns``: fraction of the readings made no-returns.
    seed : int
        Seed of ``no_returns``' draw.
    """

    odom_shift_s: float = 0.15
    heading_error_factor: float = 3.0
    turn_rate: float = 0.2
    no_return_fraction: float = 0.1
    seed: int = 0

    def __post_init__(self) -> None:
        if not (math.isfinite(self.odom_shift_s) and abs(self.odom_shift_s) <= 5.0):
            raise ConfigError(f"StressSettings.odom_shift_s: must be within +-5 s (got {self.odom_shift_s!r})")
        if not (math.isfinite(self.heading_error_factor) and self.heading_error_factor >= 0):
            raise ConfigError(f"StressSettings.heading_error_factor: must be >= 0 (got {self.heading_error_factor!r})")
        if not (math.isfinite(self.turn_rate) and self.turn_rate >= 0):
            raise ConfigError(f"StressSettings.turn_rate: must be >= 0 (got {self.turn_rate!r})")
        if not 0.0 <= self.no_return_fraction <= 1.0:
            raise ConfigError(f"StressSettings.no_return_fraction: must be in [0, 1] (got {self.no_return_fraction!r})")


def load_records(path: str | os.PathLike[str], max_scans: int | None = None) -> list[CarmenRecord]:
    """The scans and odometry records of a CARMEN log in file order, up to the ``max_scans``-th
    scan (the odometry records after it are left out)."""
    from crlam.io.carmen import CarmenReader

    out: list[CarmenRecord] = []
    n = 0
    for rec in CarmenReader(path):
        if isinstance(rec, LaserScan):
            if max_scans is not None and n >= max_scans:
                break
            n += 1
        out.append(rec)
    if n == 0:
        raise DataFormatError("the log holds no laser scans", path=str(path))
    return out


def _scans(records: list[CarmenRecord]) -> list[LaserScan]:
    return [r for r in records if isinstance(r, LaserScan)]


def odometry_series(scans: list[LaserScan]) -> tuple[Array, Array]:
    """(stamps, poses) of the scans' odometry, sorted by stamp, stamps out of order with both
    file-order neighbours left out (:mod:`crlam.slam.time_offset`)."""
    from crlam.preflight.odometry_retime import locally_ordered

    t = np.array([s.timestamp for s in scans], dtype=np.float64)
    p = np.array([s.odom for s in scans], dtype=np.float64).reshape(-1, 3)
    ok = locally_ordered(t)
    t, p = t[ok], p[ok]
    order = np.argsort(t, kind="stable")
    t, p = t[order], p[order]
    keep = np.concatenate([[True], np.diff(t) > 0])
    return t[keep], p[keep]


def _with_odometry(scans: list[LaserScan], odom_stamps: list[float] | None = None) -> list[CarmenRecord]:
    """The scans, each after an ODOM line holding its odometry (stamped ``odom_stamps[k]``, by
    default the scan's own stamp)."""
    out: list[CarmenRecord] = []
    for k, s in enumerate(scans):
        t = s.timestamp if odom_stamps is None else odom_stamps[k]
        out.append(OdometryReading(pose=s.odom.copy(), timestamp=t, host=s.host, logger_timestamp=s.logger_timestamp))
        out.append(s)
    return out


def _set_odom(scan: LaserScan, odom: Array) -> LaserScan:
    """The scan with a new odometry pose; its pose field keeps its logged relation to it."""
    pose = np.asarray(compose(odom, between(scan.odom, scan.pose)), dtype=np.float64)
    return replace(scan, odom=np.asarray(odom, dtype=np.float64), pose=pose)


def _odom_shift(scans: list[LaserScan], s: StressSettings) -> list[CarmenRecord]:
    from crlam.slam.time_offset import interpolate_pose

    t, p = odometry_series(scans)
    # The scan's own pose moved by the series' motion from t to t - shift: the series at t - shift
    # where the stamp is in order (the series passes through the scan's pose there), and no jump
    # from the scan's place where its stamp is out of order (Intel's).
    shifted = [
        _set_odom(
            sc,
            np.asarray(
                compose(
                    sc.odom, between(interpolate_pose(t, p, sc.timestamp), interpolate_pose(t, p, sc.timestamp - s.odom_shift_s))
                ),
                dtype=np.float64,
            ),
        )
        for sc in scans
    ]
    odom_stamps = [sc.timestamp + s.odom_shift_s for sc in scans]
    out: list[CarmenRecord] = []
    for k, sc in enumerate(shifted):
        out.append(OdometryReading(pose=scans[k].odom.copy(), timestamp=odom_stamps[k], host=sc.host))
        out.append(sc)
    return out


def reference_headings(scans: list[LaserScan]) -> Array:
    """Scan-matching odometry's heading (rad, unwrapped) at every scan."""
    from crlam.slam.scan_odometry import ScanMatchOdometry

    fe = ScanMatchOdometry()
    out = np.empty(len(scans))
    last = 0.0
    for k, sc in enumerate(scans):
        ranges = np.where(sc.ranges >= sc.max_range, np.inf, sc.ranges)
        h = float(fe.step(sc.angles, ranges, sc.laser_offset, sc.timestamp)[2])
        last = h if k == 0 else last + math.remainder(h - last, 2.0 * math.pi)
        out[k] = last
    return out


def _turn_heading(scans: list[LaserScan], s: StressSettings) -> list[CarmenRecord]:
    ref = reference_headings(scans)
    extra = s.heading_error_factor - 1.0
    pose = scans[0].odom.copy()
    out = [scans[0]]
    for k in range(1, len(scans)):
        inc = np.asarray(between(scans[k - 1].odom, scans[k].odom), dtype=np.float64)
        d_ref = ref[k] - ref[k - 1]
        dt = scans[k].timestamp - scans[k - 1].timestamp
        turning = dt > 0 and abs(d_ref) / dt > s.turn_rate
        if turning:
            inc[2] += extra * math.remainder(inc[2] - d_ref, 2.0 * math.pi)
        pose = np.asarray(compose(pose, inc), dtype=np.float64)
        out.append(_set_odom(scans[k], pose))
    return _with_odometry(out)


def _half_beams(scans: list[LaserScan], s: StressSettings) -> list[CarmenRecord]:
    return _with_odometry([replace(sc, ranges=sc.ranges[::2].copy(), angle_increment=2.0 * sc.angle_increment) for sc in scans])


def _no_returns(scans: list[LaserScan], s: StressSettings) -> list[CarmenRecord]:
    rng = np.random.default_rng(s.seed)
    out = []
    for sc in scans:
        r = sc.ranges.copy()
        r[rng.random(len(r)) < s.no_return_fraction] = sc.max_range
        out.append(replace(sc, ranges=r))
    return _with_odometry(out)


def _mount_yaw(scans: list[LaserScan], s: StressSettings) -> list[CarmenRecord]:
    return _with_odometry([replace(sc, angle_min=math.remainder(sc.angle_min + math.pi, 2.0 * math.pi)) for sc in scans])


def _mount_flip(scans: list[LaserScan], s: StressSettings) -> list[CarmenRecord]:
    out = []
    for sc in scans:
        last = sc.angle_min + sc.angle_increment * (sc.n_beams - 1)
        out.append(replace(sc, angle_min=-last, ranges=sc.ranges[::-1].copy()))
    return _with_odometry(out)


_BUILDERS: dict[str, Callable[[list[LaserScan], StressSettings], list[CarmenRecord]]] = {
    "odom_shift": _odom_shift,
    "turn_heading": _turn_heading,
    "half_beams": _half_beams,
    "no_returns": _no_returns,
    "mount_yaw": _mount_yaw,
    "mount_flip": _mount_flip,
}


def build_variant(records: list[CarmenRecord], variant: str, settings: StressSettings | None = None) -> list[CarmenRecord]:
    """The records of stress variant ``variant`` (one of :data:`STRESS_VARIANTS`, or ``none``:
    the scans with one ODOM line each, unchanged otherwise)."""
    s = settings or StressSettings()
    if variant != "none" and variant not in _BUILDERS:
        raise ConfigError(f"unknown stress variant {variant!r}: one of none, {', '.join(STRESS_VARIANTS)}")
    scans = _scans(records)
    if not scans:
        raise DataFormatError("the log holds no laser scans")
    if variant == "none":
        return _with_odometry(scans)
    return _BUILDERS[variant](scans, s)


def write_variant(records: list[CarmenRecord], path: str | os.PathLike[str], variant: str) -> Path:
    """Write a variant's records as a CARMEN log (``.gz`` compresses); returns the path."""
    p = Path(path)
    header = f"crlam stress variant {variant} (crlam.experiments.stress_variants)"
    write_carmen(p, records, header=header, robotlaser_pose="odom")
    return p
