"""Rigid alignment of a planar trajectory to a reference, and the absolute pose error (APE).

:func:`align_se2` is the closed-form least-squares rigid motion between matched positions
(Umeyama 1991 without scale, in the plane): the rotation angle and translation that minimise
``sum_i |R(theta) p_i + t - q_i|^2``. For planar trajectories (z = 0) it is the alignment that
``evo_ape --align`` computes in 3-D, so :func:`ape_statistics` of the aligned errors gives evo's
translation-part APE numbers (RMSE, mean, median, std with ddof = 0, min, max).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from crlam.errors import DataFormatError
from crlam.pose import wrap_angle

__all__ = ["Se2Alignment", "align_se2", "ape_statistics"]

FloatArray = NDArray[np.float64]


@dataclass(frozen=True)
class Se2Alignment:
    """A planar rigid motion ``p -> R(theta) p + t``.

    Attributes
    ----------
    theta : float
        Rotation (rad).
    tx, ty : float
        Translation (m).
    """

    theta: float
    tx: float
    ty: float

    def apply(self, poses: ArrayLike) -> FloatArray:
        """``poses`` (n, 3) ``(x, y, theta)`` moved by this motion: positions rotated and
        translated, headings rotated (wrapped to [-pi, pi))."""
        p = np.asarray(poses, dtype=np.float64).reshape(-1, 3)
        c, s = math.cos(self.theta), math.sin(self.theta)
        out = np.empty_like(p)
        out[:, 0] = c * p[:, 0] - s * p[:, 1] + self.tx
        out[:, 1] = s * p[:, 0] + c * p[:, 1] + self.ty
        out[:, 2] = wrap_angle(p[:, 2] + self.theta)
        return out

    def to_dict(self) -> dict[str, float]:
        return {"theta_rad": self.theta, "tx_m": self.tx, "ty_m": self.ty}


def align_se2(source_xy: ArrayLike, target_xy: ArrayLike) -> Se2Alignment:
    """The rigid motion that best maps ``source_xy`` onto ``target_xy`` in least squares.

    Parameters
    ----------
    source_xy, target_xy : array_like, shape (n, 2)
        Matched positions (m): the estimate's and the reference's at the same stamps.

    Returns
    -------
    Se2Alignment
        ``theta = atan2(sum(a_x b_y - a_y b_x), sum(a_x b_x + a_y b_y))`` over the centred
        points ``a`` (source) and ``b`` (target), ``t = mean(b) - R(theta) mean(a)``.

    Raises
    ------
    DataFormatError
        With fewer than two matched positions, or all of them at one point (no rotation is defined).
    """
    a = np.asarray(source_xy, dtype=np.float64).reshape(-1, 2)
    b = np.asarray(target_xy, dtype=np.float64).reshape(-1, 2)
    if a.shape != b.shape or a.shape[0] < 2:
        raise DataFormatError(f"SE(2) alignment needs at least two matched positions, got {a.shape[0]} and {b.shape[0]}")
    ma, mb = a.mean(axis=0), b.mean(axis=0)
    ac, bc = a - ma, b - mb
    cross = float(np.sum(ac[:, 0] * bc[:, 1] - ac[:, 1] * bc[:, 0]))
    dot = float(np.sum(ac[:, 0] * bc[:, 0] + ac[:, 1] * bc[:, 1]))
    if cross == 0.0 and dot == 0.0:
        raise DataFormatError("SE(2) alignment is undefined: the matched positions do not spread out")
    theta = math.atan2(cross, dot)
    c, s = math.cos(theta), math.sin(theta)
    return Se2Alignment(theta, float(mb[0] - (c * ma[0] - s * ma[1])), float(mb[1] - (s * ma[0] + c * ma[1])))


def ape_statistics(position_errors: ArrayLike) -> dict[str, float]:
    """evo's APE statistics of the translation part.

    Parameters
    ----------
    position_errors : array_like, shape (n, 2)
        ``(dx, dy)`` of each matched pose (m).

    Returns
    -------
    dict
        ``ape_rmse_m``, ``ape_mean_m``, ``ape_median_m``, ``ape_std_m`` (population std, as evo),
        ``ape_min_m``, ``ape_max_m`` of the error norms ``sqrt(dx^2 + dy^2)``.
    """
    d = np.asarray(position_errors, dtype=np.float64).reshape(-1, 2)
    e = np.hypot(d[:, 0], d[:, 1])
    if e.size == 0:
        raise DataFormatError("no matched poses to compute the APE of")
    return {
        "ape_rmse_m": float(np.sqrt(np.mean(e**2))),
        "ape_mean_m": float(np.mean(e)),
        "ape_median_m": float(np.median(e)),
        "ape_std_m": float(np.std(e)),
        "ape_min_m": float(np.min(e)),
        "ape_max_m": float(np.max(e)),
    }
