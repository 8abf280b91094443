"""The live node's latency for ``crlam bench``: the TurtleBot 4 bag played at its own rate into
``crlam ros slam`` (default settings: the newest scan is kept, the others dropped), on the
loopback interface; from a scan's arrival at the node's reader to the published map -> odom
transform, median and 99th percentile (ms), and the scans dropped and extrapolated (the node's
default ``odom_extrapolation``: a scan does not wait for the bag's late odometry). The player runs
in the same process (a thread, mostly asleep between messages)."""

from __future__ import annotations

import os
from typing import Any

__all__ = ["ROS_LATENCY_BENCH", "ros_latency"]

ROS_LATENCY_BENCH = "ros_slam_latency_ms_turtlebot4"


def ros_latency(*, quick: bool = False, odom_extrapolation: float | None = None) -> dict[str, Any] | None:
    """The figures, or None without cyclonedds or the TurtleBot 4 bag (CRLAM_DATA).
    ``odom_extrapolation`` replaces the node's default (0.0: every scan waits for its odometry)."""
    try:
        import cyclonedds  # noqa: F401
    except ImportError:
        return None
    from crlam.io.datasets import data_root

    root = data_root()
    bag = None if root is None else root / "bags" / "turtlebot4-mac-floor"
    if bag is None or not bag.exists():
        return None
    from crlam.ros.params import NodeParameters
    from crlam.ros.play import play_bag
    from crlam.ros.slam_node import SlamNode

    domain = 150 + os.getpid() % 80
    params = NodeParameters() if odom_extrapolation is None else NodeParameters(odom_extrapolation=odom_extrapolation)
    node = SlamNode(params, {}, domain=domain)
    node.start()
    try:
        stats = play_bag(bag, rate=1.0, domain=domain, wait_for=["/scan", "/odom", "/tf_static"], duration=8.0 if quick else None)
        node.wait_idle()
    finally:
        node.stop(save=False)
    lat = node.latency_summary()
    return {
        "median_ms": lat.get("latency_median_ms", float("nan")),
        "p99_ms": lat.get("latency_p99_ms", float("nan")),
        "scans_published": stats.published.get("/scan", 0),
        "counters": dict(node.counters),
        "scan_period_ms": 1e3 / 7.7,
        "bag": str(bag),
    }
