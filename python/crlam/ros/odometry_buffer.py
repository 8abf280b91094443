"""Laser scans matched with odometry as they arrive, by the offline bag reader's rule.

A scan takes the odometry pose interpolated at its stamp between the two odometry readings
around it (:mod:`crlam.io.rosbag`'s rule, so that a live run sees the same poses as
``crlam slam`` on the recorded bag); it waits until an odometry reading at or after its stamp
has arrived, or until ``resolve_all`` (the end, a save) or ``max_wait`` wall seconds, after
which the newest reading is used when it is within ``tolerance`` s. Scans before the first
odometry (by more than ``tolerance``) or after the last one are dropped and counted.

A live robot's odometry often arrives later than the scan it should be matched with (the
TurtleBot 4 bag's odometry messages arrive 50-316 ms after their stamps, so a scan waits 90 ms
for its reading at the median and 275 ms at the 99th percentile, longer than the 130 ms between
two scans). With ``max_extrapolation`` > 0 a scan stamped at most that long after the newest
reading does not wait: its odometry is the newest reading moved on at the odometry's own
velocity (the increment over the last ``VELOCITY_WINDOW`` s of readings, scaled to the scan's
stamp: constant linear and angular velocity in the robot's frame). At a ground robot's
accelerations (1 m/s^2, 3 rad/s^2) that errs by at most 2 cm and 3.4 deg over 0.2 s, inside
the scan match's search; the filter's motion noise covers the increment it changes. 0 waits as
``crlam slam`` reads a recorded bag (a replay that must equal the offline run).
"""

from __future__ import annotations

import math
from bisect import bisect_left
from collections import deque
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from crlam.io.rosbag_tf import wrap
from crlam.pose import between, compose

__all__ = ["OdometryBuffer", "PendingScan"]

_HISTORY = 4096
#: Seconds of odometry readings the extrapolation's velocity is measured over: at least one
#: period of a 20 Hz odometry, short enough to follow a turn's start.
VELOCITY_WINDOW = 0.1


@dataclass
class PendingScan:
    """A scan waiting for its odometry: its stamp (s), arrival (wall s) and whatever the caller keeps."""

    stamp: float
    arrival: float
    payload: object
    odom: NDArray[np.float64] | None = None


class OdometryBuffer:
    """Odometry history and the scans waiting for it (not thread safe: one caller)."""

    def __init__(self, tolerance: float = 0.25, max_wait: float = 0.5, max_extrapolation: float = 0.0) -> None:
        self.tolerance = tolerance
        self.max_wait = max_wait
        self.max_extrapolation = max_extrapolation
        #: Scans whose odometry was extrapolated past the newest reading.
        self.extrapolated = 0
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

    def _extrapolated(self, t: float) -> NDArray[np.float64]:
        """The newest reading moved on to ``t`` at the velocity of the last ``VELOCITY_WINDOW`` s."""
        t1, p1 = self.t[-1], self.p[-1]
        k = len(self.t) - 2
        while k > 0 and t1 - self.t[k] < VELOCITY_WINDOW:
            k -= 1
        t0, p0 = self.t[k], self.p[k]
        if t1 - t0 < 0.5 * VELOCITY_WINDOW:
            # Too short a history to tell a velocity (two readings a millisecond apart would
            # scale their increment a hundredfold): the newest reading as it is.
            return np.array(p1, dtype=np.float64)
        # The increment p0 -> p1 in p0's frame, scaled to the time ahead, applied in p1's frame.
        step = between(p0, p1) * ((t - t1) / (t1 - t0))
        return np.asarray(compose(p1, step), dtype=np.float64)

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
                ahead = scan.stamp - self.t[-1]
                if not (final or waited) and ahead <= self.max_extrapolation and len(self.t) >= 2:
                    self.pending.popleft()
                    scan.odom = self._extrapolated(scan.stamp)
                    self.extrapolated += 1
                    out.append(scan)
                    continue
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
