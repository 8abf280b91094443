"""Rules for the fields of the ROS messages crlam reads (:mod:`crlam.io.rosbag`).

Each rule is applied to every message before its values are used; a message that breaks one is
refused with a :class:`~crlam.errors.DataFormatError` naming the bag, the topic, the message's
1-based index in its topic and the field, or skipped and counted where the message alone is at
fault and the rest of the bag is sound (stamps).

LaserScan header (``sensor_msgs/msg/LaserScan``, ``MultiEchoLaserScan``)
    ``range_max`` finite and > 0; ``range_min`` finite, >= 0 and < ``range_max``;
    ``angle_min``, ``angle_max``, ``angle_increment``, ``time_increment`` and ``scan_time``
    finite; ``angle_increment`` nonzero when the scan has more than one beam, and the beams
    spanning at most one turn plus one increment (|increment| x (n - 1) <= 2 pi + |increment|).
    Refused otherwise.
Beam count
    The number of beams is checked against the ``readings`` resource limit
    (:mod:`crlam.limits`, ``--max-readings``) and against :data:`MAX_BEAMS_PER_SCAN` before any
    array is made from it: no 2D laser has that many beams a turn, and a scan of more is a
    damaged or foreign message.
Quaternions (odometry orientation, ``/tf`` and ``/tf_static`` rotations)
    All four components finite and a length within :data:`QUATERNION_TOLERANCE` of 1: such a
    quaternion is normalised before use (one within 1e-9 of 1 is used as it is), so that the rounding of a driver that publishes
    slightly off-unit quaternions does not move the heading. A quaternion of length 0, NaN, or
    off by more than the tolerance is refused: it does not say which rotation was meant.
Translations (odometry positions, transforms: the laser's mount)
    Finite. Refused otherwise.
Stamps
    A scan stamped at or before the previous scan of its topic (a stamp that goes backwards or
    repeats) is skipped and counted (``BagStats.skipped_stamp_backwards``,
    ``skipped_stamp_repeated``): every output of crlam is in time order. Odometry readings out of
    order are put in place (the reader keeps its history sorted); a reading that repeats the stamp
    of one already held is skipped and counted (``skipped_odom_repeated``).
"""

from __future__ import annotations

import math
from typing import Any

from crlam.errors import DataFormatError
from crlam.limits import check_limit

__all__ = [
    "MAX_BEAMS_PER_SCAN",
    "QUATERNION_TOLERANCE",
    "MessagePlace",
    "check_scan_header",
    "check_translation",
    "unit_quaternion",
]

#: Largest length error of a quaternion that is normalised rather than refused (|q| in [0.99, 1.01]):
#: float32 rounding gives 1e-7, drivers that compute in float32 a few 1e-4.
QUATERNION_TOLERANCE = 1e-2
#: Length error below which a quaternion is used as it is (its heading moves by less than this
#: in radians): a quaternion written from float64 sines and cosines reads back bit for bit.
_EXACT = 1e-9
#: Most beams a scan message may have: 65,536, several times the densest 2D laser's per turn
#: (0.036 deg is 10,000 a turn). A scan of more is a damaged or foreign message; every beam of a
#: scan is weighed for every particle, so 100,000-beam scans would keep ``crlam localize`` busy
#: for hours per scan.
MAX_BEAMS_PER_SCAN = 65_536


class MessagePlace:
    """Where a message sits: the bag, the topic and the message's 1-based index in its topic;
    makes the errors that name them."""

    def __init__(self, path: str, topic: str, index: int) -> None:
        self.path, self.topic, self.index = path, topic, index

    def error(self, message: str, field: str | None = None) -> DataFormatError:
        return DataFormatError(f"{self.topic} message {self.index}: {message}", path=self.path, field=field)


def _number(value: Any) -> float:
    try:
        return float(value)
    except (TypeError, ValueError):
        return math.nan


def check_scan_header(msg: Any, n_beams: int, place: MessagePlace) -> None:
    """Refuse a scan message whose geometry breaks the rules of the module documentation, or
    whose beam count exceeds the limits (checked before any array is built from it)."""
    check_limit("readings", n_beams, f"scan {place.topic} message {place.index} of {place.path} ({n_beams:,} beams)")
    if n_beams > MAX_BEAMS_PER_SCAN:
        raise place.error(f"{n_beams:,} beams, more than any laser has ({MAX_BEAMS_PER_SCAN:,})", "ranges")
    values = {
        name: _number(getattr(msg, name, math.nan))
        for name in ("range_min", "range_max", "angle_min", "angle_max", "angle_increment", "time_increment", "scan_time")
    }
    for name, v in values.items():
        if not math.isfinite(v):
            raise place.error(f"{name} is {v}, not a finite number", name)
    rmin, rmax, inc = values["range_min"], values["range_max"], values["angle_increment"]
    if rmax <= 0.0:
        raise place.error(f"range_max {rmax} is not positive", "range_max")
    if rmin < 0.0 or rmin >= rmax:
        raise place.error(f"range_min {rmin} is not in [0, range_max = {rmax})", "range_min")
    if n_beams > 1 and inc == 0.0:
        raise place.error(f"angle_increment is 0 for {n_beams} beams (every beam at one bearing)", "angle_increment")
    if abs(inc) * (n_beams - 1) > 2.0 * math.pi + abs(inc) + 1e-6:
        raise place.error(
            f"{n_beams} beams of {inc} rad span {abs(inc) * (n_beams - 1):.3f} rad, more than a turn", "angle_increment"
        )


def unit_quaternion(q: Any, place: MessagePlace, field: str) -> tuple[float, float, float, float]:
    """``(x, y, z, w)`` of a ROS quaternion, normalised; refused when not finite or when its length
    is off 1 by more than :data:`QUATERNION_TOLERANCE`."""
    x, y, z, w = (_number(getattr(q, c, math.nan)) for c in ("x", "y", "z", "w"))
    n = math.sqrt(x * x + y * y + z * z + w * w)
    if not math.isfinite(n):
        raise place.error(f"quaternion ({x}, {y}, {z}, {w}) is not finite", field)
    if abs(n - 1.0) > QUATERNION_TOLERANCE:
        raise place.error(
            f"quaternion ({x:.6g}, {y:.6g}, {z:.6g}, {w:.6g}) has length {n:.6g}; a rotation's is 1 "
            f"(lengths within {QUATERNION_TOLERANCE} of 1 are normalised, others refused)",
            field,
        )
    if abs(n - 1.0) <= _EXACT:
        return x, y, z, w
    return x / n, y / n, z / n, w / n


def check_translation(v: Any, place: MessagePlace, field: str) -> tuple[float, float, float]:
    """``(x, y, z)`` of a ROS point or vector, refused when not finite."""
    x, y, z = (_number(getattr(v, c, math.nan)) for c in ("x", "y", "z"))
    if not (math.isfinite(x) and math.isfinite(y) and math.isfinite(z)):
        raise place.error(f"({x}, {y}, {z}) is not finite", field)
    return x, y, z
