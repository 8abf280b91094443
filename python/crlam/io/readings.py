"""What a scan's non-readings become before they reach a filter: the no-return policy.

Kinds of non-reading
--------------------
A laser reports "no range measured" in several ways. The readers turn each into the scan's
stated maximum range ``max_range`` (a :class:`~crlam.io.carmen_types.LaserScan` has one range
per bearing, so a reading cannot be left out there) and count each kind:

=========================  ======================================  ==============================
reading                    where                                   counted as
=========================  ======================================  ==============================
``+inf``                   ROS ``LaserScan`` (REP 117: no return)  ``n_inf_ranges``
at or above ``range_max``  ROS ``range_max``; ROBOTLASER1's         ``n_above_max_ranges`` (above)
                           maximum; FLASER: 81 m (none stated)
``NaN``                    ROS (REP 117: invalid), CARMEN           ``n_nan_ranges`` /
                                                                   ``n_nonfinite_ranges``
``0``, negative, ``-inf``  drivers that write 0 for "no echo"      ``n_nonpositive_ranges``
below ``range_min``        ROS ``range_min`` (too close to see)    ``n_below_min_ranges``
=========================  ======================================  ==============================

Every one of them is a *no-return* here: the beam gives no distance at which it met something.
On top of those, beyond the filter's ``z_max``, a reading within
:data:`FIXED_NO_RETURN_TOLERANCE` (5 cm) of the largest reading of the log so far is a no-return
as well: a laser that reports "nothing seen" as one fixed value, its configured maximum, below
the maximum the log states (ACES: 50.00 m, while FLASER states none) — the rule the ``robust``
preset's scan matcher already applies (``match_range = "full"``).

Policy (``SlamConfig.no_return``)
---------------------------------
``"drop"`` (preset ``robust``)
    A no-return is left out of the scan: it neither updates the map nor weighs a particle. The
    rule: a missing echo says nothing about where the beam ended. It happens on dark, glossy or
    glass walls, at grazing angles and in the sensor's blind sectors as well as in open space,
    so clearing along it (to any length) can erase a wall that other scans hit; only beams that
    returned clear free space. A no-return therefore never lowers any cell's occupancy.
``"z_max"`` (preset ``paper``, crm-spec 2.1)
    A no-return is the atom ``z = z_max`` of the sensor model: the ``∞`` cause; the cells along
    the beam up to ``z_max`` are updated as seen free. With a lidar that reports 30 % of its
    beams as ``inf`` indoors this paints free space through walls.

Readings that returned at or beyond ``z_max`` (but below the sensor's maximum and not the log's
fixed no-return value) are real echoes in both policies: the beam crossed ``z_max`` freely, so
the map is updated as free to ``z_max`` (the ``∞`` cause), as crm-spec 2.1 states.

Beams masked as hits on the robot's own body (:mod:`crlam.preflight.body_mask`) are left out in both
policies.
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray

from crlam.errors import ConfigError

__all__ = [
    "FIXED_NO_RETURN_TOLERANCE",
    "NO_RETURN_POLICIES",
    "ReadingFilter",
    "ReadingStats",
    "check_no_return_policy",
]

#: Values of ``SlamConfig.no_return``.
NO_RETURN_POLICIES = ("drop", "z_max")
#: Beyond z_max, readings within this distance (m) of the log's largest reading so far are a
#: laser's fixed "nothing seen" value.
FIXED_NO_RETURN_TOLERANCE = 0.05


def check_no_return_policy(value: object) -> str:
    """``value`` if it is one of :data:`NO_RETURN_POLICIES`, else a :class:`ConfigError`."""
    if value not in NO_RETURN_POLICIES:
        raise ConfigError(f"no_return: must be one of {NO_RETURN_POLICIES} (got {value!r})")
    return str(value)


@dataclass
class ReadingStats:
    """Beams seen by a :class:`ReadingFilter` (summed over scans).

    Attributes
    ----------
    n_beams : int
        Every beam of every scan.
    n_no_return : int
        No-returns: non-readings of any kind (at or above the scan's ``max_range``, non-finite,
        non-positive) and, beyond z_max, the log's fixed no-return value.
    n_fixed_value_no_return : int
        Of those, the readings taken for the log's fixed no-return value (below ``max_range``).
    n_no_return_dropped, n_no_return_z_max : int
        No-returns left out (``drop``) or passed to the filter as the z_max atom (``z_max``).
    n_body_masked : int
        Beams left out as hits on the robot's body (:mod:`crlam.preflight.body_mask`).
    n_used : int
        Beams passed to the filter.
    """

    n_beams: int = 0
    n_no_return: int = 0
    n_fixed_value_no_return: int = 0
    n_no_return_dropped: int = 0
    n_no_return_z_max: int = 0
    n_body_masked: int = 0
    n_used: int = 0

    def to_dict(self) -> dict[str, Any]:
        return asdict(self)


class ReadingFilter:
    """Applies the no-return policy and a body mask to each scan, in log order.

    Parameters
    ----------
    policy : str
        ``"drop"`` or ``"z_max"`` (module docstring).
    z_max : float
        The filter's z_max (m): the fixed no-return value is only looked for beyond it.
    body_mask : ndarray of bool, shape (n,), optional
        True for the beams to leave out (hits on the robot's body); applied to scans of ``n``
        beams (a scan of another length is left unmasked).
    """

    def __init__(self, policy: str, z_max: float, body_mask: NDArray[np.bool_] | None = None) -> None:
        self.policy = check_no_return_policy(policy)
        if not (math.isfinite(z_max) and z_max > 0):
            raise ConfigError(f"z_max must be a finite number > 0 (got {z_max!r})")
        self.z_max = float(z_max)
        self.body_mask = None if body_mask is None else np.asarray(body_mask, dtype=bool)
        self.stats = ReadingStats()
        #: The largest reading below a scan's max_range seen so far (m).
        self._largest = 0.0

    def no_returns(self, ranges: NDArray[np.float64], max_range: float) -> NDArray[np.bool_]:
        """True for the no-returns of a scan's ``ranges`` (n,) whose stated maximum is
        ``max_range`` (m); updates the log's largest reading (call once per scan, in order)."""
        r = np.asarray(ranges, dtype=np.float64)
        bad = ~np.isfinite(r) | (r <= 0.0) | (r >= max_range)
        returned = r[~bad]
        if returned.size:
            self._largest = max(self._largest, float(returned.max()))
        fixed = ~bad & (r > self.z_max) & (r >= self._largest - FIXED_NO_RETURN_TOLERANCE)
        self.stats.n_fixed_value_no_return += int(fixed.sum())
        return bad | fixed

    def apply(
        self, angles: NDArray[np.float64], ranges: NDArray[np.float64], max_range: float
    ) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """(bearings, ranges) for the filter: no-returns left out (``drop``) or as ``inf``
        (``z_max``: the filter's z_max atom), body beams left out."""
        angles = np.asarray(angles, dtype=np.float64)
        r = np.asarray(ranges, dtype=np.float64)
        no_return = self.no_returns(r, max_range)
        keep = np.ones(r.shape, dtype=bool)
        st = self.stats
        if self.body_mask is not None and self.body_mask.shape == r.shape:
            keep &= ~self.body_mask
            st.n_body_masked += int(self.body_mask.sum())
        n_nr = int((no_return & keep).sum())
        st.n_beams += int(r.size)
        st.n_no_return += int(no_return.sum())
        if self.policy == "drop":
            keep &= ~no_return
            st.n_no_return_dropped += n_nr
            out = r[keep]
        else:
            st.n_no_return_z_max += n_nr
            out = np.where(no_return, np.inf, r)[keep]
        st.n_used += int(keep.sum())
        return angles[keep], out
