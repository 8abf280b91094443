"""A small synthetic ROS 2 bag for the live-node tests (tests/test_ros_nodes.py, tests/test_live_view.py)."""

from __future__ import annotations

from pathlib import Path

import numpy as np

__all__ = ["corridor_bag"]


def corridor_bag(path: Path) -> Path:
    """A small MCAP bag: a robot driving 1 m along a corridor, 40 scans, odometry at 2x the scan rate."""
    from crlam.io.rosbag_writer import LASER_SCAN, ODOMETRY, TF_MESSAGE, McapBagWriter

    angles = np.linspace(-np.pi / 2, np.pi / 2, 181)
    with McapBagWriter(path) as w:
        w.write("/tf_static", TF_MESSAGE, 0, w.tf([w.transform(0.0, "base_link", "laser", (0.1, 0.0, 0.0))]), latched=True)
        for k in range(80):
            t = 1.0 + 0.05 * k
            x = 0.0125 * k
            w.write("/odom", ODOMETRY, int(t * 1e9), w.odometry(t, "odom", "base_link", (x, 0.0, 0.0), tv=0.25))
            if k % 2 == 1:
                ts = t + 0.01
                lx = x + 0.1
                # Walls at y = +-1.5 and x = 4: the range along each bearing.
                with np.errstate(divide="ignore"):
                    side = np.where(np.abs(np.sin(angles)) > 1e-9, 1.5 / np.abs(np.sin(angles)), np.inf)
                    front = np.where(np.cos(angles) > 1e-9, (4.0 - lx) / np.cos(angles), np.inf)
                ranges = np.minimum(np.minimum(side, front), 8.0)
                w.write(
                    "/scan", LASER_SCAN, int(ts * 1e9), w.laser_scan(ts, "laser", ranges, angles[0], angles[1] - angles[0], 8.0)
                )
    return path
