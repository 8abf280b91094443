"""The correlative front end of RBPF-CLAM's scan-match proposal (SlamConfig.front_end)."""

from __future__ import annotations

import numpy as np
import pytest

from crlam.errors import ConfigError
from crlam.pose import between, compose
from crlam.sim.simulate import SimulationConfig, simulate
from crlam.slam import SlamConfig, SlamRun


def test_the_settings_are_validated() -> None:
    base = SlamConfig.from_preset()
    with pytest.raises(ConfigError, match="front_end"):
        SlamConfig(**{**base.to_dict(), "front_end": "icp"})
    with pytest.raises(ConfigError, match="front_end"):
        SlamConfig(**{**base.to_dict(), "front_end": "correlative", "proposal": "odometry"})
    for window in [(0.0, 0.3), (0.4, 4.0), (float("nan"), 0.3), (11.0, 0.3)]:
        with pytest.raises(ConfigError, match="front_end_window"):
            SlamConfig(**{**base.to_dict(), "front_end": "correlative", "front_end_window": window})


def _kicked_run(front_end: str, kick: float) -> tuple[SlamRun, np.ndarray]:
    """RBPF-CLAM on a simulated office log whose odometry turns by ``kick`` rad more than the robot
    at scan 60 (a wheel slipping in a sharp turn): every later odometry pose is moved with it."""
    log = simulate(SimulationConfig(world="office", n_scans=140, seed=4))
    config = SlamConfig.from_preset(particles=8, seed=1, front_end=front_end)
    run = SlamRun(config)
    jump = np.array([0.0, 0.0, kick])
    angles = log.sensor.angles
    for i, (stamp, odom, ranges) in enumerate(zip(log.timestamps, log.odometry, log.ranges)):
        if i >= 60:
            # The odometry from scan 60 on, as if its frame had jumped by `jump` at scan 60.
            odom = compose(compose(log.odometry[60], jump), between(log.odometry[60], odom))
        run.step(odom, angles, ranges, np.zeros(3), float(stamp))
    return run, log.poses


def _heading_errors_after_the_slip(run: SlamRun, truth: np.ndarray) -> np.ndarray:
    _, poses = run.trajectory()
    return np.abs(np.angle(np.exp(1j * (poses[70:, 2] - truth[70:, 2]))))


def test_a_slip_in_a_turn_beyond_the_climbs_reach_is_searched_for_and_undone() -> None:
    # A 29 degree slip: the particles' hill climbs alone settle on the odometry's wrong heading...
    run, truth = _kicked_run("none", 0.5)
    assert np.median(_heading_errors_after_the_slip(run, truth)) > 0.3
    # ...the correlative search brings their start back within their reach.
    run, truth = _kicked_run("correlative", 0.5)
    searched, corrected = run.filter.front_end_counts()
    assert searched == sum(run.processed) - 1  # every processed scan after the first
    assert corrected >= 1
    assert np.median(_heading_errors_after_the_slip(run, truth)) < 0.05
