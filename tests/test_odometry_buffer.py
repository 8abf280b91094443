"""The live nodes' odometry buffer (:mod:`crlam.ros.odometry_buffer`): scans wait for the odometry
reading after their stamp and take the interpolation (the offline bag reader's rule), or, with
``max_extrapolation``, go at once with the newest reading moved on at the odometry's velocity."""

from __future__ import annotations

import math

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from crlam.ros.odometry_buffer import OdometryBuffer, PendingScan


def _arc(t: float, v: float, w: float) -> np.ndarray:
    """Pose at ``t`` of a robot leaving the origin at speed ``v`` (m/s) and turn rate ``w`` (rad/s)."""
    if abs(w) < 1e-12:
        return np.array([v * t, 0.0, 0.0])
    return np.array([v / w * math.sin(w * t), v / w * (1.0 - math.cos(w * t)), math.remainder(w * t, 2 * math.pi)])


def _feed(buffer: OdometryBuffer, v: float, w: float, until: float, rate: float = 20.0) -> None:
    for k in range(int(until * rate) + 1):
        buffer.add_odometry(k / rate, _arc(k / rate, v, w))


def test_waiting_takes_the_interpolation_of_the_readings_around_the_scan() -> None:
    buffer = OdometryBuffer()  # no extrapolation: the offline reader's rule
    _feed(buffer, 0.5, 0.0, 1.0)
    buffer.add_scan(PendingScan(1.02, arrival=0.0, payload=None))
    assert buffer.resolved(now=0.1) == []  # waits for the reading after 1.02 s
    buffer.add_odometry(1.05, _arc(1.05, 0.5, 0.0))
    (scan,) = buffer.resolved(now=0.1)
    np.testing.assert_allclose(scan.odom, [0.51, 0.0, 0.0], atol=1e-12)
    assert buffer.extrapolated == 0


def test_extrapolation_follows_a_turning_robot() -> None:
    buffer = OdometryBuffer(max_extrapolation=0.2)
    v, w = 0.4, 0.8
    _feed(buffer, v, w, 2.0)
    buffer.add_scan(PendingScan(2.08, arrival=0.0, payload=None))
    (scan,) = buffer.resolved(now=0.0)  # at once, not waiting
    truth = _arc(2.08, v, w)
    assert math.hypot(*(scan.odom[:2] - truth[:2])) < 5e-4  # the chord scaled along the arc
    assert abs(math.remainder(scan.odom[2] - truth[2], 2 * math.pi)) < 1e-9
    # Holding the newest reading instead (what a scan that waited too long gets) is 3 cm off.
    assert math.hypot(*(_arc(2.0, v, w)[:2] - truth[:2])) > 0.03
    assert buffer.extrapolated == 1


def test_a_scan_further_ahead_than_the_limit_waits() -> None:
    buffer = OdometryBuffer(max_extrapolation=0.2)
    _feed(buffer, 0.5, 0.1, 1.0)
    buffer.add_scan(PendingScan(1.3, arrival=0.0, payload=None))
    assert buffer.resolved(now=0.1) == []
    buffer.add_odometry(1.15, _arc(1.15, 0.5, 0.1))  # now within 0.2 s of the newest reading
    (scan,) = buffer.resolved(now=0.1)
    assert math.hypot(*(scan.odom[:2] - _arc(1.3, 0.5, 0.1)[:2])) < 1e-4
    assert buffer.extrapolated == 1


def test_scans_inside_the_readings_are_interpolated_not_extrapolated() -> None:
    buffer = OdometryBuffer(max_extrapolation=0.2)
    _feed(buffer, 0.5, 0.3, 1.0)
    buffer.add_scan(PendingScan(0.52, arrival=0.0, payload=None))
    (scan,) = buffer.resolved(now=0.0)
    assert buffer.extrapolated == 0
    assert math.hypot(*(scan.odom[:2] - _arc(0.52, 0.5, 0.3)[:2])) < 1e-4


@settings(max_examples=60, deadline=None)
@given(
    x=st.floats(-50, 50),
    y=st.floats(-50, 50),
    heading=st.floats(-math.pi, math.pi),
    speed=st.floats(-1.0, 1.0),
    ahead=st.floats(0.0, 0.2),
)
def test_straight_motion_is_extrapolated_exactly(x: float, y: float, heading: float, speed: float, ahead: float) -> None:
    buffer = OdometryBuffer(max_extrapolation=0.2)
    c, s = math.cos(heading), math.sin(heading)
    for k in range(10):
        t = 0.05 * k
        buffer.add_odometry(t, np.array([x + c * speed * t, y + s * speed * t, heading]))
    t = 0.45 + ahead
    buffer.add_scan(PendingScan(t, arrival=0.0, payload=None))
    (scan,) = buffer.resolved(now=0.0)
    np.testing.assert_allclose(scan.odom[:2], [x + c * speed * t, y + s * speed * t], atol=1e-9)
    assert abs(math.remainder(scan.odom[2] - heading, 2 * math.pi)) < 1e-12


def test_too_short_a_history_holds_the_newest_reading() -> None:
    buffer = OdometryBuffer(max_extrapolation=0.2)
    buffer.add_odometry(1.000, np.array([0.0, 0.0, 0.0]))
    buffer.add_odometry(1.001, np.array([0.01, 0.0, 0.0]))  # a burst: no velocity to read
    buffer.add_scan(PendingScan(1.1, arrival=0.0, payload=None))
    (scan,) = buffer.resolved(now=0.0)
    np.testing.assert_allclose(scan.odom, [0.01, 0.0, 0.0])
