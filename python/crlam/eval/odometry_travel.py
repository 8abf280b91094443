"""How far the estimate travelled against how far the wheel odometry says the robot travelled.

A wheel odometry drifts in heading but measures the distance travelled to a few percent (the
default's estimates, seeds 0-2, travel 4-7 % less than the odometry on Intel, 2 % less on ACES,
within 2.2 % on the semi-real logs). A SLAM estimate that
moves much less (or more) than the odometry over straight stretches has compressed (or
stretched) the map along them: in a corridor whose walls look the same everywhere the filter can
be pulled back towards what it has mapped and map the corridor short (docs/method/rbpf-clam.md,
"Corridors"). This module measures the ratio; ``crlam slam`` reports it in ``metrics.json``
(``odometry_travel``) and warns on stderr when it is outside ``1 +- TRAVEL_TOLERANCE``.

The ratio: over consecutive windows of ``window`` scans, the forward displacement of the
odometry (the x component of its increment in the frame of the window's first pose) and the
estimate's forward displacement in the same direction; windows where the odometry moved less than
``min_forward_m`` forward (turns, standing still) are left out; the ratio is the sum of the
estimate's over the sum of the odometry's.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike

from crlam.pose import between

__all__ = ["TRAVEL_TOLERANCE", "OdometryTravel", "odometry_travel"]

#: Largest relative difference of the travelled distances that counts as agreement: twice the
#: largest difference between the estimate and the odometry on the real logs (Intel: 7 % with the scan
#: read in every direction, ``degeneracy = "off"``; 4-5 % with the default's remapping).
TRAVEL_TOLERANCE = 0.15
#: Scans per window.
WINDOW_SCANS = 50
#: Least forward travel (m) of the odometry for a window to count.
MIN_FORWARD_M = 1.0
#: Least straight travel (m) of the odometry over all windows for a verdict.
MIN_TOTAL_M = 10.0


@dataclass(frozen=True)
class OdometryTravel:
    """The estimate's travel against the odometry's (see the module documentation).

    Attributes
    ----------
    ratio : float or None
        The estimate's forward travel over the odometry's, on the windows that count; None when
        none does.
    odometry_m : float
        The odometry's forward travel over those windows (m).
    n_windows : int
        Windows that count.
    agrees : bool or None
        Whether ``ratio`` lies within ``1 +- TRAVEL_TOLERANCE``; None with less than
        ``MIN_TOTAL_M`` of straight travel.
    """

    ratio: float | None
    odometry_m: float
    n_windows: int
    agrees: bool | None

    def to_dict(self) -> dict[str, object]:
        return {
            "ratio": self.ratio,
            "odometry_m": self.odometry_m,
            "n_windows": self.n_windows,
            "agrees": self.agrees,
            "tolerance": TRAVEL_TOLERANCE,
            "window_scans": WINDOW_SCANS,
        }

    def warning(self) -> str | None:
        """What to tell the user when the travel disagrees (None when it agrees or cannot say)."""
        if self.agrees is not False or self.ratio is None:
            return None
        how = "less" if self.ratio < 1 else "more"
        return (
            f"crlam: WARNING: the estimate travelled {abs(1 - self.ratio):.0%} {how} than the wheel odometry over "
            f"{self.odometry_m:.0f} m of straight travel (ratio {self.ratio:.2f}); an odometry's distance is rarely off "
            f"by more than {TRAVEL_TOLERANCE:.0%}, so the map is probably {'compressed' if self.ratio < 1 else 'stretched'} "
            "along corridors (docs: RBPF-CLAM, Corridors; --match-climb posterior keeps closer to the odometry there)"
        )


def odometry_travel(
    estimate: ArrayLike, odometry: ArrayLike, *, window: int = WINDOW_SCANS, min_forward_m: float = MIN_FORWARD_M
) -> OdometryTravel:
    """The travel check of ``estimate`` against ``odometry``, both ``(n, 3)`` poses (x m, y m, θ rad),
    one per scan in the same order (any frames: only increments are compared)."""
    est = np.asarray(estimate, dtype=np.float64).reshape(-1, 3)
    odo = np.asarray(odometry, dtype=np.float64).reshape(-1, 3)
    if len(est) != len(odo):
        raise ValueError(f"{len(est)} estimated poses but {len(odo)} odometry poses")
    if window < 1:
        raise ValueError("window must be >= 1")
    seen = moved = 0.0
    n = 0
    for k in range(0, len(odo) - window, window):
        forward = between(odo[k], odo[k + window])[0]
        if abs(forward) < min_forward_m:
            continue
        seen += float(np.sign(forward) * between(est[k], est[k + window])[0])
        moved += float(abs(forward))
        n += 1
    ratio = float(seen / moved) if n else None
    agrees = None if ratio is None or moved < MIN_TOTAL_M else bool(abs(ratio - 1.0) <= TRAVEL_TOLERANCE)
    return OdometryTravel(ratio=ratio, odometry_m=float(moved), n_windows=n, agrees=agrees)
