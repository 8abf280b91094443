"""Bursty stamps (:mod:`crlam.preflight.odometry_retime`, "Bursty stamps"): a logger that stamps
records as they arrive, in bursts, puts stamps a scan period off; the re-attachment at a
corrected stamp then reads its stamps from a robust fit against the records' places."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from crlam.io.carmen_types import CarmenRecord, LaserScan, OdometryReading
from crlam.preflight.odometry_retime import RetimeStats, is_bursty, regular_stamps, retime_odometry
from crlam.slam.time_offset import log_stamps

SCAN_PERIOD = 0.2
TURN_RATE = 0.5  # rad/s
SPEED = 0.4  # m/s


def _pose(t: float) -> np.ndarray:
    """The robot on a circle: SPEED m/s, TURN_RATE rad/s, from the origin heading along x."""
    r = SPEED / TURN_RATE
    th = TURN_RATE * t
    return np.array([r * math.sin(th), r * (1.0 - math.cos(th)), math.remainder(th, 2 * math.pi)])


def _bursty(t: np.ndarray, seed: int) -> np.ndarray:
    """Arrival stamps as Intel's logger writes them: a fifth of the records held back and sent
    1 ms before the next one, and a few more delayed by up to half a period."""
    rng = np.random.default_rng(seed)
    out = t.copy()
    held = np.flatnonzero(rng.random(len(t) - 1) < 0.2)
    out[held] = t[held + 1] - 0.001
    late = rng.random(len(t)) < 0.05
    out[late] += rng.uniform(0.0, 0.5 * SCAN_PERIOD, int(late.sum()))
    return out


def _log(shift: float, seed: int = 0, n: int = 300) -> tuple[list[CarmenRecord], list[np.ndarray]]:
    """Two odometry records per scan, both series stamped in bursts, the odometry's stamps
    ``shift`` s after the laser's for the same instant; each scan's field holds the odometry of
    its own instant (so that only the re-attachment decides). Returns the records and the true
    odometry of every scan."""
    t_scan = SCAN_PERIOD * np.arange(n)
    t_odo = 0.5 * SCAN_PERIOD * np.arange(2 * n)
    s_scan, s_odo = _bursty(t_scan, seed), _bursty(t_odo, seed + 1) + shift
    records: list[CarmenRecord] = []
    truth = []
    for k in range(n):
        for j in (2 * k, 2 * k + 1):
            records.append(OdometryReading(pose=_pose(t_odo[j]), timestamp=float(s_odo[j])))
        truth.append(_pose(t_scan[k]))
        records.append(LaserScan(np.ones(3), -0.1, 0.1, 10.0, pose=truth[-1], odom=truth[-1], timestamp=float(s_scan[k])))
    return records, truth


def _errors(records: list[CarmenRecord], truth: list[np.ndarray], offset: float, fitted: bool) -> np.ndarray:
    stamps = log_stamps(iter(records)) if fitted else None
    stats = RetimeStats()
    out = [r for r in retime_odometry(iter(records), offset, stats=stats, stamps=stamps) if isinstance(r, LaserScan)]
    assert stats.scan_stamps_fitted == stats.odometry_stamps_fitted == fitted
    return np.array([math.hypot(*(r.odom[:2] - p[:2])) for r, p in zip(out, truth, strict=True)])


def test_a_steady_series_is_not_bursty_and_a_logger_s_bursts_are() -> None:
    t = SCAN_PERIOD * np.arange(200)
    assert not is_bursty(t)
    assert not is_bursty(t + np.random.default_rng(0).normal(0, 0.005, len(t)))  # jitter is not a burst
    assert is_bursty(_bursty(t, 0))
    broken = _bursty(t, 0)
    broken[7] = np.nan
    assert not is_bursty(broken)  # not fitted: the re-attachment reads the stamps as they are


def test_the_fit_recovers_the_steady_clock_of_bursty_stamps() -> None:
    t = SCAN_PERIOD * np.arange(400)
    raw = _bursty(t, 3)
    fit = regular_stamps(raw)
    assert np.percentile(np.abs(raw - t), 90) > 0.15
    # A fifth of the records are held back by a period; after the fit nine in ten are on the
    # clock (a window whose records are mostly held back is not).
    assert np.percentile(np.abs(fit - t), 90) < 0.01 and np.max(np.abs(fit - t)) < SCAN_PERIOD


@settings(max_examples=50, deadline=None)
@given(
    start=st.floats(-1e9, 1e9),
    period=st.floats(0.001, 10.0),
    n=st.integers(1, 60),
)
def test_a_steady_series_is_its_own_fit(start: float, period: float, n: int) -> None:
    t = start + period * np.arange(n)
    np.testing.assert_allclose(regular_stamps(t), t, rtol=0, atol=1e-9 * max(1.0, abs(start)) + 1e-9 * period * n)


@pytest.mark.parametrize("seed", [0, 1])
def test_retiming_bursty_logs_reads_the_fitted_stamps(seed: int) -> None:
    shift = 0.15
    records, truth = _log(shift, seed)
    # An estimate 3 ms off the true shift, as the estimate's own error is: with the logged
    # stamps the interpolation crosses bursts and many scans get odometry a period away.
    raw = _errors(records, truth, shift - 0.003, fitted=False)[5:-5]
    fit = _errors(records, truth, shift - 0.003, fitted=True)[5:-5]
    assert np.mean(raw > 0.02) > 0.5 and np.percentile(raw, 90) > 0.05
    assert np.mean(fit > 0.02) < 0.1 and np.percentile(fit, 90) < 0.015


def test_steady_logs_are_retimed_from_their_own_stamps() -> None:
    records, _ = _log(0.15, 0)
    stamps = log_stamps(iter(records))
    assert stamps.scans is not None and stamps.odometry is not None
    steady = [OdometryReading(pose=_pose(0.1 * k), timestamp=0.1 * k + 0.15) for k in range(600)]
    assert log_stamps(iter(steady)).odometry is None and log_stamps(iter(steady)).scans is None


def test_a_pause_is_neither_a_burst_nor_fitted_across() -> None:
    # A steady 20 Hz series with a three-hour pause: still steady, and the fit keeps it.
    t = np.concatenate([0.05 * np.arange(200), 10_800.0 + 0.05 * np.arange(200)])
    assert not is_bursty(t)
    np.testing.assert_allclose(regular_stamps(t), t, atol=1e-9)
    # Bursty on both sides of the pause: each side is fitted on its own clock.
    b = np.concatenate([_bursty(SCAN_PERIOD * np.arange(300), 5), 5_000.0 + _bursty(SCAN_PERIOD * np.arange(300), 6)])
    assert is_bursty(b)
    fit = regular_stamps(b)
    truth = np.concatenate([SCAN_PERIOD * np.arange(300), 5_000.0 + SCAN_PERIOD * np.arange(300)])
    assert np.percentile(np.abs(fit - truth), 90) < 0.01 and np.max(np.abs(fit - truth)) < SCAN_PERIOD
