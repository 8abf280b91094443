"""Semi-real logs: the real scans of a GMapping-corrected log at their corrected poses, given a
drifting odometry of our own, so that SLAM error can be measured against a ground truth on real
buildings (long corridors, campus loops) (``crlam semireal``).

Input: a corrected CARMEN log (``corrected/*-corrected.log.gz`` of the data folder: the FLASER
``odom`` fields hold the corrected robot pose). The corrected poses are the ground truth; the
scans are kept as they are.

Stamps
------
``stamps="log"`` keeps the log's scan stamps; ``"synthetic"`` makes new ones: each scan follows the
previous one after the time the robot needs at ``speed`` (m/s) and ``turn_speed`` (rad/s), the
longer of the two, at least ``min_interval`` (s). ``"auto"`` (default) keeps the log's when they
increase strictly from scan to scan, else makes them (some corrected logs have coarse, repeated or
missing stamps).

Odometry (per scan-to-scan step; ``d`` the true travel in m, ``a`` the true turn in rad)
--------------------------------------------------------------------------------------
Translation in the robot frame: scaled by ``1 + trans_scale``, plus Gaussian noise of standard
deviation ``trans_noise * d`` (m) along and across. Heading: scaled by ``1 + rot_scale``, plus
``heading_bias * d`` (rad: a steady drift per metre, as from unequal wheels), plus Gaussian noise
of standard deviation ``rot_noise * |a| + rot_per_trans * d``. Slip in turns: in steps that turn
faster than ``turn_rate`` (rad/s), an extra Gaussian heading error of standard deviation
``turn_slip * |a|`` and translation error of ``turn_slip * d``. The odometry is the composition of
these steps from the first true pose. Every draw comes from one generator seeded by ``seed``.

Laser lag
---------
``laser_lag`` (s, >= 0): the laser stamps each scan that much after it was taken (on arrival).
The scan's stamp is ``t + laser_lag``; the odometry record of that instant is stamped ``t``; the
scan's odometry field is the odometry at its (late) stamp, as a logger that trusts the stamps
attaches it. The log's time offset (:mod:`crlam.slam.time_offset`) is then ``-laser_lag``.

Output (:func:`write_semireal`): ``log.clf`` (an ``ODOM`` line per scan, then the scan),
``groundtruth.tum`` (the corrected poses at the scans' stamps), ``odometry.tum`` (the odometry at
the true instants) and ``semireal.json`` (settings and summary).
"""

from __future__ import annotations

import json
import math
import os
from dataclasses import asdict, dataclass, replace
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from crlam.errors import ConfigError, DataFormatError
from crlam.io.carmen_types import CarmenRecord, LaserScan, OdometryReading
from crlam.pose import between, compose

__all__ = ["SemiRealLog", "SemiRealSettings", "make_semireal", "write_semireal"]

Array = NDArray[np.float64]


@dataclass(frozen=True)
class SemiRealSettings:
    """The odometry and stamps of a semi-real log (module documentation); units m, rad, s."""

    seed: int = 0
    trans_scale: float = 0.02
    trans_noise: float = 0.03
    rot_scale: float = 0.02
    heading_bias: float = 0.005
    rot_noise: float = 0.03
    rot_per_trans: float = 0.005
    turn_rate: float = 0.2
    turn_slip: float = 0.1
    laser_lag: float = 0.0
    stamps: str = "auto"
    speed: float = 0.5
    turn_speed: float = 0.8
    min_interval: float = 0.1

    def __post_init__(self) -> None:
        for name in ("trans_noise", "rot_noise", "rot_per_trans", "turn_rate", "turn_slip", "laser_lag"):
            v = getattr(self, name)
            if not (isinstance(v, (int, float)) and math.isfinite(v) and v >= 0):
                raise ConfigError(f"SemiRealSettings.{name}: must be a finite number >= 0 (got {v!r})")
        for name in ("trans_scale", "rot_scale", "heading_bias"):
            v = getattr(self, name)
            if not (isinstance(v, (int, float)) and math.isfinite(v) and abs(v) < 1):
                raise ConfigError(f"SemiRealSettings.{name}: must be finite and within (-1, 1) (got {v!r})")
        for name in ("speed", "turn_speed", "min_interval"):
            v = getattr(self, name)
            if not (isinstance(v, (int, float)) and math.isfinite(v) and v > 0):
                raise ConfigError(f"SemiRealSettings.{name}: must be a finite number > 0 (got {v!r})")
        if self.stamps not in ("auto", "log", "synthetic"):
            raise ConfigError(f"SemiRealSettings.stamps: must be auto, log or synthetic (got {self.stamps!r})")
        if not (isinstance(self.seed, int) and self.seed >= 0):
            raise ConfigError(f"SemiRealSettings.seed: must be an integer >= 0 (got {self.seed!r})")


@dataclass
class SemiRealLog:
    """A semi-real log in memory.

    Attributes
    ----------
    scans : list of LaserScan
        The real scans, stamped and with the drifting odometry attached.
    odometry : list of OdometryReading
        One record per scan, at the true instant.
    truth_stamps : ndarray, shape (n,)
        The scans' stamps (s).
    truth : ndarray, shape (n, 3)
        The corrected (true) robot poses.
    odometry_poses : ndarray, shape (n, 3)
        The odometry at the true instants.
    stamps_source : str
        ``log`` or ``synthetic``.
    """

    scans: list[LaserScan]
    odometry: list[OdometryReading]
    truth_stamps: Array
    truth: Array
    odometry_poses: Array
    stamps_source: str

    def records(self) -> list[CarmenRecord]:
        """An ODOM record then the scan, scan after scan (what :func:`write_semireal` writes)."""
        out: list[CarmenRecord] = []
        for o, s in zip(self.odometry, self.scans, strict=True):
            out += [o, s]
        return out


def _stamps(scans: list[LaserScan], truth: Array, s: SemiRealSettings) -> tuple[Array, str]:
    t = np.array([sc.timestamp for sc in scans], dtype=np.float64)
    increasing = len(t) < 2 or bool(np.all(np.diff(t) > 0))
    if s.stamps == "log" or (s.stamps == "auto" and increasing):
        if not increasing:
            raise DataFormatError("stamps='log': the log's scan stamps do not increase strictly from scan to scan")
        return t, "log"
    dt = np.empty(len(scans))
    dt[0] = 0.0
    for k in range(1, len(scans)):
        u = between(truth[k - 1], truth[k])
        dt[k] = max(math.hypot(u[0], u[1]) / s.speed, abs(u[2]) / s.turn_speed, s.min_interval)
    return np.cumsum(dt), "synthetic"


def make_semireal(scans: list[LaserScan], settings: SemiRealSettings | None = None, *, host: str = "semireal") -> SemiRealLog:
    """The semi-real log of a corrected log's scans (module documentation)."""
    s = settings or SemiRealSettings()
    if len(scans) < 2:
        raise DataFormatError(f"a semi-real log needs at least 2 scans, got {len(scans)}")
    truth = np.array([sc.odom for sc in scans], dtype=np.float64)
    if not np.all(np.isfinite(truth)):
        raise DataFormatError("the corrected log has non-finite poses")
    t_true, source = _stamps(scans, truth, s)
    rng = np.random.default_rng(s.seed)
    odo = np.empty_like(truth)
    odo[0] = truth[0]
    for k in range(1, len(scans)):
        u = np.asarray(between(truth[k - 1], truth[k]), dtype=np.float64)
        d, a = math.hypot(u[0], u[1]), math.remainder(float(u[2]), 2.0 * math.pi)
        dt = t_true[k] - t_true[k - 1]
        v = u.copy()
        v[:2] *= 1.0 + s.trans_scale
        v[:2] += rng.normal(0.0, 1.0, 2) * s.trans_noise * d
        v[2] = a * (1.0 + s.rot_scale) + s.heading_bias * d + rng.normal() * (s.rot_noise * abs(a) + s.rot_per_trans * d)
        if dt > 0 and abs(a) / dt > s.turn_rate:
            v[2] += rng.normal() * s.turn_slip * abs(a)
            v[:2] += rng.normal(0.0, 1.0, 2) * s.turn_slip * d
        odo[k] = compose(odo[k - 1], v)
    stamps = t_true + s.laser_lag
    out_scans: list[LaserScan] = []
    records: list[OdometryReading] = []
    from crlam.preflight.odometry_retime import interpolate_pose

    for k, sc in enumerate(scans):
        # The logger attaches the odometry at the scan's stamp, which is late by the lag.
        attached = interpolate_pose(t_true, odo, float(stamps[k])) if s.laser_lag > 0 else odo[k].copy()
        pose = np.asarray(compose(attached, sc.laser_offset), dtype=np.float64)
        out_scans.append(
            replace(
                sc, odom=attached, pose=pose, timestamp=float(stamps[k]), host=host, logger_timestamp=float(stamps[k] - stamps[0])
            )
        )
        records.append(
            OdometryReading(
                pose=odo[k].copy(), timestamp=float(t_true[k]), host=host, logger_timestamp=float(t_true[k] - stamps[0])
            )
        )
    return SemiRealLog(out_scans, records, stamps, truth, odo, source)


def write_semireal(
    corrected_log: str | os.PathLike[str],
    out_dir: str | os.PathLike[str],
    settings: SemiRealSettings | None = None,
    *,
    max_scans: int | None = None,
) -> dict[str, Any]:
    """Read ``corrected_log``, make its semi-real log and write the files of the module
    documentation into ``out_dir``; returns the summary written to ``semireal.json``."""
    from crlam.experiments.stress_variants import load_records
    from crlam.io.carmen_writer import write_carmen
    from crlam.io.tum import write_tum

    s = settings or SemiRealSettings()
    scans = [r for r in load_records(corrected_log, max_scans) if isinstance(r, LaserScan)]
    log = make_semireal(scans, s)
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    header = (
        f"crlam semi-real log: the scans of {Path(corrected_log).name} at their corrected poses, "
        f"odometry drawn with seed {s.seed}"
    )
    write_carmen(out / "log.clf", log.records(), header=header)
    write_tum(out / "groundtruth.tum", log.truth_stamps, log.truth, header="corrected poses at the scans' stamps")
    write_tum(out / "odometry.tum", log.truth_stamps - s.laser_lag, log.odometry_poses, header="semi-real odometry")
    end = between(log.truth[-1], log.odometry_poses[-1])
    path = float(np.sum(np.hypot(*np.diff(log.truth[:, :2], axis=0).T)))
    summary = {
        "source": str(corrected_log),
        "settings": asdict(s),
        "n_scans": len(scans),
        "stamps": log.stamps_source,
        "duration_s": float(log.truth_stamps[-1] - log.truth_stamps[0]),
        "path_length_m": path,
        "odometry_end_error_m": float(math.hypot(end[0], end[1])),
        "odometry_end_error_deg": math.degrees(abs(float(end[2]))),
        "time_offset_s": -s.laser_lag,
        # Names inside the folder: the CLI writes into a staging folder and renames it when whole.
        "files": {"carmen": "log.clf", "groundtruth": "groundtruth.tum", "odometry": "odometry.tum"},
    }
    (out / "semireal.json").write_text(json.dumps(summary, indent=2, sort_keys=True) + "\n")
    return summary
