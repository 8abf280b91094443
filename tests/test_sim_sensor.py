"""Range sensor: beam layouts, presets and the statistics of the beam-mixture noise."""

from __future__ import annotations

import math

import numpy as np
import pytest

from crlam.errors import ConfigError
from crlam.sim import RangeSensor, noiseless, office_world, paper_lidar, sick_lms200

N = 400_000  # beams per statistics test; binomial fractions are then good to ~0.002 (4 sigma)


def _frac_tol(p: float, n: int = N) -> float:
    return 5.0 * math.sqrt(max(p * (1 - p), 1e-4) / n) + 1e-4


def test_beam_layouts() -> None:
    lidar = paper_lidar()
    a = lidar.angles
    assert lidar.n_beams == 1079 and a.shape == (1079,) and lidar.max_range == 8.0
    np.testing.assert_allclose([a[0], a[-1], a[539]], [-0.75 * math.pi, 0.75 * math.pi, 0.0], atol=1e-12)
    np.testing.assert_allclose(np.diff(a), lidar.angle_increment, atol=1e-12)
    sick = sick_lms200()
    np.testing.assert_allclose(np.degrees(sick.angles), -90.0 + np.arange(180), atol=1e-9)
    assert sick.angle_min == -0.5 * math.pi and sick.angle_increment == pytest.approx(math.pi / 180)
    quiet = noiseless(n_beams=5, fov=math.pi, max_range=4.0)
    np.testing.assert_allclose(quiet.angles, np.linspace(-math.pi / 2, math.pi / 2, 5))
    assert quiet.p_hit == 1.0 and quiet.sigma_hit == 0.0
    assert RangeSensor.from_dict(lidar.to_dict()) == lidar


@pytest.mark.parametrize(
    "kwargs",
    [
        {"n_beams": 0},
        {"fov": 0.0},
        {"max_range": math.inf},
        {"min_range": 9.0},
        {"p_short": 0.6, "p_rand": 0.6},
        {"p_max": -0.1},
        {"sigma_hit": -1.0},
    ],
)
def test_invalid_sensors(kwargs: dict[str, float]) -> None:
    base = {"n_beams": 10, "fov": 1.0, "max_range": 8.0}
    with pytest.raises(ConfigError):
        RangeSensor(**{**base, **kwargs})  # type: ignore[arg-type]


def test_hit_noise_statistics() -> None:
    sensor = RangeSensor(n_beams=1, fov=1.0, max_range=8.0, sigma_hit=0.05)
    d = np.full((N, 1), 3.0)
    z = sensor.apply_noise(d, np.random.default_rng(1))
    err = z - d
    assert abs(err.mean()) < 5 * 0.05 / math.sqrt(N)
    assert err.std() == pytest.approx(0.05, rel=0.01)
    # Clipping: a true range near max_range still gives returns strictly below it.
    z2 = sensor.apply_noise(np.full((N, 1), 7.99), np.random.default_rng(2))
    assert z2.max() < 8.0
    # Nothing within range: a hit becomes a no-return.
    z3 = sensor.apply_noise(np.full((100, 1), np.inf), np.random.default_rng(3))
    assert np.all(z3 == 8.0)


def test_mixture_component_fractions() -> None:
    p_short, p_rand, p_max = 0.1, 0.15, 0.05
    sensor = RangeSensor(
        n_beams=1, fov=1.0, max_range=8.0, sigma_hit=0.02, p_short=p_short, p_rand=p_rand, p_max=p_max, lambda_short=0.5
    )
    d = 5.0
    z = sensor.apply_noise(np.full((N, 1), d), np.random.default_rng(4)).ravel()
    assert z.min() >= 0.0 and z.max() <= 8.0
    no_return = z == 8.0
    assert no_return.mean() == pytest.approx(p_max, abs=_frac_tol(p_max))
    # Readings within 0.2 m of the true range: all hits (sigma 0.02), plus the random and short
    # readings that happen to land there (short ones only from below).
    near = np.abs(z - d) < 0.2
    short_near = p_short * (math.exp(-0.5 * (d - 0.2)) - math.exp(-0.5 * d)) / (1 - math.exp(-0.5 * d))
    expected_near = sensor.p_hit + p_rand * 0.4 / 8.0 + short_near
    assert near.mean() == pytest.approx(expected_near, abs=_frac_tol(expected_near))
    # Readings beyond the true range (and not a no-return) come only from the random component.
    beyond = (z > d + 0.2) & ~no_return
    assert beyond.mean() == pytest.approx(p_rand * (8.0 - d - 0.2) / 8.0, abs=_frac_tol(0.05))


def test_short_readings_are_truncated_exponential() -> None:
    lam, d = 0.5, 4.0
    sensor = RangeSensor(n_beams=1, fov=1.0, max_range=8.0, p_short=1.0, lambda_short=lam)
    z = sensor.apply_noise(np.full((N, 1), d), np.random.default_rng(5)).ravel()
    assert z.min() >= 0.0 and z.max() < d  # always short of the true range
    mean = 1.0 / lam - d * math.exp(-lam * d) / (1.0 - math.exp(-lam * d))
    assert z.mean() == pytest.approx(mean, abs=5 * z.std() / math.sqrt(N))
    # Nothing within range: short readings are truncated at max_range instead.
    z_inf = sensor.apply_noise(np.full((1000, 1), np.inf), np.random.default_rng(6))
    assert z_inf.max() < 8.0


def test_random_readings_are_uniform() -> None:
    sensor = RangeSensor(n_beams=1, fov=1.0, max_range=8.0, p_rand=1.0)
    z = sensor.apply_noise(np.full((N, 1), 2.0), np.random.default_rng(7)).ravel()
    assert z.min() >= 0.0 and z.max() < 8.0
    assert z.mean() == pytest.approx(4.0, abs=0.02)
    assert z.var() == pytest.approx(64.0 / 12.0, rel=0.01)


def test_noise_draws_are_per_scan() -> None:
    sensor = paper_lidar()
    d = np.random.default_rng(8).uniform(0.5, 9.0, (30, sensor.n_beams))
    a = sensor.apply_noise(d[:20], np.random.default_rng(9))
    b = sensor.apply_noise(d, np.random.default_rng(9))
    np.testing.assert_array_equal(a, b[:20])  # more scans do not change the first ones


def test_simulate_ranges_on_a_world() -> None:
    world = office_world(0)
    poses = np.array([[3.0, 7.2, 0.0], [10.0, 7.2, 1.0], [16.0, 7.4, -2.0]])
    quiet = noiseless(n_beams=361, fov=2 * math.pi, max_range=8.0)
    true = quiet.true_ranges(world, poses)
    z = quiet.simulate_ranges(world, poses, np.random.default_rng(0))
    np.testing.assert_array_equal(z, np.where(np.isfinite(true), true, 8.0))
    assert np.isfinite(true).mean() > 0.5  # an office: most beams hit something within 8 m
    noisy = paper_lidar().simulate_ranges(world, poses, np.random.default_rng(0))
    assert noisy.shape == (3, 1079)
    assert np.all((noisy >= 0.0) & (noisy <= 8.0))
