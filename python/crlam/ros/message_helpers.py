"""Small builders shared by the ROS 2 nodes and the live view: the generated message module, stamps
and planar poses as ROS messages."""

from __future__ import annotations

import math
from typing import Any

import numpy as np
from numpy.typing import NDArray

__all__ = ["pose_msg", "ros_messages", "ros_stamp", "stamp_seconds", "yaw_quaternion"]


def ros_messages() -> Any:
    """:mod:`crlam.ros.messages`, typed as Any: its IDL field annotations are runtime objects
    that type checkers cannot read (tests/test_ros_messages.py checks the types instead)."""
    from crlam.ros import messages

    return messages


def stamp_seconds(t: Any) -> float:
    return float(t.sec) + float(t.nanosec) * 1e-9


def ros_stamp(seconds: float) -> Any:
    from crlam.ros.messages import Time

    ns = max(int(round(seconds * 1e9)), 0)
    return Time(sec=ns // 1_000_000_000, nanosec=ns % 1_000_000_000)


def yaw_quaternion(yaw: float) -> Any:
    from crlam.ros.messages import Quaternion

    return Quaternion(x=0.0, y=0.0, z=math.sin(yaw / 2), w=math.cos(yaw / 2))


def pose_msg(p: NDArray[np.float64]) -> Any:
    from crlam.ros.messages import Point, Pose

    return Pose(position=Point(x=float(p[0]), y=float(p[1]), z=0.0), orientation=yaw_quaternion(float(p[2])))
