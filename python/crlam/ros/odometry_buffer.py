"""Laser scans matched with odometry as they arrive, by the offline bag reader's rule.

A scan takes the odometry pose interpolated at its stamp between the two odometry readings
around it (:mod:`crlam.io.rosbag`'s rule, so that a live run sees the same poses as
``crlam slam`` on the recorded bag); it waits until an odometry reading at or after its stamp
has arrived, or until ``resolve_all`` (the end, a save) or ``max_wait`` wall seconds, after
which the newest reading is used when it is within ``tolerance`` s. Scans before the first
odometry (by more than ``tolerance``) or after the last one are dropped and counted.
"""

from __future__ import annotations

import math
from bisect import bisect_left
from collections import deque
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from crlam.io.rosbag_tf import wrap

__all__ = ["OdometryBuffer", "PendingScan"]

_HISTORY = 4096


@dataclass
class PendingScan:
    """A scan waiting for its odometry: its stamp (s), arrival (wall s) and whatever the caller keeps."""

    stamp: float
    arrival: float
    payload: object
    odom: NDArray[np.float64] | None = None


class OdometryBuffer:
    """Odometry history and the scans waiting for it (not thread safe: one caller)."""

    def __init__(self, tolerance: float = 0.25, max_wait: float = 0.5) -> None:
        self.tolerance = tolerance
        self.max_wait = max_wait
        self.t: deque[float] = deque(maxlen=_HISTORY)
        self.p: deque[NDArray[np.float64]] = deque(maxlen=_HISTORY)
        self.pending: deque[PendingScan] = deque()
        self.skipped_before = 0
        self.skipped_after = 0

    def add_odometry(self, t: float, pose: NDArray[np.float64]) -> None:
        """One odometry reading (stamp s, pose x y theta); out-of-order ones are put in place."""
        if self.t and t < self.t[-1]:
            ts = list(self.t)
            k = bisect_left(ts, t)
            if len(self.t) == self.t.maxlen:
                self.t.popleft()
                self.p.popleft()
                k = max(k - 1, 0)
            self.t.insert(k, t)
            self.p.insert(k, pose)
        else:
            self.t.append(t)
            self.p.append(pose)

    def add_scan(self, scan: PendingScan) -> None:
        self.pending.append(scan)

    def _pose_at(self, t: float) -> NDArray[np.float64] | None:
        ts = list(self.t)
        k = bisect_left(ts, t)
        if k < len(ts) and ts[k] == t:
            return self.p[k]
        if k == 0:
            if ts[0] - t > self.tolerance:
                self.skipped_before += 1
                return None
            return self.p[0]
        if k == len(ts):
            return self.p[-1]
        t0, t1 = ts[k - 1], ts[k]
        p0, p1 = self.p[k - 1], self.p[k]
        a = (t - t0) / (t1 - t0) if t1 > t0 else 0.0
        return np.array([p0[0] + a * (p1[0] - p0[0]), p0[1] + a * (p1[1] - p0[1]), wrap(p0[2] + a * wrap(p1[2] - p0[2]))])

    def resolved(self, now: float = -math.inf, final: bool = False) -> list[PendingScan]:
        """The scans that can now be matched (in arrival order), with ``odom`` set; ``now`` is the
        wall time (s) for ``max_wait``; ``final`` resolves every scan that can be."""
        out: list[PendingScan] = []
        while self.pending:
            scan = self.pending[0]
            waited = now - scan.arrival > self.max_wait
            if not self.t:
                if not (final or waited):
                    break
                self.skipped_before += 1
                self.pending.popleft()
                continue
            if scan.stamp > self.t[-1]:
                if not (final or waited):
                    break
                if scan.stamp - self.t[-1] > self.tolerance:
                    self.skipped_after += 1
                    self.pending.popleft()
                    continue
            self.pending.popleft()
            pose = self._pose_at(scan.stamp)
            if pose is not None:
                scan.odom = np.array(pose, dtype=np.float64)
                out.append(scan)
        return out
