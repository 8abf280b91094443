"""A laser scan with the sensor pose it was taken from: what known-pose mapping and the
likelihood diagnostics read (built by :func:`crlam.experiments.known_poses.known_pose_scans`)."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

__all__ = ["KnownPoseScan"]


@dataclass(frozen=True)
class KnownPoseScan:
    """A scan ready for mapping: sensor pose (3,), beam angles (n,), ranges (n,), stamp (s)."""

    pose: NDArray[np.float64]
    angles: NDArray[np.float64]
    ranges: NDArray[np.float64]
    timestamp: float
