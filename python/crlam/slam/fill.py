"""Poses for the scans a SLAM filter skips.

With update triggers (``linear_update``, ``angular_update``) a filter processes only some scans;
every other scan still gets a pose in the recorded trajectories. Two rules:

``odometry``
    The estimate of the last processed scan k composed with the raw-odometry increment since k:
    the estimate as it stands online while that scan is the latest.
``interpolate``
    The same, plus a share of the correction that the next processed scan's estimate makes to
    the odometry's prediction of it. The correction is what the filter learned about the
    odometry's error over the whole segment; the share of scan i is how far the robot has come
    from k towards the next update as the triggers measure motion, max(travelled /
    ``linear_update``, turned / ``angular_update``) with the path length and rotation summed
    per raw step, divided by the same at the next processed scan. This needs that scan, so the
    pose is available at most one update later. The poses of processed scans are not changed,
    and scans after the last processed one get the odometry fill.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from crlam.errors import CrlamError
from crlam.pose import between, compose, wrap_angle

__all__ = ["FILLS", "fill_rule", "fill_skipped"]

#: The fill rules, the default first.
FILLS: tuple[str, ...] = ("interpolate", "odometry")


def fill_rule(fill: str) -> str:
    """One sentence stating the fill rule ``fill``, for metrics.json and run READMEs."""
    head = "every laser scan gets a pose: processed scans the filter's estimate, the others the estimate of the last "
    head += "processed scan composed with the raw-odometry increment since then"
    if fill == "odometry":
        return head
    if fill == "interpolate":
        return (
            head + ", plus the share of the next processed scan's correction to that odometry prediction reached so far "
            "(max of travelled / linear_update and turned / angular_update, over the same at the next processed scan); "
            "scans after the last processed one get no correction"
        )
    raise CrlamError(f"unknown fill rule {fill!r} (one of {', '.join(FILLS)})")


def fill_skipped(
    path: NDArray[np.float64],
    processed: NDArray[np.bool_],
    odometry: NDArray[np.float64],
    stamps: NDArray[np.float64],
    fill: str,
    linear_update: float,
    angular_update: float,
) -> NDArray[np.float64]:
    """One pose per scan from one pose per processed scan.

    Parameters
    ----------
    path : ndarray, shape (m, 3)
        Pose (m, m, rad) of each processed scan, in scan order.
    processed : ndarray of bool, shape (n,)
        Which scans were processed; ``m`` of them, the first scan among them.
    odometry : ndarray, shape (n, 3)
        Raw odometry pose of every scan.
    stamps : ndarray, shape (n,)
        Scan times (s): the share falls back to elapsed time for a segment in which the
        odometry neither moved nor turned.
    fill : {"interpolate", "odometry"}
        The rule (module documentation).
    linear_update, angular_update : float
        The update triggers (m, rad) that decided which scans were processed.

    Returns
    -------
    ndarray, shape (n, 3)
    """
    if fill not in FILLS:
        raise CrlamError(f"unknown fill rule {fill!r} (one of {', '.join(FILLS)})")
    processed = np.asarray(processed, dtype=bool)
    n = processed.shape[0]
    index = np.flatnonzero(processed)
    if path.shape != (index.size, 3):
        raise CrlamError(f"{path.shape[0]} poses for {index.size} processed scans")
    if n == 0:
        return np.zeros((0, 3))
    if not processed[0]:
        raise CrlamError("the first scan must be processed")
    segment = np.cumsum(processed) - 1  # the last processed scan at or before each scan, as an index into path
    anchor = index[segment]
    filled = compose(path[segment], between(odometry[anchor], odometry))
    filled[index] = path
    if fill == "odometry" or index.size < 2:
        return filled

    # Progress since the anchor as the triggers measure it: path length and rotation summed per raw step.
    step = np.diff(odometry, axis=0)
    travelled = np.r_[0.0, np.cumsum(np.hypot(step[:, 0], step[:, 1]))]
    turned = np.r_[0.0, np.cumsum(np.abs(wrap_angle(step[:, 2])))]
    measures = [
        (total, threshold) for total, threshold in ((travelled, linear_update), (turned, angular_update)) if threshold > 0
    ]

    def progress(since: NDArray[np.intp], at: NDArray[np.intp]) -> NDArray[np.float64]:
        """How far the robot has come from scan ``since`` to scan ``at``, in trigger units."""
        out = np.zeros(at.shape)
        for total, threshold in measures:
            out = np.maximum(out, (total[at] - total[since]) / threshold)
        return out

    # Scans of the segments that end at a processed scan (the last segment has no end).
    inner = segment < index.size - 1
    k = segment[inner]
    start, end = index[k], index[k + 1]
    at = np.flatnonzero(inner)
    predicted = compose(path[k], between(odometry[start], odometry[end]))
    correction = path[k + 1] - predicted
    correction[:, 2] = wrap_angle(correction[:, 2])
    reach = progress(start, end)
    by_time = reach <= 0.0
    with np.errstate(divide="ignore", invalid="ignore"):
        share = np.where(by_time, (stamps[at] - stamps[start]) / (stamps[end] - stamps[start]), progress(start, at) / reach)
    share = np.clip(np.nan_to_num(share, nan=0.0, posinf=0.0), 0.0, 1.0)
    out = filled.copy()
    out[inner, :2] += share[:, None] * correction[:, :2]
    out[inner, 2] = wrap_angle(out[inner, 2] + share * correction[:, 2])
    out[index] = path  # a processed scan keeps its own estimate (its share is 0 up to rounding)
    return out
