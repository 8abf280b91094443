"""GMapping's odometry noise fitted to a log's own scans (crlam.slam.motion_noise)."""

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
from crlam.slam import SlamConfig
from crlam.slam.motion_noise import fit_gmapping_noise, gmapping_sigmas


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
    # Left out of the fit (their mean absolute residual is 20 sigmas); the tail coverage then
    # widens the fit only by what 2 % of the steps beyond the normal's 95 % interval move its
    # 95th percentile (the clean residuals' 96.9th: 2.16 against 1.96 sigmas).
    for got, true in zip(est.params, params):
        assert 0.9 * true < got < 1.25 * true, est.params


def test_a_heavy_tail_widens_the_fit_until_it_covers_the_residuals() -> None:
    """Wheel slip gives odometry errors a tail: 15 % of the steps five times the rest. The fitted
    normals must still hold TAIL_COVERAGE of the residuals (a filter that trusts its odometry more
    than that cannot follow a slip), and a Gaussian residual is left as it was fitted."""
    from statistics import NormalDist

    from crlam.slam.motion_noise import TAIL_COVERAGE

    params = (0.03, 0.01, 0.03, 0.03)
    u, r = _synthetic(params, 4000, seed=7)
    slip = np.random.default_rng(8).random(len(u)) < 0.15
    r[slip] *= 5.0
    est = fit_gmapping_noise(u, r)
    z = np.abs(r) / gmapping_sigmas(est.params, u)
    z_target = NormalDist().inv_cdf(0.5 + TAIL_COVERAGE / 2)
    assert abs(float(np.mean(z[:, :2] <= z_target)) - TAIL_COVERAGE) < 0.01
    assert abs(float(np.mean(z[:, 2] <= z_target)) - TAIL_COVERAGE) < 0.01
    assert all(got > 1.5 * true for got, true in zip(est.params, params))


def test_the_pre_pass_restarts_its_map_and_skips_the_pair_across_the_restart(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """A long log's whole map at 0.05 m exceeds the cell limit: the matcher starts a fresh map
    every WINDOW_STEPS processed scans, and the step across a restart is no residual."""
    import crlam.slam.motion_noise as motion_noise
    from crlam.io import open_log
    from crlam.sim.simulate import SimulationConfig, simulate, write_simulation

    write_simulation(simulate(SimulationConfig(world="office", n_scans=400, seed=2, sensor="sick")), tmp_path)
    scans = list(open_log(tmp_path / "log.clf"))
    from crlam.errors import ResourceLimitError
    from crlam.limits import limits, set_limits

    fit_rows: list[int] = []
    fit = motion_noise.fit_gmapping_noise

    def spy(u: np.ndarray, r: np.ndarray) -> motion_noise.MotionNoiseEstimate:
        assert np.all(np.isfinite(u)) and np.all(np.isfinite(r))  # no increment spans a restart
        fit_rows.append(len(u))
        return fit(u, r)

    monkeypatch.setattr(motion_noise, "fit_gmapping_noise", spy)
    full = motion_noise.estimate_gmapping_noise(scans, linear_update=0.5, angular_update=0.25, max_range=8.0)
    monkeypatch.setattr(motion_noise, "WINDOW_STEPS", 10)
    windowed = motion_noise.estimate_gmapping_noise(scans, linear_update=0.5, angular_update=0.25, max_range=8.0)
    # Each restart adds the fresh map's first scan (processed at once: one more increment) and
    # drops the increment across the restart and the one into that first scan: one fewer.
    assert fit_rows[0] >= 40 and fit_rows[1] == fit_rows[0]
    assert all(math.isfinite(v) and v >= 0 for v in windowed.params)
    for a, b in zip(full.params, windowed.params):  # the same odometry, the matcher's own scatter
        assert abs(a - b) <= 0.5 * max(a, b) + 0.01, (full.params, windowed.params)
    # A map limit that the whole log's map exceeds: the windows stay within it.
    saved = limits()
    try:
        set_limits(map_cells=200_000)
        monkeypatch.setattr(motion_noise, "WINDOW_STEPS", 200)
        with pytest.raises(ResourceLimitError):
            motion_noise.estimate_gmapping_noise(scans, linear_update=0.5, angular_update=0.25, max_range=8.0)
        monkeypatch.setattr(motion_noise, "WINDOW_STEPS", 5)
        motion_noise.estimate_gmapping_noise(scans, linear_update=0.5, angular_update=0.25, max_range=8.0)
    finally:
        set_limits(map_cells=saved.map_cells)


def test_too_few_steps_is_an_error() -> None:
    u, r = _synthetic((0.1, 0.1, 0.1, 0.1), 10, seed=1)
    with pytest.raises(DataFormatError, match="at least"):
        fit_gmapping_noise(u, r)


def test_a_log_with_too_little_motion_keeps_gmappings_defaults_and_says_so(tmp_path: Path) -> None:
    from crlam.io import open_log
    from crlam.sim.simulate import SimulationConfig, simulate, write_simulation
    from crlam.slam.motion_noise import GMAPPING_DEFAULT, estimate_gmapping_noise

    write_simulation(simulate(SimulationConfig(world="office", n_scans=60, seed=1, sensor="sick")), tmp_path)
    est = estimate_gmapping_noise(open_log(tmp_path / "log.clf"), linear_update=0.5, angular_update=0.25, max_range=8.0)
    assert not est.fitted and est.params == GMAPPING_DEFAULT and est.n_steps < 20
    assert "GMapping's defaults" in est.describe() and est.to_dict()["fitted"] is False


def test_estimate_needs_gmappings_model() -> None:
    with pytest.raises(ConfigError, match="motion_noise"):
        SlamConfig(motion_noise="estimate", motion="thrun")
    # The robust preset's estimate gives way to another motion model chosen over it...
    thrun = SlamConfig.from_preset(motion="thrun")
    assert thrun.motion == "thrun" and thrun.motion_noise == "model"
    assert SlamConfig.from_preset().motion_noise == "estimate"
    # ... but not when the noise is asked for too.
    with pytest.raises(ConfigError, match="motion_noise"):
        SlamConfig.from_preset(motion="thrun", motion_noise="estimate")
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
