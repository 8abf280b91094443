"""The map's reach chosen from a log's readings (crlam.preflight.map_range, SlamConfig.map_range)."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from crlam.cli import main
from crlam.errors import ConfigError
from crlam.io.carmen import LaserScan
from crlam.preflight.map_range import MAX_READINGS_RANGE, SAMPLE_SCANS, map_range_from_readings
from crlam.sim.simulate import SimulationConfig, simulate, write_simulation
from crlam.slam import SlamConfig


def _scans(readings: list[np.ndarray], max_range: float = 40.0) -> list[LaserScan]:
    return [
        LaserScan(
            ranges=r,
            angle_min=-np.pi / 2,
            angle_increment=np.pi / (len(r) - 1),
            max_range=max_range,
            pose=np.zeros(3),
            odom=np.zeros(3),
        )
        for r in readings
    ]


def test_the_reach_is_the_share_of_the_returns_rounded_up_between_the_floor_and_the_cap() -> None:
    rng = np.random.default_rng(0)
    # Indoors: every return within 5 m; the floor stands.
    indoor = map_range_from_readings(_scans([rng.uniform(0.2, 5.0, 181) for _ in range(50)]), 8.0)
    assert indoor.max_range == 8.0 and indoor.share_range is not None and indoor.share_range < 5.0
    # A hall: 90 % of the returns within 11.3 m -> 12 m.
    hall = map_range_from_readings(_scans([np.linspace(0.5, 12.5, 181) for _ in range(20)]), 8.0)
    assert hall.share_range == pytest.approx(0.5 + 0.9 * 12.0, abs=0.02)
    assert hall.max_range == 12.0
    # Outdoors: returns out to 39 m; the cap.
    outdoor = map_range_from_readings(_scans([rng.uniform(1.0, 39.0, 181) for _ in range(20)]), 8.0)
    assert outdoor.max_range == MAX_READINGS_RANGE
    # A floor above the cap is kept.
    assert map_range_from_readings(_scans([rng.uniform(1.0, 39.0, 181)]), 25.0).max_range == 25.0


def test_no_returns_and_other_records_do_not_count() -> None:
    near = np.full(181, 3.0)
    # Half of each scan is no-return (at or above the sensor's maximum, inf, NaN, 0).
    near[:90] = [40.0, np.inf, np.nan, 0.0, 45.0, -1.0] * 15
    choice = map_range_from_readings(["not a scan", *_scans([near] * 10)], 8.0)
    assert choice.n_scans == 10
    assert choice.n_returns == 91 * 10
    assert choice.share_range == pytest.approx(3.0)
    assert choice.max_range == 8.0
    # Without a single return the floor stands, and nothing is claimed about the returns.
    empty = map_range_from_readings(_scans([np.full(181, np.inf)] * 3), 8.0)
    assert (empty.max_range, empty.share_range, empty.n_returns) == (8.0, None, 0)


def test_only_the_first_scans_are_read() -> None:
    far, near = np.full(181, 15.0), np.full(181, 2.0)
    assert map_range_from_readings(_scans([near] * 5 + [far] * 5), 8.0, max_scans=5).max_range == 8.0
    assert map_range_from_readings(_scans([near] * 5 + [far] * 5), 8.0).max_range == 15.0
    # At most SAMPLE_SCANS, whatever the run's own limit.
    scans = _scans([near]) * SAMPLE_SCANS + _scans([far]) * 10
    assert map_range_from_readings(scans, 8.0, max_scans=SAMPLE_SCANS + 10).n_scans == SAMPLE_SCANS


def test_the_setting_is_validated() -> None:
    with pytest.raises(ConfigError, match="map_range"):
        SlamConfig(map_range="auto")
    assert SlamConfig.from_preset("paper").map_range == "fixed"


def test_crlam_slam_records_the_chosen_reach(tmp_path: Path) -> None:
    log_dir = tmp_path / "sim"
    write_simulation(simulate(SimulationConfig(world="office", n_scans=40, seed=2)), log_dir)
    out = tmp_path / "run"
    argv = ["slam", str(log_dir / "log.clf"), "--out", str(out), "--particles", "4", "--map-range", "readings", "-q"]
    assert main([*argv, "--max-range", "3"]) == 0
    metrics = json.loads((out / "metrics.json").read_text())
    record = metrics["map_range"]
    assert record["floor_m"] == 3.0 and record["n_scans"] == 40
    # The run's z_max is the chosen one, and the simulated sensor's returns reach past 3 m.
    assert record["max_range_m"] == np.clip(np.ceil(record["share_range_m"]), 3.0, MAX_READINGS_RANGE)
    assert record["max_range_m"] > 3.0
    # config.toml keeps the setting (the rule and its least z_max), so that it repeats the rule.
    assert "max_range = 3.0" in (out / "config.toml").read_text()
    assert main([*argv, "--map-range", "fixed", "--force"]) == 0
    assert json.loads((out / "metrics.json").read_text())["map_range"] is None
