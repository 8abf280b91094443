"""The map's reach z_max chosen from the log's own readings (``SlamConfig.map_range = "readings"``).

The paper maps to 8 m. Indoors that holds most of a scan (Intel, ACES: 92-94 % of the returns lie
within 8 m), but outdoors, in halls and in wide corridors most returns lie farther: on a campus
only 29 % do. The particles' maps then hold little beyond the robot's feet, the scan match has
few walls to match, and the filter can end much farther from the truth than its odometry. The
rule: the map reaches as far as :data:`READINGS_SHARE` of the returns of the log's first
:data:`SAMPLE_SCANS` scans, rounded up to a whole metre, never below the configured ``max_range``
(the paper's 8 m in every preset) and never above :data:`MAX_READINGS_RANGE` (map memory and the
cost of a map update grow with it). A return is a finite reading above 0 and below the scan's
sensor maximum; no-returns do not count.
"""

from __future__ import annotations

import math
from collections.abc import Iterable
from dataclasses import dataclass
from typing import Any

import numpy as np

from crlam.io.carmen import LaserScan

__all__ = ["MAP_RANGES", "MAX_READINGS_RANGE", "READINGS_SHARE", "SAMPLE_SCANS", "MapRangeChoice", "map_range_from_readings"]

#: ``fixed``: z_max is ``max_range``; ``readings``: chosen from the log (see the module docstring).
MAP_RANGES = ("fixed", "readings")
#: Share of the returns the map must reach.
READINGS_SHARE = 0.9
#: Largest z_max the rule chooses (m).
MAX_READINGS_RANGE = 20.0
#: Scans read to choose it.
SAMPLE_SCANS = 2000


@dataclass(frozen=True)
class MapRangeChoice:
    """The z_max the rule chose, and what it was chosen from.

    Attributes
    ----------
    max_range : float
        The chosen z_max (m).
    share_range : float or None
        The range (m) within which :data:`READINGS_SHARE` of the returns lie (None without returns).
    floor : float
        The configured ``max_range`` (m), the smallest z_max the rule chooses.
    n_scans, n_returns : int
        Scans read and returns among their readings.
    """

    max_range: float
    share_range: float | None
    floor: float
    n_scans: int
    n_returns: int

    def to_dict(self) -> dict[str, Any]:
        """What ``metrics.json`` records (``map_range``)."""
        return {
            "rule": f"returns within reach: {READINGS_SHARE:.0%} of the returns of the first {SAMPLE_SCANS} scans, "
            f"rounded up to a metre, between max_range and {MAX_READINGS_RANGE:g} m",
            "max_range_m": self.max_range,
            "share_range_m": self.share_range,
            "floor_m": self.floor,
            "n_scans": self.n_scans,
            "n_returns": self.n_returns,
        }


def map_range_from_readings(records: Iterable[object], floor: float, *, max_scans: int | None = None) -> MapRangeChoice:
    """The z_max of the rule in the module docstring for a log.

    Parameters
    ----------
    records : iterable
        The log's records (:func:`crlam.io.logs.open_log`); laser scans are used, others skipped.
    floor : float
        The configured ``max_range`` (m): the rule never chooses less.
    max_scans : int, optional
        Read at most this many scans (the run's own limit), and at most :data:`SAMPLE_SCANS`.
    """
    limit = SAMPLE_SCANS if max_scans is None else min(SAMPLE_SCANS, max_scans)
    returns: list[np.ndarray] = []
    n_scans = 0
    for rec in records:
        if n_scans >= limit:
            break
        if not isinstance(rec, LaserScan):
            continue
        n_scans += 1
        r = np.asarray(rec.ranges, dtype=np.float64)
        returns.append(r[np.isfinite(r) & (r > 0) & (r < rec.max_range)])
    values = np.concatenate(returns) if returns else np.empty(0)
    if values.size == 0:
        return MapRangeChoice(float(floor), None, float(floor), n_scans, 0)
    share_range = float(np.quantile(values, READINGS_SHARE))
    chosen = min(max(float(floor), float(math.ceil(share_range))), max(float(floor), MAX_READINGS_RANGE))
    return MapRangeChoice(chosen, share_range, float(floor), n_scans, int(values.size))
