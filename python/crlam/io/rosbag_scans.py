"""What :class:`~crlam.io.rosbag.RosbagReader` counts (:class:`BagStats`) and how it turns a scan
message's ranges into a CARMEN-style range array: every invalid reading (NaN, +-inf, 0 or
negative, below ``range_min``, above ``range_max``) becomes ``range_max``, a no-return, and is
counted per cause (the rule is described in :mod:`crlam.io.rosbag`).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray

from crlam.errors import DataFormatError
from crlam.io.carmen_types import CarmenStats

__all__ = ["ECHOES", "BagStats", "echo_ranges", "scan_ranges"]

#: Which return of a MultiEchoLaserScan beam is the range.
ECHOES = ("first", "last", "strongest")


@dataclass
class BagStats(CarmenStats):
    """What a :class:`RosbagReader` saw (the CARMEN counters plus the bag's own).

    Attributes
    ----------
    scan_topic, odom_topic : str
        The topics read (``odom_topic`` is ``"/tf"`` when odometry came from TF).
    odom_frame, base_frame, laser_frame : str
        Frames: odometry's parent frame, the robot's base frame, the scan's ``frame_id``.
    laser_offset : tuple of float
        The laser mount used (x, y, yaw in the base frame).
    upside_down : bool
        True when the beam bearings were mirrored.
    mount_source : str
        ``"tf_static"``, ``"tf"`` (a fixed transform published on ``/tf``), ``"user"``,
        ``"same frame"`` or ``"none (laser at the base frame's origin)"``.
    echo : str
        The return of a MultiEchoLaserScan beam used (``"first"``, ``"last"``, ``"strongest"``).
    imu_topic : str
        The IMU topic read ("" when none was).
    n_inf_ranges, n_nan_ranges, n_above_max_ranges, n_below_min_ranges : int
        Readings made no-returns, per cause (``n_nonpositive_ranges`` counts 0 and negative ones).
    skipped_before_odometry, skipped_after_odometry : int
        Scans skipped because no odometry reading was close enough before/after them.
    skipped_stamp_backwards, skipped_stamp_repeated : int
        Scans skipped because they were stamped before, or at, the previous scan of the topic.
    skipped_odom_repeated : int
        Odometry readings skipped because they repeat the stamp of one already read.
    """

    scan_topic: str = ""
    odom_topic: str = ""
    odom_frame: str = ""
    base_frame: str = ""
    laser_frame: str = ""
    laser_offset: tuple[float, float, float] = (0.0, 0.0, 0.0)
    upside_down: bool = False
    mount_source: str = ""
    echo: str = "first"
    imu_topic: str = ""
    n_inf_ranges: int = 0
    n_nan_ranges: int = 0
    n_above_max_ranges: int = 0
    n_below_min_ranges: int = 0
    skipped_before_odometry: int = 0
    skipped_after_odometry: int = 0
    skipped_stamp_backwards: int = 0
    skipped_stamp_repeated: int = 0
    skipped_odom_repeated: int = 0

    def describe(self) -> dict[str, Any]:
        """The topics, frames and mount used, for a run's ``config.toml``."""
        return {
            "scan_topic": self.scan_topic,
            "odom_topic": self.odom_topic,
            "odom_frame": self.odom_frame,
            "base_frame": self.base_frame,
            "laser_frame": self.laser_frame,
            "laser_mount": [float(v) for v in self.laser_offset],
            "upside_down": self.upside_down,
            "mount_source": self.mount_source,
            "echo": self.echo,
            "imu_topic": self.imu_topic,
        }


def scan_ranges(msg: Any, echo: str, stats: BagStats, path: str) -> NDArray[np.float64]:
    """The ranges of a LaserScan (or MultiEchoLaserScan: the ``echo`` of each beam) with every
    invalid reading made a no-return (``range_max``), each cause counted in ``stats``.
    ``path`` (the bag) names the file in an error."""
    raw = msg.ranges
    if hasattr(raw, "__len__") and len(raw) and hasattr(raw[0], "echoes"):  # MultiEchoLaserScan
        r = echo_ranges(raw, msg.intensities, echo, path)
    else:
        r = np.asarray(raw, dtype=np.float64).copy()
    st = stats
    rmax, rmin = float(msg.range_max), float(msg.range_min)
    nan = np.isnan(r)
    inf = np.isposinf(r)
    nonpos = ~nan & (r <= 0.0)  # includes -inf
    below = ~nan & ~nonpos & (r < rmin)
    above = ~inf & (r > rmax)
    st.n_nan_ranges += int(nan.sum())
    st.n_inf_ranges += int(inf.sum())
    st.n_nonpositive_ranges += int(nonpos.sum())
    st.n_below_min_ranges += int(below.sum())
    st.n_above_max_ranges += int(above.sum())
    st.n_nonfinite_ranges += int((nan | ~np.isfinite(r)).sum())
    r[nan | inf | nonpos | below | above] = rmax
    st.n_no_return_ranges += int(np.count_nonzero(r >= rmax))
    return r


def echo_ranges(ranges: Any, intensities: Any, echo: str, path: str) -> NDArray[np.float64]:
    """One range per beam of a MultiEchoLaserScan: the first, last or strongest echo (NaN,
    a no-return, for a beam without echoes)."""
    out = np.full(len(ranges), np.nan)
    for i, beam in enumerate(ranges):
        echoes = np.asarray(beam.echoes, dtype=np.float64)
        if not len(echoes):
            continue
        if echo == "first":
            out[i] = echoes[0]
        elif echo == "last":
            out[i] = echoes[-1]
        else:
            strength = np.asarray(intensities[i].echoes, dtype=np.float64) if i < len(intensities) else np.zeros(0)
            if len(strength) != len(echoes):
                raise DataFormatError(
                    f"--echo strongest needs an intensity per echo; beam {i} has {len(echoes)} echoes and "
                    f"{len(strength)} intensities",
                    path=path,
                )
            out[i] = echoes[int(np.argmax(strength))]
    return out
