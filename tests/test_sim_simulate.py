"""End-to-end simulation: determinism, prefix stability, and the written files read back."""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pytest

from crlam.errors import ConfigError
from crlam.io.carmen import load_log
from crlam.io.tum import read_tum
from crlam.sim import (
    GaussianIncrementNoise,
    SimulationConfig,
    ThrunOdometryNoise,
    World,
    increments_from_poses,
    noiseless,
    simulate,
    write_simulation,
)

FILES = ("log.clf", "groundtruth.tum", "odometry.tum", "world.pgm", "world.yaml", "simulation.json")


def _config(**kw: object) -> SimulationConfig:
    base: dict[str, object] = {"world": "office", "n_scans": 50, "seed": 3}
    base.update(kw)
    return SimulationConfig(**base)  # type: ignore[arg-type]


def test_same_seed_same_bytes(tmp_path: Path) -> None:
    cfg = _config()
    write_simulation(simulate(cfg), tmp_path / "a")
    write_simulation(simulate(cfg), tmp_path / "b")
    for name in FILES:
        assert (tmp_path / "a" / name).read_bytes() == (tmp_path / "b" / name).read_bytes(), name
    write_simulation(simulate(_config(seed=4)), tmp_path / "c")
    assert (tmp_path / "a" / "log.clf").read_bytes() != (tmp_path / "c" / "log.clf").read_bytes()
    assert (tmp_path / "a" / "world.pgm").read_bytes() == (tmp_path / "c" / "world.pgm").read_bytes()


def test_more_scans_do_not_change_the_first_ones() -> None:
    short = simulate(_config(n_scans=30))
    long = simulate(_config(n_scans=50))
    np.testing.assert_array_equal(short.poses, long.poses[:30])
    np.testing.assert_array_equal(short.odometry, long.odometry[:30])
    np.testing.assert_array_equal(short.ranges, long.ranges[:30])
    np.testing.assert_array_equal(short.timestamps, long.timestamps[:30])


def test_paper_lidar_log_reads_back(tmp_path: Path) -> None:
    log = simulate(_config())
    assert log.ranges.shape == (50, 1079)
    paths = write_simulation(log, tmp_path)
    assert {p.name for p in paths.values()} == set(FILES)
    text = (tmp_path / "log.clf").read_text()
    assert text.count("\nROBOTLASER1 ") == 50 and text.count("\nODOM ") == 50 and "FLASER" not in text
    back = load_log(tmp_path / "log.clf")
    assert len(back.scans) == 50 and len(back.odometry) == 50
    zmax = log.sensor.max_range
    for k in (0, 17, 49):
        scan = back.scans[k]
        assert scan.timestamp == pytest.approx(log.timestamps[k], abs=1e-6)
        assert scan.max_range == pytest.approx(zmax)
        np.testing.assert_allclose(scan.angles, log.sensor.angles, atol=1e-6)
        hit = log.ranges[k] < zmax
        # Returns stay returns, no-returns stay no-returns, values to the written 0.1 mm.
        np.testing.assert_array_equal(scan.ranges < zmax, hit)
        np.testing.assert_allclose(scan.ranges[hit], log.ranges[k][hit], atol=1.1e-4)
        np.testing.assert_allclose(scan.pose, log.odometry[k], atol=1e-4)
    np.testing.assert_allclose(back.odometry_poses, log.odometry, atol=1e-4)
    gt = read_tum(tmp_path / "groundtruth.tum")
    np.testing.assert_allclose(gt.poses, log.poses, atol=1e-8)
    np.testing.assert_allclose(gt.timestamps, log.timestamps, atol=1e-9)
    world = World.from_nav2_yaml(tmp_path / "world.yaml")
    np.testing.assert_array_equal(world.occupied, log.world.occupied)
    meta = json.loads((tmp_path / "simulation.json").read_text())
    assert meta["n_scans"] == 50 and meta["config"]["sensor"]["name"] == "paper_lidar"
    assert meta["config"]["odometry"]["model"] == "gaussian_increment"


def test_sick_log_is_flaser(tmp_path: Path) -> None:
    log = simulate(_config(sensor="sick_lms200", n_scans=20))
    write_simulation(log, tmp_path)
    text = (tmp_path / "log.clf").read_text()
    assert text.count("\nFLASER 180 ") == 20 and "ROBOTLASER1" not in text
    back = load_log(tmp_path / "log.clf")
    np.testing.assert_allclose(back.scans[5].angles, np.radians(-90.0 + np.arange(180)), atol=1e-12)
    np.testing.assert_array_equal(back.scans[5].ranges >= back.scans[5].max_range, log.ranges[5] >= log.sensor.max_range)


def test_odometry_and_ground_truth_relation() -> None:
    quiet = simulate(_config(sensor=noiseless(n_beams=90, fov=2 * math.pi), odometry=GaussianIncrementNoise(1e-9, 1e-9, 1e-9)))
    np.testing.assert_allclose(quiet.odometry, quiet.poses, atol=1e-6)  # (almost) perfect odometry
    noisy = simulate(_config(n_scans=200, odometry=ThrunOdometryNoise(), odometry_at_origin=True))
    np.testing.assert_array_equal(noisy.odometry[0], [0.0, 0.0, 0.0])
    # The increments, not the absolute poses, carry the information: they stay close to the truth.
    d = noisy.odometry_increments - increments_from_poses(noisy.poses)
    assert np.abs(d[:, :2]).max() < 0.05 and np.abs(d[:, 2]).max() < 0.1


def test_config_validation() -> None:
    with pytest.raises(ConfigError):
        _config(n_scans=0)
    with pytest.raises(ConfigError):
        _config(sensor="no-such-sensor")
    with pytest.raises(ConfigError):
        _config(host="two words")
    assert _config(speed=0.3).robot_params.max_speed == 0.3
