"""``crlam convert``: a CARMEN log to a ROS 2 bag (MCAP storage) and a ROS bag to a CARMEN log.

CARMEN log -> ROS 2 bag (:func:`carmen_to_bag`)
    Every laser scan becomes a ``sensor_msgs/msg/LaserScan`` on ``/scan`` (frame ``laser``,
    stamped with the scan's ipc timestamp; no-returns are ``+inf``) and a ``nav_msgs/msg/Odometry``
    on ``/odom`` (frame ``odom``, child ``base_link``) holding the scan's own odometry at the
    scan's own stamp, written just before it, so that the bag reader (:mod:`crlam.io.rosbag`)
    gives every scan the odometry it had in the log instead of an interpolation. The log's
    ``ODOM`` records are written on ``/odom`` too (with their velocities), except those stamped
    exactly like a scan (the scan's odometry is written there instead). ``/tf_static`` holds
    ``base_link -> laser``, the first scan's laser offset; a log whose laser offset changes
    (by more than the CARMEN precision, 0.05 mm or 5e-7 rad) cannot be written (a bag has one
    static mount). The receive time of each message is its stamp, kept
    in file order (a record stamped before the previous one is received when that one was).
ROS bag -> CARMEN log (:func:`bag_to_carmen`)
    The records of :class:`~crlam.io.rosbag.RosbagReader` (scans with their interpolated
    odometry, and every odometry reading as an ``ODOM`` line) written by
    :class:`~crlam.io.carmen_writer.CarmenWriter`. A scan whose float32 bearings and maximum
    range are those of a FLASER line (a bag converted from a CARMEN log) is written as
    ``FLASER`` with the exact FLASER geometry; any other becomes ``ROBOTLASER1``, whose robot pose
    is the scan's odometry.

What survives a CARMEN -> bag -> CARMEN round trip: the stamps (nanoseconds), the odometry
(float64 in the message), the ranges to the log's 0.1 mm (the message stores float32) and the
beam bearings to float32 precision (``angle_min`` and ``angle_increment`` are float32 in
``sensor_msgs/msg/LaserScan``; about 1e-7 rad). The float32 fields are why ``crlam slam`` on a
log and on its bag agree bit for bit only when the log's ranges and geometry are float32
values; otherwise they differ by what a 1e-7 change in each reading does to the filter.
"""

from __future__ import annotations

import math
import os
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from crlam.errors import ConfigError, DataFormatError
from crlam.io.carmen import CarmenReader
from crlam.io.carmen_types import DEFAULT_FLASER_MAX_RANGE, ImuReading, LaserScan, OdometryReading, flaser_geometry
from crlam.io.carmen_writer import CarmenWriter
from crlam.io.logs import open_log
from crlam.io.rosbag import RosbagReader, is_bag
from crlam.io.rosbag_writer import LASER_SCAN, ODOMETRY, TF_MESSAGE, McapBagWriter, ros_time

__all__ = ["ConversionSummary", "bag_to_carmen", "carmen_to_bag", "convert"]

SCAN_TOPIC = "/scan"
ODOM_TOPIC = "/odom"
ODOM_FRAME = "odom"
BASE_FRAME = "base_link"
LASER_FRAME = "laser"


@dataclass
class ConversionSummary:
    """What a conversion wrote."""

    source: Path
    target: Path
    direction: str
    n_scans: int = 0
    n_odometry: int = 0
    n_odometry_replaced: int = 0
    laser_offset: tuple[float, float, float] | None = None
    topics: dict[str, int] = field(default_factory=dict)

    def describe(self) -> str:
        text = f"{self.source} -> {self.target} ({self.direction}): {self.n_scans} scans, {self.n_odometry} odometry readings"
        if self.n_odometry_replaced:
            text += f" ({self.n_odometry_replaced} ODOM records stamped like a scan replaced by the scan's odometry)"
        if self.topics:
            text += "; topics " + ", ".join(f"{t} ({n})" for t, n in sorted(self.topics.items()))
        return text


def _ns(t: float) -> int:
    sec, nsec = ros_time(t)
    return sec * 1_000_000_000 + nsec


def _same_mount(a: np.ndarray, b: np.ndarray) -> bool:
    # Equal at the CARMEN writer's precision: ROBOTLASER1 offsets are differences of two logged
    # poses and carry rounding noise of ~1e-15.
    return bool(np.all(np.abs(a[:2] - b[:2]) <= 5e-5) and abs(a[2] - b[2]) <= 5e-7)


def carmen_to_bag(source: str | os.PathLike[str], target: str | os.PathLike[str]) -> ConversionSummary:
    """Write the CARMEN log ``source`` as a ROS 2 bag (MCAP storage) at ``target``: a new folder,
    or a single file when ``target`` ends in ``.mcap`` (see the module docstring)."""
    src, dst = Path(source), Path(target)
    summary = ConversionSummary(src, dst, "CARMEN log -> ROS 2 bag (MCAP)")
    # First pass: the scans' stamps (an ODOM record stamped like a scan gives way to it) and
    # the laser offset (one static mount per bag).
    scan_stamps: set[float] = set()
    offset: np.ndarray | None = None
    for rec in CarmenReader(src):
        if isinstance(rec, LaserScan):
            scan_stamps.add(rec.timestamp)
            if offset is None:
                offset = rec.laser_offset.copy()
            elif not _same_mount(rec.laser_offset, offset):
                raise DataFormatError(
                    f"the laser offset changes from {offset.tolist()} to {rec.laser_offset.tolist()}: a bag holds one "
                    "static base_link -> laser transform",
                    path=str(src),
                    line=rec.line,
                )
    if offset is None:
        raise DataFormatError("the log holds no laser scans", path=str(src))
    summary.laser_offset = (float(offset[0]), float(offset[1]), float(offset[2]))
    with McapBagWriter(dst) as bag:
        last_ns = 0
        first = True
        for rec in CarmenReader(src):
            t_ns = max(_ns(rec.timestamp), last_ns)
            if first:
                # The mount, received with the first record.
                static = bag.transform(rec.timestamp, BASE_FRAME, LASER_FRAME, offset)
                bag.write("/tf_static", TF_MESSAGE, t_ns, bag.tf([static]), latched=True)
                first = False
            last_ns = t_ns
            if isinstance(rec, OdometryReading):
                if rec.timestamp in scan_stamps:
                    summary.n_odometry_replaced += 1
                    continue
                msg = bag.odometry(rec.timestamp, ODOM_FRAME, BASE_FRAME, rec.pose, rec.tv, rec.rv)
                bag.write(ODOM_TOPIC, ODOMETRY, t_ns, msg)
                summary.n_odometry += 1
                continue
            bag.write(ODOM_TOPIC, ODOMETRY, t_ns, bag.odometry(rec.timestamp, ODOM_FRAME, BASE_FRAME, rec.odom))
            summary.n_odometry += 1
            scan = bag.laser_scan(rec.timestamp, LASER_FRAME, rec.ranges, rec.angle_min, rec.angle_increment, rec.max_range)
            bag.write(SCAN_TOPIC, LASER_SCAN, t_ns, scan)
            summary.n_scans += 1
        summary.topics = dict(bag.counts)
    return summary


def _snap_flaser(scan: LaserScan) -> None:
    """Give a scan whose float32 geometry is that of a FLASER line (a bag made from a CARMEN log)
    the exact FLASER geometry, so that it is written back as FLASER."""
    amin, inc = flaser_geometry(scan.n_beams, math.pi)
    f32 = np.float32
    if (
        f32(scan.angle_min) == f32(amin)
        and f32(scan.angle_increment) == f32(inc)
        and f32(scan.max_range) == f32(DEFAULT_FLASER_MAX_RANGE)
    ):
        scan.angle_min, scan.angle_increment, scan.max_range = amin, inc, DEFAULT_FLASER_MAX_RANGE


def bag_to_carmen(source: str | os.PathLike[str], target: str | os.PathLike[str], **bag_options: Any) -> ConversionSummary:
    """Write the ROS bag ``source`` as a CARMEN log ``target`` (plain, ``.gz`` or ``.bz2``);
    ``bag_options`` go to :class:`~crlam.io.rosbag.RosbagReader`."""
    src, dst = Path(source), Path(target)
    summary = ConversionSummary(src, dst, "ROS bag -> CARMEN log")
    reader = open_log(src, **bag_options)
    assert isinstance(reader, RosbagReader)
    with CarmenWriter(dst, header=f"converted from the ROS bag {src.name} by crlam convert", robotlaser_pose="odom") as out:
        for rec in reader:
            if isinstance(rec, ImuReading):
                continue  # CARMEN logs have no IMU records
            if isinstance(rec, LaserScan):
                _snap_flaser(rec)
            out.write(rec)
            if isinstance(rec, LaserScan):
                summary.n_scans += 1
            else:
                summary.n_odometry += 1
    st = reader.stats
    summary.laser_offset = st.laser_offset
    summary.topics = {st.scan_topic: summary.n_scans, st.odom_topic: summary.n_odometry}
    return summary


def convert(source: str | os.PathLike[str], target: str | os.PathLike[str], **bag_options: Any) -> ConversionSummary:
    """A ROS bag ``source`` to a CARMEN log, anything else (a CARMEN log) to a ROS 2 bag."""
    src = Path(source)
    if not src.exists():
        raise FileNotFoundError(f"not found: {src}")
    if is_bag(src):
        return bag_to_carmen(src, target, **bag_options)
    if bag_options:
        raise ConfigError(f"{', '.join(sorted(bag_options))}: options for a ROS bag input, but {src.name} is a CARMEN log")
    return carmen_to_bag(src, target)
