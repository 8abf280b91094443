"""ROS 2's QoS profiles (``rclcpp::SensorDataQoS``, ``rclcpp::QoS(10)``, a latched map) as Cyclone DDS QoS.

- :func:`sensor_data`: best effort, keep last 5, volatile (``/scan``): a subscriber of either
  reliability receives it.
- :func:`reliable`: reliable, keep last ``depth`` (10), volatile (``/odom``, ``/tf``, ``/pose``...).
- :func:`latched`: reliable, transient local, keep last 1 (``/map``, ``/map_metadata``,
  ``/tf_static``): a late subscriber (RViz, Nav2) still gets the newest sample, as
  ``map_server`` and slam_toolbox publish their map.

Every profile pins the data representation to XCDR1 (plain CDR), the one ROS 2 uses.
"""

from __future__ import annotations

from cyclonedds.core import Policy, Qos
from cyclonedds.util import duration

__all__ = ["latched", "qos_for_topic", "reliable", "sensor_data"]

_XCDR1 = Policy.DataRepresentation(use_cdrv0_representation=True)


def sensor_data(depth: int = 5) -> Qos:
    """Best effort, keep last ``depth``, volatile."""
    return Qos(Policy.Reliability.BestEffort, Policy.History.KeepLast(depth), Policy.Durability.Volatile, _XCDR1)


def reliable(depth: int = 10) -> Qos:
    """Reliable, keep last ``depth``, volatile."""
    return Qos(
        Policy.Reliability.Reliable(max_blocking_time=duration(milliseconds=100)),
        Policy.History.KeepLast(depth),
        Policy.Durability.Volatile,
        _XCDR1,
    )


def latched(depth: int = 1) -> Qos:
    """Reliable, keep last ``depth``, transient local."""
    return Qos(
        Policy.Reliability.Reliable(max_blocking_time=duration(milliseconds=100)),
        Policy.History.KeepLast(depth),
        Policy.Durability.TransientLocal,
        _XCDR1,
    )


#: Topics with a profile other than :func:`reliable`.
_SENSOR_TOPICS = ("/scan", "/scan_multi", "/multi_scan")
_LATCHED_TOPICS = ("/tf_static", "/map", "/map_metadata", "/map_confidence", "/robot_description")


def qos_for_topic(topic: str, latched_in_bag: bool = False) -> Qos:
    """The profile ROS 2 drivers use for ``topic``: sensor data for laser scans, latched for the
    map and the static transforms (and whatever a bag recorded as transient local), else reliable."""
    if topic in _LATCHED_TOPICS or latched_in_bag:
        return latched()
    if topic in _SENSOR_TOPICS or topic.endswith("/scan"):
        return sensor_data()
    return reliable()
