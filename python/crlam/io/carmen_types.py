"""Record dataclasses shared by the CARMEN reader (:mod:`crlam.io.carmen`) and writer
(:mod:`crlam.io.carmen_writer`).

Units: metres, radians, seconds. Poses are ``(x, y, theta)`` float64 arrays of shape (3,).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
from numpy.typing import ArrayLike, NDArray

from crlam.errors import DataFormatError

__all__ = [
    "DEFAULT_FLASER_MAX_RANGE",
    "CarmenLog",
    "CarmenRecord",
    "CarmenStats",
    "ImuReading",
    "LaserScan",
    "LogRecord",
    "OdometryReading",
    "flaser_geometry",
]

FloatArray = NDArray[np.float64]

DEFAULT_FLASER_MAX_RANGE = 81.0
"""Maximum range (m) given to FLASER/RLASER scans, whose format does not log it (SICK LMS)."""


def _as_vec3(value: ArrayLike, name: str) -> FloatArray:
    a = np.array(value, dtype=np.float64).reshape(-1)
    if a.shape != (3,):
        raise DataFormatError(f"expected 3 values (x, y, theta), got shape {np.shape(value)}", field=name)
    return a


@dataclass(eq=False)
class LaserScan:
    """One planar laser scan.

    Attributes
    ----------
    ranges : ndarray, shape (n,), float64
        Measured distances in metres; ``>= max_range`` means "no return".
    angle_min : float
        Bearing of beam 0 in the laser frame (rad, counter-clockwise, 0 = forward).
    angle_increment : float
        Bearing step between consecutive beams (rad).
    max_range : float
        Sensor maximum range (m).
    pose : ndarray, shape (3,)
        Pose field as logged (x, y in m, theta in rad): the laser pose for FLASER/RLASER, the
        robot pose for ROBOTLASER1; NaN for RAWLASER; for a ROS bag scan the laser pose from
        odometry (``odom`` composed with ``laser_offset``, see :mod:`crlam.io.rosbag`).
    odom : ndarray, shape (3,)
        Odometry pose field (the robot pose again for ROBOTLASER1).
    laser_offset : ndarray, shape (3,)
        Laser pose in the robot frame (m, m, rad).
    timestamp : float
        ``ipc_timestamp`` (s).
    host : str
        Logging host name.
    logger_timestamp : float
        Logger-relative timestamp (s).
    line : int
        1-based line number in the source file (0 for records built in memory).
    kind : str
        Message type the scan came from (``"FLASER"``, ``"RLASER"``, ``"ROBOTLASER1"``, ...;
        ``"LaserScan"`` or ``"MultiEchoLaserScan"`` for a ROS bag).
    """

    ranges: FloatArray
    angle_min: float
    angle_increment: float
    max_range: float
    pose: FloatArray
    odom: FloatArray
    laser_offset: FloatArray = field(default_factory=lambda: np.zeros(3))
    timestamp: float = 0.0
    host: str = "nohost"
    logger_timestamp: float = 0.0
    line: int = 0
    kind: str = "FLASER"

    def __post_init__(self) -> None:
        self.ranges = np.asarray(self.ranges, dtype=np.float64)
        if self.ranges.ndim != 1:
            raise DataFormatError(f"ranges must be 1-D, got shape {self.ranges.shape}", field="ranges")
        self.pose = _as_vec3(self.pose, "pose")
        self.odom = _as_vec3(self.odom, "odom")
        self.laser_offset = _as_vec3(self.laser_offset, "laser_offset")
        self.angle_min = float(self.angle_min)
        self.angle_increment = float(self.angle_increment)
        self.max_range = float(self.max_range)

    @property
    def n_beams(self) -> int:
        """Number of beams ``n``."""
        return int(self.ranges.shape[0])

    @property
    def angles(self) -> FloatArray:
        """Beam bearings in the laser frame, shape (n,), rad."""
        return self.angle_min + self.angle_increment * np.arange(self.n_beams, dtype=np.float64)


@dataclass(eq=False)
class OdometryReading:
    """One ``ODOM`` record.

    Attributes
    ----------
    pose : ndarray, shape (3,)
        Odometry pose (m, m, rad).
    tv, rv, accel : float
        Translational velocity (m/s), rotational velocity (rad/s), acceleration (m/s^2).
    timestamp, logger_timestamp : float
        ``ipc_timestamp`` and logger timestamp (s).
    host : str
        Logging host name.
    line : int
        1-based line number in the source file (0 for records built in memory).
    """

    pose: FloatArray
    tv: float = 0.0
    rv: float = 0.0
    accel: float = 0.0
    timestamp: float = 0.0
    host: str = "nohost"
    logger_timestamp: float = 0.0
    line: int = 0

    def __post_init__(self) -> None:
        self.pose = _as_vec3(self.pose, "pose")


@dataclass(eq=False)
class ImuReading:
    """The yaw rate of one ``sensor_msgs/msg/Imu`` message of a ROS bag (only read for
    scan-matching odometry, :mod:`crlam.slam.scan_odometry`).

    Attributes
    ----------
    yaw_rate : float
        Angular velocity about the robot's vertical axis (rad/s, counter-clockwise): the IMU's
        angular velocity rotated into the base frame by the IMU's mount, z component.
    timestamp : float
        Header stamp (s).
    host : str
        Topic.
    logger_timestamp : float
        The bag's receive time (s).
    """

    yaw_rate: float
    timestamp: float = 0.0
    host: str = "nohost"
    logger_timestamp: float = 0.0


CarmenRecord = LaserScan | OdometryReading
#: A record of any reader: a bag reader asked for IMU readings also yields :class:`ImuReading` s.
LogRecord = LaserScan | OdometryReading | ImuReading


@dataclass
class CarmenStats:
    """What a :class:`CarmenReader` saw, filled while iterating.

    Attributes
    ----------
    n_lines : int
        Lines read so far.
    records : dict[str, int]
        Yielded records per message type (``"FLASER"``, ``"ODOM"``, ...).
    ignored : dict[str, int]
        Lines skipped on purpose per type (``"PARAM"``, ``"NEFF"``, ``"comment"``, ``"blank"``,
        ``"RAWLASER1"`` without ``include_raw``, ...).
    unknown_kinds : dict[str, int]
        Lines whose message type the reader does not know, per type.
    skipped_malformed : int
        Malformed lines skipped (``on_error="skip"`` only).
    malformed_examples : list[tuple[int, str]]
        The first few ``(line, reason)`` of the skipped malformed lines.
    n_no_return_ranges : int
        Ranges at or above the scan's ``max_range`` (after the replacements below).
    n_nonfinite_ranges : int
        NaN / infinite ranges replaced by ``max_range``.
    n_nonpositive_ranges : int
        Ranges ``<= 0`` replaced by ``max_range``.
    params : dict[str, str]
        Last value of every ``PARAM`` seen.
    """

    n_lines: int = 0
    records: dict[str, int] = field(default_factory=dict)
    ignored: dict[str, int] = field(default_factory=dict)
    unknown_kinds: dict[str, int] = field(default_factory=dict)
    skipped_malformed: int = 0
    malformed_examples: list[tuple[int, str]] = field(default_factory=list)
    n_no_return_ranges: int = 0
    n_nonfinite_ranges: int = 0
    n_nonpositive_ranges: int = 0
    params: dict[str, str] = field(default_factory=dict)

    @property
    def n_scans(self) -> int:
        """Laser scans yielded (all laser kinds)."""
        return sum(v for k, v in self.records.items() if k != "ODOM")

    @property
    def n_odometry(self) -> int:
        """ODOM records yielded."""
        return self.records.get("ODOM", 0)

    @property
    def n_records(self) -> int:
        """All records yielded."""
        return sum(self.records.values())


def flaser_geometry(n: int, fov: float = math.pi) -> tuple[float, float]:
    """Implicit ``(angle_min, angle_increment)`` (rad) of an ``n``-beam FLASER/RLASER scan.

    Even ``n`` divides the field of view into ``n`` steps (180 -> 1 deg, 360 -> 0.5 deg); odd
    ``n > 1`` includes both ends (181 -> 1 deg from -90 to +90 deg).
    """
    step = fov / (n - 1) if n % 2 == 1 and n > 1 else fov / max(n, 1)
    return -0.5 * fov, step


@dataclass(eq=False)
class CarmenLog:
    """A whole CARMEN log in memory (for small logs), in file order.

    Attributes
    ----------
    scans : list[LaserScan]
    odometry : list[OdometryReading]
    stats : CarmenStats
    path : Path or None
    """

    scans: list[LaserScan]
    odometry: list[OdometryReading]
    stats: CarmenStats
    path: Path | None = None

    @property
    def scan_timestamps(self) -> FloatArray:
        """``ipc_timestamp`` of every scan, shape (n_scans,), s, file order (not sorted)."""
        return np.array([s.timestamp for s in self.scans], dtype=np.float64)

    @property
    def odometry_poses(self) -> FloatArray:
        """Odometry poses of the ODOM records, shape (n_odometry, 3)."""
        return np.array([o.pose for o in self.odometry], dtype=np.float64).reshape(-1, 3)
