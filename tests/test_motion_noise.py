"""GMapping's odometry noise fitted to a log's own scans (crlam.motion_noise)."""

from __future__ import annotations

import json
import math
from pathlib import Path

try:
    import tomllib
except ModuleNotFoundError:  # Python 3.10
    import tomli as tomllib

import numpy as np
import pytest

from crlam.cli import main
from crlam.errors import ConfigError, DataFormatError
from crlam.motion_noise import fit_gmapping_noise, gmapping_sigmas
from crlam.slam import SlamConfig


def _synthetic(params: tuple[float, float, float, float], n: int, seed: int) -> tuple[np.ndarray, np.ndarray]:
    rng = np.random.default_rng(seed)
    u = np.stack([rng.uniform(0.0, 0.6, n), rng.normal(0.0, 0.02, n), rng.uniform(-0.3, 0.3, n)], 1)
    r = rng.normal(size=(n, 3)) * gmapping_sigmas(params, u)
    return u, r


@pytest.mark.parametrize("params", [(0.1, 0.2, 0.1, 0.2), (0.04, 0.05, 0.02, 0.08), (0.15, 0.0, 0.05, 0.1)])
def test_the_fit_recovers_the_parameters_that_drew_the_residuals(params: tuple[float, float, float, float]) -> None:
    u, r = _synthetic(params, 4000, seed=3)
    est = fit_gmapping_noise(u, r)
    assert est.n_steps == 4000 and est.n_used >= 3900
    for got, true in zip(est.params, params):
        assert abs(got - true) < 0.1 * max(true, 0.05), (est.params, params)


def test_outliers_are_left_out_of_the_fit() -> None:
    params = (0.05, 0.05, 0.05, 0.05)
    u, r = _synthetic(params, 2000, seed=5)
    r[::50] += np.array([1.0, -0.8, 0.5])  # a failed match every 50 steps
    est = fit_gmapping_noise(u, r)
    assert est.n_used <= 2000 - 40
    for got, true in zip(est.params, params):
        assert abs(got - true) < 0.15 * true, est.params


def test_too_few_steps_is_an_error() -> None:
    u, r = _synthetic((0.1, 0.1, 0.1, 0.1), 10, seed=1)
    with pytest.raises(DataFormatError, match="at least"):
        fit_gmapping_noise(u, r)


def test_estimate_needs_gmappings_model() -> None:
    with pytest.raises(ConfigError, match="motion_noise"):
        SlamConfig(motion_noise="estimate", motion="thrun")
    with pytest.raises(ConfigError, match="motion_noise"):
        SlamConfig(motion_noise="guess")


@pytest.mark.slow
def test_crlam_slam_fits_the_noise_and_records_it(tmp_path: Path) -> None:
    log = tmp_path / "sim"
    assert (
        main(["simulate", "--world", "office", "--scans", "600", "--seed", "2", "--sensor", "sick", "--out", str(log), "--quiet"])
        == 0
    )
    out = tmp_path / "run"
    argv = ["slam", str(log / "log.clf"), "--out", str(out), "--particles", "3", "--motion-noise", "estimate", "--quiet"]
    assert main(argv) == 0
    metrics = json.loads((out / "metrics.json").read_text())
    est = metrics["motion_noise_estimate"]
    assert est["n_steps"] >= 20 and all(math.isfinite(v) and v >= 0 for v in est["params"])
    # The fitted values are the run's motion parameters, so --config repeats the run exactly.
    config = (out / "config.toml").read_text()
    assert len(tomllib.loads(config)["slam"]["motion_params"]) == 4 and 'motion_noise = "estimate"' in config
    again = tmp_path / "again"
    assert main(["slam", str(log / "log.clf"), "--out", str(again), "--config", str(out / "config.toml"), "--quiet"]) == 0
    assert (again / "trajectory.tum").read_text() == (out / "trajectory.tum").read_text()
