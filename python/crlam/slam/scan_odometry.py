"""Scan-matching odometry: a motion input for the filters from the laser scans themselves, for
logs without wheel odometry (hand-held and backpack lasers) or with it withheld.

Each scan is matched against a local map of the scans just before it, and the matched poses
stand in for the odometry: :func:`scan_match_odometry` replaces every scan's ``odom`` field (and
``pose``, the laser pose from odometry) by the front end's pose, and drops the log's own odometry
records, so a filter downstream sees an ordinary odometry stream and takes its increments between
processed scans as its motion input, as it does with wheel odometry.

The front end (:class:`ScanMatchOdometry`)
------------------------------------------
Local map
    Two GMapping-style grids of the same key scans (:class:`crlam._native.LocalMapMatcher`:
    counting cells with the mean of their hits, GMapping's matcher), 0.05 m and 0.025 m, with
    readings used up to ``usable_range`` (20 m: along a corridor only the far walls fix the
    position), holding the last ``window`` to ``2 * window`` key scans. A scan becomes a key
    scan when the matched pose has moved ``keyframe_distance`` or turned ``keyframe_angle``
    since the last one (the first scan is one). When the grids hold ``2 * window`` key scans
    they are rebuilt from the last ``window``: the map never holds the drift of a whole loop,
    and a revisit cannot snap the odometry onto an old, drifted copy of a place (closing loops
    is the filter's job).
Prediction
    The start of each match: the last pose composed with ``carry`` (one half) of the last
    increment, scaled by the ratio of the scan intervals when both are positive and within a
    factor two (CARMEN logs are not always time-sorted). Carrying all of it (constant velocity)
    lets a motion that the scans do not confirm run on by itself along a corridor; carrying half
    lets it die away. With an IMU (``sensor_msgs/msg/Imu`` in a bag), the heading change is the
    yaw rate integrated between the two scans' stamps instead.
Match
    GMapping's hill climbing on the coarse grid and then on the fine one, with a score kernel
    ``score_cells`` (1.5) cells wide on each (GMapping's own kernel is nearly flat over a cell,
    so its climb counts matched beams more than it measures their distances: 1.5 to 2 times
    the step error on the simulated logs). A match is accepted when at least ``min_match_fraction`` of the
    scan's usable beams match on a grid; the pose is that of the finest such grid. Only when the
    climb from the prediction is not accepted does it start again from the last pose (no
    motion): along a corridor both starts would be kept where they are, and the better score of
    the two a coin toss between moving on and stopping. When neither is accepted the prediction
    is kept (counted in :class:`ScanOdometryStats`).

The settings were chosen on the simulated development logs (``crlam simulate --sensor sick``,
museum and office worlds, seeds 0 and 1), by the error of the front end's increments over 10
and 100 scans against the ground truth.

The poses are the robot's base frame (the scans' laser offset is applied when matching and
mapping). They start at the first scan's odometry pose when the log has one (so that a
trajectory compares with a reference in the log's frame; nothing else of the log's odometry is
read), else at the origin, (0, 0, 0).
"""

from __future__ import annotations

import math
import os
from collections import deque
from collections.abc import Iterable, Iterator
from dataclasses import asdict, dataclass, field, replace
from typing import TYPE_CHECKING, Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from crlam import _native
from crlam.errors import ConfigError
from crlam.io.carmen_types import ImuReading, LaserScan
from crlam.pose import between, compose

if TYPE_CHECKING:
    from crlam.slam.config import SlamConfig

__all__ = [
    "ODOMETRY_CHOICES",
    "SCAN_MATCH_MOTION_PARAMS",
    "ImuYaw",
    "ScanMatchOdometry",
    "ScanOdometryConfig",
    "ScanOdometryStats",
    "resolve_odometry",
    "scan_match_filter_config",
    "scan_match_odometry",
]

#: GMapping's odometry-noise parameters (srr, srt, str, stt) that a filter uses with
#: scan-matching odometry unless ``motion_params`` are given (see ``crlam slam --odometry``):
#: :func:`crlam.slam.motion_noise.fit_gmapping_noise` of the front end's increments between the
#: filter's processed scans (0.5 m / 0.25 rad) against the ground truth's, over the four simulated
#: development logs of the default preset (``crlam simulate --sensor sick``, museum and office,
#: seeds 0 and 1, 3,000 scans; 1,173 steps). GMapping's defaults are 0.1, 0.2, 0.1, 0.2: the
#: front end's increments are 3 to 30 times more precise than wheel odometry's.
SCAN_MATCH_MOTION_PARAMS = (0.0156, 0.0052, 0.0275, 0.0177)


@dataclass(frozen=True)
class ScanOdometryConfig:
    """Settings of the scan-matching front end (see the module documentation).

    Attributes
    ----------
    resolution : float
        Cell size of the local map the match is refined on (m).
    coarse_resolution : float or None
        Cell size of a second local map of the same key scans that each match climbs on first
        (m; None: none). Its cells widen the matcher's reach (a beam matches within one cell of
        an occupied cell), the fine map then sets the pose.
    usable_range : float
        Readings are matched and mapped up to this range (m); longer ones only clear free space.
        Longer than a filter's z_max: along a corridor only the far walls fix the position, and
        the local map is small.
    score_cells : float or None
        Width of the matcher's score kernel in cells of each map: a beam at distance d from its
        match scores exp(-d² / (score_cells x cell)²). GMapping's kernel (None: 0.05 m², a
        0.22 m wide kernel) is nearly flat over a cell, so its climb counts matched beams more
        than it measures their distances.
    keyframe_distance, keyframe_angle : float
        Motion (m, rad) since the last key scan that makes a scan a key scan.
    window : int
        The local map holds the last ``window`` to ``2 * window`` key scans.
    min_match_fraction : float
        A match is accepted when at least this fraction of the usable beams match.
    carry : float
        The prediction repeats this fraction of the last increment (1: constant velocity). Below
        1, a motion that the scans do not confirm (along a corridor, where a climb stays where it
        starts) dies away instead of carrying itself on.
    """

    resolution: float = 0.025
    coarse_resolution: float | None = 0.05
    usable_range: float = 20.0
    score_cells: float | None = 1.5
    keyframe_distance: float = 0.2
    keyframe_angle: float = 0.1
    window: int = 20
    min_match_fraction: float = 0.25
    carry: float = 0.5

    def __post_init__(self) -> None:
        for name in ("resolution", "usable_range", "keyframe_distance", "keyframe_angle"):
            v = getattr(self, name)
            if not (isinstance(v, (int, float)) and math.isfinite(v) and v > 0):
                raise ConfigError(f"ScanOdometryConfig.{name}: must be a finite number > 0 (got {v!r})")
        c = self.coarse_resolution
        if c is not None and not (isinstance(c, (int, float)) and math.isfinite(c) and c > self.resolution):
            raise ConfigError(f"ScanOdometryConfig.coarse_resolution: must be None or finite and > resolution (got {c!r})")
        if not (isinstance(self.window, int) and self.window >= 1):
            raise ConfigError(f"ScanOdometryConfig.window: must be an integer >= 1 (got {self.window!r})")
        if not (isinstance(self.carry, (int, float)) and 0.0 <= self.carry <= 1.0):
            raise ConfigError(f"ScanOdometryConfig.carry: must be in [0, 1] (got {self.carry!r})")
        if not 0.0 <= self.min_match_fraction <= 1.0:
            raise ConfigError(f"ScanOdometryConfig.min_match_fraction: must be in [0, 1] (got {self.min_match_fraction!r})")

    def to_dict(self) -> dict[str, Any]:
        return asdict(self)


@dataclass
class ScanOdometryStats:
    """What the front end did.

    Attributes
    ----------
    n_scans : int
        Scans given a pose.
    n_matched : int
        Scans whose match was accepted.
    n_predicted : int
        Scans that kept the prediction (too few beams matched, or none usable), the first excluded.
    n_keyframes : int
        Key scans inserted into the local map.
    n_rebuilds : int
        Times the local map was rebuilt from its last ``window`` key scans.
    n_imu_readings : int
        IMU readings received.
    n_imu_scans : int
        Scans whose predicted heading change came from the IMU.
    path_length_m : float
        Length of the front end's trajectory (m).
    """

    n_scans: int = 0
    n_matched: int = 0
    n_predicted: int = 0
    n_keyframes: int = 0
    n_rebuilds: int = 0
    n_imu_readings: int = 0
    n_imu_scans: int = 0
    path_length_m: float = 0.0

    def to_dict(self) -> dict[str, Any]:
        return asdict(self)


@dataclass
class _KeyScan:
    pose: NDArray[np.float64]
    angles: NDArray[np.float64]
    ranges: NDArray[np.float64]
    laser_offset: NDArray[np.float64]


def _wrap(a: float) -> float:
    return (a + math.pi) % (2.0 * math.pi) - math.pi


class ScanMatchOdometry:
    """The scan-to-local-map front end (see the module documentation)."""

    def __init__(self, config: ScanOdometryConfig | None = None, initial_pose: ArrayLike | None = None) -> None:
        self.config = config or ScanOdometryConfig()
        self.stats = ScanOdometryStats()
        cfg = self.config
        # Coarse first, the fine map last: each match climbs on every map in turn.
        resolutions = ([] if cfg.coarse_resolution is None else [cfg.coarse_resolution]) + [cfg.resolution]
        self._matchers = [
            _native.LocalMapMatcher(
                resolution=r,
                usable_range=cfg.usable_range,
                score_sigma=0.05 if cfg.score_cells is None else (cfg.score_cells * r) ** 2,
            )
            for r in resolutions
        ]
        self._keys: deque[_KeyScan] = deque(maxlen=2 * self.config.window)
        self._pose: NDArray[np.float64] | None = None
        self._initial = np.zeros(3) if initial_pose is None else np.asarray(initial_pose, dtype=np.float64).reshape(3)
        self._last_increment = np.zeros(3)
        self._last_dt = math.nan
        self._last_stamp = math.nan

    def start_at(self, pose: ArrayLike) -> None:
        """Start the trajectory at ``pose`` instead of the origin (before the first scan only)."""
        if self._pose is not None:
            raise ConfigError("start_at: the front end has started already")
        self._initial = np.asarray(pose, dtype=np.float64).reshape(3).copy()

    def _predict(self, stamp: float, yaw_change: float | None) -> NDArray[np.float64]:
        """The increment (robot frame) expected from the last scan to this one."""
        u = self.config.carry * self._last_increment
        dt, dt0 = stamp - self._last_stamp, self._last_dt
        if dt > 0 and dt0 > 0 and 0.5 <= dt / dt0 <= 2.0:
            u *= dt / dt0
        if yaw_change is not None:
            u[2] = yaw_change
        return u

    def step(
        self,
        angles: NDArray[np.float64],
        ranges: NDArray[np.float64],
        laser_offset: NDArray[np.float64],
        stamp: float,
        yaw_change: float | None = None,
    ) -> NDArray[np.float64]:
        """The robot pose at this scan (x m, y m, theta rad).

        Parameters
        ----------
        angles, ranges : ndarray, shape (n,)
            Beam bearings in the laser frame (rad) and ranges (m; ``inf`` = no return).
        laser_offset : ndarray, shape (3,)
            Laser pose in the robot frame.
        stamp : float
            The scan's time (s).
        yaw_change : float, optional
            Heading change since the previous scan from an IMU (rad).
        """
        angles = np.ascontiguousarray(angles, dtype=np.float64)
        ranges = np.ascontiguousarray(ranges, dtype=np.float64)
        offset = np.ascontiguousarray(laser_offset, dtype=np.float64)
        st = self.stats
        st.n_scans += 1
        if yaw_change is not None:
            st.n_imu_scans += 1
        if self._pose is None:
            pose = self._initial.copy()
        else:
            prev = self._pose
            predicted = np.asarray(compose(prev, self._predict(stamp, yaw_change)), dtype=np.float64)
            starts = [predicted]
            if np.any(self._last_increment != 0.0) or (yaw_change is not None and yaw_change != 0.0):
                still = prev.copy()
                if yaw_change is not None:
                    still[2] = _wrap(still[2] + yaw_change)
                starts.append(still)
            # The prediction first; no motion only when the climb from the prediction fails. A
            # climb moves only while the score strictly improves, so along a corridor, where the
            # scan does not fix the position, it stays at its start: both starts would then be
            # kept where they are, and the better score of the two a coin toss between moving on
            # and stopping.
            best = None
            for start in starts:
                best = self._match(start, angles, ranges, offset)
                if best is not None:
                    break
            if best is not None:
                pose = best[1]
                st.n_matched += 1
            else:
                pose = predicted
                st.n_predicted += 1
            inc = np.asarray(between(prev, pose), dtype=np.float64)
            st.path_length_m += float(math.hypot(inc[0], inc[1]))
            dt = stamp - self._last_stamp
            self._last_increment, self._last_dt = inc, dt
        self._last_stamp = stamp
        self._pose = pose
        self._maybe_insert(pose, angles, ranges, offset)
        return pose.copy()

    def _match(
        self, start: NDArray[np.float64], angles: NDArray[np.float64], ranges: NDArray[np.float64], offset: NDArray[np.float64]
    ) -> tuple[float, NDArray[np.float64]] | None:
        """(fine score, pose) of a climb over the maps in turn from ``start``; the pose of the
        finest map on which enough beams matched, None when none had enough."""
        pose, accepted = start, None
        for matcher in self._matchers:
            p, score, matched, used = matcher.match_scan(pose, angles, ranges, offset)
            if used > 0 and matched >= self.config.min_match_fraction * used:
                pose, accepted = np.array(p), (score, np.array(p))
        return accepted

    def _maybe_insert(
        self, pose: NDArray[np.float64], angles: NDArray[np.float64], ranges: NDArray[np.float64], offset: NDArray[np.float64]
    ) -> None:
        cfg = self.config
        if self._keys:
            d = between(self._keys[-1].pose, pose)
            if math.hypot(d[0], d[1]) < cfg.keyframe_distance and abs(d[2]) < cfg.keyframe_angle:
                return
        key = _KeyScan(pose.copy(), angles.copy(), ranges.copy(), offset.copy())
        self._keys.append(key)
        self.stats.n_keyframes += 1
        rebuild = self._matchers[0].n_inserted >= 2 * cfg.window
        for matcher in self._matchers:
            if rebuild:
                matcher.clear()
                for k in list(self._keys)[-cfg.window :]:
                    matcher.insert(k.pose, k.angles, k.ranges, k.laser_offset)
            else:
                matcher.insert(key.pose, key.angles, key.ranges, key.laser_offset)
        self.stats.n_rebuilds += int(rebuild)

    @property
    def n_key_scans_mapped(self) -> int:
        """Key scans the local map holds now."""
        return self._matchers[0].n_inserted


class ImuYaw:
    """Yaw rates of an IMU, integrated between two stamps (trapezoids between readings, the
    first and last rate held outside them)."""

    def __init__(self, history: int = 4096) -> None:
        self._t: deque[float] = deque(maxlen=history)
        self._w: deque[float] = deque(maxlen=history)

    def __bool__(self) -> bool:
        return bool(self._t)

    def add(self, stamp: float, yaw_rate: float) -> None:
        if self._t and stamp <= self._t[-1]:
            return  # out of order or repeated: the history stays sorted
        if math.isfinite(yaw_rate):
            self._t.append(stamp)
            self._w.append(yaw_rate)

    def _rate(self, t: float) -> float:
        ts = self._t
        k = int(np.searchsorted(np.asarray(ts), t))
        if k == 0:
            return self._w[0]
        if k >= len(ts):
            return self._w[-1]
        a = (t - ts[k - 1]) / (ts[k] - ts[k - 1])
        return self._w[k - 1] + a * (self._w[k] - self._w[k - 1])

    def change(self, t0: float, t1: float) -> float:
        """The heading change (rad) from ``t0`` to ``t1`` (0 when ``t1 <= t0``)."""
        if not self._t or not t1 > t0:
            return 0.0
        ts = np.asarray(self._t)
        inside = ts[(ts > t0) & (ts < t1)]
        knots = np.concatenate([[t0], inside, [t1]])
        rates = np.array([self._rate(float(t)) for t in knots])
        return float(np.sum(0.5 * (rates[1:] + rates[:-1]) * np.diff(knots)))


@dataclass
class _Stream:
    """State of :func:`scan_match_odometry`, readable by the caller after the stream ends."""

    front_end: ScanMatchOdometry
    imu: ImuYaw = field(default_factory=ImuYaw)
    last_stamp: float = math.nan


def scan_match_odometry(
    records: Iterable[object],
    config: ScanOdometryConfig | None = None,
    *,
    front_end: ScanMatchOdometry | None = None,
) -> Iterator[LaserScan]:
    """The laser scans of ``records`` with their odometry replaced by scan-matching odometry.

    Parameters
    ----------
    records : iterable
        A log's records (``crlam.io.open_log``): laser scans are matched, IMU readings
        (:class:`~crlam.io.carmen_types.ImuReading`) give the heading prior, everything else
        (the log's own odometry) is dropped.
    config : ScanOdometryConfig, optional
        The front end's settings (ignored when ``front_end`` is given).
    front_end : ScanMatchOdometry, optional
        The front end to use, so that the caller can read its ``stats`` afterwards.

    Yields
    ------
    LaserScan
        Each scan, ``odom`` = the front end's robot pose and ``pose`` = that pose composed with
        the laser offset; everything else as read.
    """
    state = _Stream(front_end or ScanMatchOdometry(config))
    fe = state.front_end
    first = True
    for rec in records:
        if isinstance(rec, ImuReading):
            state.imu.add(rec.timestamp, rec.yaw_rate)
            fe.stats.n_imu_readings += 1
            continue
        if not isinstance(rec, LaserScan):
            continue
        if first and fe.stats.n_scans == 0 and np.all(np.isfinite(rec.odom)):
            fe.start_at(rec.odom)
        first = False
        ranges = np.where(rec.ranges >= rec.max_range, np.inf, rec.ranges)
        yaw = state.imu.change(state.last_stamp, rec.timestamp) if state.imu and math.isfinite(state.last_stamp) else None
        odom = fe.step(rec.angles, ranges, rec.laser_offset, rec.timestamp, yaw)
        state.last_stamp = rec.timestamp
        yield replace(rec, odom=odom, pose=np.asarray(compose(odom, rec.laser_offset), dtype=np.float64))


#: Values of ``crlam slam --odometry``: ``auto`` takes the input's odometry when it has any.
ODOMETRY_CHOICES = ("auto", "wheel", "scan_match")


def resolve_odometry(
    log_path: str | os.PathLike[str], choice: str = "auto", bag_options: dict[str, Any] | None = None
) -> tuple[str, str]:
    """Which odometry a run uses: ``("wheel" | "scan_match", why)``.

    ``auto`` is ``scan_match`` for a ROS bag without odometry (no ``nav_msgs/msg/Odometry``
    topic and no ``odom -> base`` transform in ``/tf``) and ``wheel`` otherwise (a CARMEN log
    carries odometry in every scan record).
    """
    from crlam.io.logs import open_log
    from crlam.io.rosbag import RosbagReader

    if choice not in ODOMETRY_CHOICES:
        raise ConfigError(f"odometry must be one of {', '.join(ODOMETRY_CHOICES)}, got {choice!r}")
    if choice != "auto":
        return choice, "given"
    reader = open_log(log_path, **(bag_options or {}))
    if not isinstance(reader, RosbagReader):
        return "wheel", "auto: a CARMEN log has odometry in every scan record"
    if reader.has_odometry():
        return "wheel", "auto: the bag has odometry"
    return "scan_match", "auto: the bag has no odometry (no nav_msgs/msg/Odometry topic, no odom -> base transform in /tf)"


def scan_match_filter_config(config: SlamConfig) -> SlamConfig:
    """The filter settings for scan-matching odometry: GMapping's motion model with
    :data:`SCAN_MATCH_MOTION_PARAMS` unless ``motion_params`` are given.

    ``motion_noise = "estimate"`` fits wheel odometry against a scan matcher; scan-matching
    odometry is a scan matcher already, whose noise :data:`SCAN_MATCH_MOTION_PARAMS` states (fitted
    the same way against ground truth), so it takes those and the run records ``"model"``.
    """
    if config.motion_params is not None:
        return config
    return replace(config, motion="gmapping", motion_params=SCAN_MATCH_MOTION_PARAMS, motion_noise="model")
