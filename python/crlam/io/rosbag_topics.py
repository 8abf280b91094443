"""Which topics of a ROS bag :class:`~crlam.io.rosbag.RosbagReader` reads: the message types it
knows and the choice of the scan, odometry and IMU topics (given, or the only one of its type).

A topic that is missing or ambiguous is an error made by the reader's ``error`` callback (a
:class:`~crlam.errors.DataFormatError` naming the bag and listing its topics, :func:`topics_text`).
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from typing import Any

from crlam.errors import DataFormatError

__all__ = [
    "IMU_TYPE",
    "LASER_TYPES",
    "ODOMETRY_TYPE",
    "TF_TYPE",
    "TopicError",
    "pick_imu",
    "pick_odom",
    "pick_scan",
    "topics_text",
]

LASER_TYPES = ("sensor_msgs/msg/LaserScan", "sensor_msgs/msg/MultiEchoLaserScan")
ODOMETRY_TYPE = "nav_msgs/msg/Odometry"
TF_TYPE = "tf2_msgs/msg/TFMessage"
IMU_TYPE = "sensor_msgs/msg/Imu"

#: Makes the error of a topic choice: (message, the bag's connections) -> the error to raise.
TopicError = Callable[[str, Sequence[Any]], DataFormatError]


def topics_text(connections: Sequence[Any]) -> str:
    """The bag's topics and their types, ``"/scan (sensor_msgs/msg/LaserScan), ..."``."""
    seen: dict[str, str] = {}
    for c in connections:
        seen.setdefault(c.topic, c.msgtype)
    return ", ".join(f"{t} ({ty})" for t, ty in sorted(seen.items())) or "(none)"


def pick_scan(conns: Sequence[Any], scan_topic: str | None, error: TopicError) -> list[Any]:
    """The scan connections: the given topic (a laser topic), else the only laser topic of the bag."""
    if scan_topic is not None:
        sel = [c for c in conns if c.topic == scan_topic]
        if not sel:
            raise error(f"scan topic {scan_topic!r} not in the bag", conns)
        if sel[0].msgtype not in LASER_TYPES:
            raise error(f"scan topic {scan_topic!r} is a {sel[0].msgtype}, not a LaserScan", conns)
        return sel
    topics = sorted({c.topic for c in conns if c.msgtype in LASER_TYPES})
    if not topics:
        raise error("no sensor_msgs/msg/LaserScan topic in the bag", conns)
    if len(topics) > 1:
        raise error(f"several laser topics ({', '.join(topics)}): choose one with --scan-topic", conns)
    return [c for c in conns if c.topic == topics[0]]


def pick_odom(conns: Sequence[Any], odom_topic: str | None, error: TopicError) -> tuple[list[Any], bool]:
    """The odometry connections and whether they are TF (True) or Odometry messages."""
    tf = [c for c in conns if c.topic in ("/tf", "tf") and c.msgtype == TF_TYPE]
    if odom_topic is not None:
        sel = [c for c in conns if c.topic == odom_topic]
        if not sel:
            raise error(f"odometry topic {odom_topic!r} not in the bag", conns)
        if sel[0].msgtype == TF_TYPE:
            return sel, True
        if sel[0].msgtype != ODOMETRY_TYPE:
            raise error(f"odometry topic {odom_topic!r} is a {sel[0].msgtype}, not nav_msgs/msg/Odometry", conns)
        return sel, False
    topics = sorted({c.topic for c in conns if c.msgtype == ODOMETRY_TYPE})
    if len(topics) > 1:
        preferred = [t for t in topics if t in ("/odom", "odom")]
        if not preferred:
            raise error(f"several odometry topics ({', '.join(topics)}): choose one with --odom-topic", conns)
        topics = preferred[:1]
    if topics:
        return [c for c in conns if c.topic == topics[0]], False
    if tf:
        return tf, True
    raise error(
        "no odometry: neither a nav_msgs/msg/Odometry topic nor /tf (give --odom-topic, or take scan-matching "
        "odometry: crlam slam --odometry scan_match)",
        conns,
    )


def pick_imu(conns: Sequence[Any], imu_topic: str | None, error: TopicError) -> list[Any]:
    """The IMU connections: the given topic, else the only Imu topic, else none."""
    if imu_topic is not None:
        sel = [c for c in conns if c.topic == imu_topic]
        if not sel:
            raise error(f"IMU topic {imu_topic!r} not in the bag", conns)
        if sel[0].msgtype != IMU_TYPE:
            raise error(f"IMU topic {imu_topic!r} is a {sel[0].msgtype}, not {IMU_TYPE}", conns)
        return sel
    topics = sorted({c.topic for c in conns if c.msgtype == IMU_TYPE})
    if len(topics) > 1:
        raise error(f"several IMU topics ({', '.join(topics)}): choose one with --imu-topic", conns)
    return [c for c in conns if c.topic in topics]
