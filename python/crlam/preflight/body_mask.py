"""Beams that read the robot's own body, found from the scans themselves.

A laser mounted among the robot's parts (posts, a bumper, a cable) reads the same short range at
the same bearings scan after scan, whatever the robot does. Mapped, each such reading paints an
obstacle that travels with the robot and a trail of them along its path; weighed, it matches
every pose equally and flattens the weights.

Rule
----
Over scans taken while the robot moves (:func:`find_body_beams`'s caller picks them), a beam is
a body beam when

* it returned a reading shorter than :data:`BODY_RANGE` (0.5 m) in at least
  :data:`BODY_SHARE` (80 %) of the scans, and
* those readings stay within :data:`BODY_SPREAD` (5 cm: from the 5th to the 95th percentile).

The world around a moving robot does not stay within 5 cm at one bearing for most of a drive, so
the rule needs motion: it is applied only when the scans cover at least :data:`MIN_TRAVEL` (1 m)
of travel or :data:`MIN_TURN` (90 deg) of turning, and only to at least :data:`MIN_SCANS` scans;
otherwise nothing is masked and the result says why.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import NDArray

__all__ = ["BODY_RANGE", "BODY_SHARE", "BODY_SPREAD", "BodyMask", "find_body_beams"]

BODY_RANGE = 0.5
BODY_SHARE = 0.8
BODY_SPREAD = 0.05
MIN_TRAVEL = 1.0
MIN_TURN = math.pi / 2
MIN_SCANS = 30


@dataclass
class BodyMask:
    """The beams found on the robot's body.

    Attributes
    ----------
    mask : ndarray of bool, shape (n,) or None
        True for a body beam (beam order of the scans as read); None when nothing was decided.
    decided : bool
        Whether the rule could be applied (enough scans and motion).
    reason : str
        What was found, or why nothing was decided.
    ranges : ndarray, shape (k,)
        Median reading (m) of each masked beam, in beam order.
    bearings : ndarray, shape (k,)
        Bearing (rad, laser frame as read) of each masked beam.
    """

    mask: NDArray[np.bool_] | None
    decided: bool
    reason: str
    ranges: NDArray[np.float64] = field(default_factory=lambda: np.zeros(0))
    bearings: NDArray[np.float64] = field(default_factory=lambda: np.zeros(0))

    @property
    def n_masked(self) -> int:
        return 0 if self.mask is None else int(self.mask.sum())

    def record(self) -> dict[str, Any]:
        """What metrics.json records."""
        return {
            "decided": self.decided,
            "reason": self.reason,
            "n_masked": self.n_masked,
            "n_beams": None if self.mask is None else int(self.mask.size),
            "beams": [] if self.mask is None else [int(i) for i in np.flatnonzero(self.mask)],
            "bearings_deg": [round(math.degrees(float(b)), 3) for b in self.bearings],
            "ranges_m": [round(float(r), 4) for r in self.ranges],
            "rule": f"returned below {BODY_RANGE} m in >= {BODY_SHARE:.0%} of the scans, spread <= {BODY_SPREAD} m",
        }


def find_body_beams(
    ranges: Sequence[NDArray[np.float64]],
    max_ranges: Sequence[float],
    odometry: NDArray[np.float64],
    bearings: NDArray[np.float64],
) -> BodyMask:
    """Applies the module's rule.

    Parameters
    ----------
    ranges : sequence of ndarray, each shape (n,)
        The scans' readings (m), all of ``n`` beams, in log order.
    max_ranges : sequence of float
        Each scan's stated maximum (m): readings at or above it are no-returns.
    odometry : ndarray, shape (m, 3)
        The robot's odometry pose at each scan (m, m, rad).
    bearings : ndarray, shape (n,)
        The beams' bearings (rad).
    """
    if len(ranges) < MIN_SCANS:
        return BodyMask(None, False, f"only {len(ranges)} scans with motion (needs {MIN_SCANS})")
    n = len(ranges[0])
    if any(len(r) != n for r in ranges):
        return BodyMask(None, False, "the scans differ in beam count")
    odo = np.asarray(odometry, dtype=np.float64)
    travel = float(np.hypot(*np.diff(odo[:, :2], axis=0).T).sum())
    turn = float(np.abs(np.angle(np.exp(1j * np.diff(odo[:, 2])))).sum())
    if travel < MIN_TRAVEL and turn < MIN_TURN:
        return BodyMask(
            None, False, f"the robot moved {travel:.2f} m and turned {math.degrees(turn):.0f} deg: too little to tell"
        )
    r = np.vstack([np.asarray(x, dtype=np.float64) for x in ranges])  # (m, n)
    maxes = np.asarray(max_ranges, dtype=np.float64)[:, None]
    returned = np.isfinite(r) & (r > 0) & (r < maxes)
    short = returned & (r < BODY_RANGE)
    share = short.mean(axis=0)
    mask = np.zeros(n, dtype=bool)
    medians = np.zeros(n)
    for b in np.flatnonzero(share >= BODY_SHARE):
        vals = r[short[:, b], b]
        lo, hi = np.percentile(vals, [5.0, 95.0])
        if hi - lo <= BODY_SPREAD:
            mask[b] = True
            medians[b] = float(np.median(vals))
    k = int(mask.sum())
    reason = (
        f"{k} of {n} beams read the robot's body ({len(ranges)} scans, {travel:.1f} m, {math.degrees(turn):.0f} deg)"
        if k
        else f"no body beams ({len(ranges)} scans, {travel:.1f} m, {math.degrees(turn):.0f} deg)"
    )
    return BodyMask(mask, True, reason, medians[mask], np.asarray(bearings, dtype=np.float64)[mask])
