"""Odometry noise models: integration, sampling, and agreement of samples with the densities."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from crlam.errors import ConfigError
from crlam.pose import between, compose
from crlam.sim import (
    GaussianIncrementNoise,
    ThrunOdometryNoise,
    increments_from_poses,
    integrate_odometry,
    odometry_noise_from_dict,
)

N = 300_000


def _grid_moments(log_pdf, centre: np.ndarray, half: np.ndarray, n: int = 121) -> tuple[float, np.ndarray, np.ndarray]:
    """Integral, mean and covariance of exp(log_pdf) on a box ``centre +- half`` (midpoint rule)."""
    axes = [c + h * (2.0 * (np.arange(n) + 0.5) / n - 1.0) for c, h in zip(centre, half)]
    pts = np.stack(np.meshgrid(*axes, indexing="ij"), axis=-1).reshape(-1, 3)
    dv = float(np.prod(2.0 * half / n))
    w = np.exp(log_pdf(pts)) * dv
    mass = w.sum()
    mean = (w[:, None] * pts).sum(0) / mass
    d = pts - mean
    cov = (w[:, None, None] * d[:, :, None] * d[:, None, :]).sum(0) / mass
    return float(mass), mean, cov


@settings(max_examples=30, deadline=None)
@given(seed=st.integers(0, 2**31), n=st.integers(0, 40))
def test_integrate_odometry_matches_compose(seed: int, n: int) -> None:
    rng = np.random.default_rng(seed)
    start = np.array([rng.normal(), rng.normal(), rng.uniform(-math.pi, math.pi)])
    inc = rng.normal(size=(n, 3)) * [0.3, 0.1, 0.5]
    poses = integrate_odometry(start, inc)
    assert poses.shape == (n + 1, 3)
    ref = [start]
    for u in inc:
        ref.append(compose(ref[-1], u))
    np.testing.assert_allclose(poses, np.array(ref), atol=1e-9)
    assert np.all((poses[:, 2] > -math.pi) & (poses[:, 2] <= math.pi))
    np.testing.assert_allclose(increments_from_poses(poses), inc if n else np.zeros((0, 3)), atol=1e-9)


def test_gaussian_samples_match_the_model() -> None:
    model = GaussianIncrementNoise(0.02, 0.01, 0.03)
    cmd = np.array([0.1, -0.02, 0.05])
    s = model.sample_increments(np.tile(cmd, (N, 1)), np.random.default_rng(0))
    np.testing.assert_allclose(s.mean(0), cmd, atol=5 * model.sigmas.max() / math.sqrt(N))
    np.testing.assert_allclose(np.cov(s.T), model.covariance, atol=3e-3 * model.sigmas.max() ** 2 * 10)
    mass, mean, cov = _grid_moments(lambda p: model.log_pdf(p, cmd), cmd, 6 * model.sigmas, n=61)
    assert mass == pytest.approx(1.0, abs=1e-3)
    np.testing.assert_allclose(mean, cmd, atol=1e-6)
    np.testing.assert_allclose(cov, np.cov(s.T), atol=0.02 * model.sigmas.max() ** 2)


def test_gaussian_log_pdf_formula_and_wrapping() -> None:
    model = GaussianIncrementNoise(0.02, 0.01, 0.03)
    cmd = np.array([0.0, 0.0, math.pi - 0.01])
    z = np.array([0.01, -0.01, -math.pi + 0.02])  # 0.03 rad from cmd across the +-pi cut
    r = np.array([0.01, -0.01, 0.03])
    ref = float(np.sum(-0.5 * (r / model.sigmas) ** 2 - np.log(model.sigmas * math.sqrt(2 * math.pi))))
    assert model.log_pdf(z, cmd) == pytest.approx(ref, abs=1e-9)
    # The PF use: density of the relative pose between two states given the odometry.
    x0, x1 = np.array([1.0, 2.0, 0.3]), np.array([1.1, 2.05, 0.35])
    assert model.log_pdf(between(x0, x1), cmd).shape == ()
    with pytest.raises(ConfigError):
        GaussianIncrementNoise(0.0, 0.1, 0.1)


@pytest.mark.parametrize(
    ("cmd", "alphas"),
    [
        (np.array([0.3, 0.05, 0.1]), (0.05, 0.05, 0.05, 0.01)),
        (np.array([0.2, -0.1, -0.4]), (0.05, 0.05, 0.05, 0.01)),
        (np.array([0.15, 0.0, 0.8]), (0.05, 0.05, 0.05, 0.001)),
        # Driving backwards: rot1 and rot2 are close to +-pi, so alpha1 and alpha4 must be small
        # to keep the heading away from the +-pi cut and the translation away from 0 (where the
        # Cartesian grid cannot integrate the 1/t singularity; see the polar test below).
        (np.array([-0.2, 0.05, 0.1]), (0.002, 0.05, 0.05, 0.0001)),
    ],
)
def test_thrun_samples_match_the_density(cmd: np.ndarray, alphas: tuple[float, ...]) -> None:
    model = ThrunOdometryNoise(*alphas)
    s = model.sample_increments(np.tile(cmd, (N, 1)), np.random.default_rng(1))
    assert s[:, 2].std() < 0.5  # the grid below must not wrap around in heading
    half = 7.0 * s.std(0)
    mass, mean, cov = _grid_moments(lambda p: model.log_pdf(p, cmd), s.mean(0), half)
    assert mass == pytest.approx(1.0, abs=5e-3)
    np.testing.assert_allclose(mean, s.mean(0), atol=5 * s.std(0).max() / math.sqrt(N) + 1e-4)
    np.testing.assert_allclose(cov, np.cov(s.T), rtol=0.03, atol=0.02 * np.diag(np.cov(s.T)).max())


def test_thrun_density_near_zero_translation() -> None:
    """Translation noise larger than the translation: both preimages (t and -t) matter.

    Integrated on a polar grid, where the density times the Jacobian ``t`` is smooth.
    """
    model = ThrunOdometryNoise(alpha1=0.05, alpha2=0.05, alpha3=0.05, alpha4=0.005)
    cmd = np.array([0.02, 0.02, 0.6])
    s = model.sample_increments(np.tile(cmd, (N, 1)), np.random.default_rng(6))
    assert (model.decompose(s)[1] < 0.02).mean() > 0.1  # many samples near the singular origin
    n_r, n_t, n_h = 144, 120, 61
    r1 = -math.pi + (np.arange(n_r) + 0.5) * 2 * math.pi / n_r
    t = (np.arange(n_t) + 0.5) * 0.4 / n_t
    h = s[:, 2].mean() + 7 * s[:, 2].std() * (2 * (np.arange(n_h) + 0.5) / n_h - 1)
    R, T, H = np.meshgrid(r1, t, h, indexing="ij")
    pts = np.stack([T * np.cos(R), T * np.sin(R), H], axis=-1).reshape(-1, 3)
    w = np.exp(model.log_pdf(pts, cmd)) * T.ravel() * (2 * math.pi / n_r) * (0.4 / n_t) * (h[1] - h[0])
    assert w.sum() == pytest.approx(1.0, abs=5e-3)
    mean = (w[:, None] * pts).sum(0) / w.sum()
    np.testing.assert_allclose(mean, s.mean(0), atol=2e-3)


def test_thrun_parameters_and_degenerate_motion() -> None:
    # Translation noise small enough that the sampled translation never changes sign (a sign
    # change would re-decompose with rot1 + pi and inflate the rot1 spread).
    model = ThrunOdometryNoise(alpha1=0.1, alpha2=0.02, alpha3=0.02, alpha4=0.002)
    cmd = np.array([0.4, 0.3, 0.2])
    r1, t, r2 = model.decompose(cmd)
    assert t == pytest.approx(0.5) and r1 == pytest.approx(math.atan2(0.3, 0.4))
    np.testing.assert_allclose(model.recompose(r1, t, r2), cmd, atol=1e-12)
    s = model.sample_increments(np.tile(cmd, (N, 1)), np.random.default_rng(2))
    sr1, st_, sr2 = model.decompose(s)
    e_r1, e_t, e_r2 = model.stds(cmd)
    # In the decomposed coordinates the noise is independent normal with the model's variances.
    assert sr1.std() == pytest.approx(float(e_r1), rel=0.01)
    assert st_.std() == pytest.approx(float(e_t), rel=0.01)
    assert sr2.std() == pytest.approx(float(e_r2), rel=0.01)
    # Thrun's value (no Jacobian) for the main preimage.
    z = np.array([0.42, 0.28, 0.25])
    zr1, zt, zr2 = model.decompose(z)
    lp = sum(
        -0.5 * ((a - b) / c) ** 2 - math.log(c * math.sqrt(2 * math.pi))
        for a, b, c in ((zr1, r1, e_r1), (zt, t, e_t), (zr2, r2, e_r2))
    )
    assert model.log_pdf(z, cmd, jacobian=False) == pytest.approx(float(lp), abs=1e-9)
    assert model.log_pdf(z, cmd) == pytest.approx(float(lp) - math.log(zt), abs=1e-9)
    # A turn on the spot is a proper, finite model.
    spin = np.array([0.0, 0.0, 0.5])
    samples = model.sample_increments(np.tile(spin, (1000, 1)), np.random.default_rng(3))
    assert np.all(np.isfinite(samples)) and np.isfinite(model.log_pdf(samples, spin)).all()
    assert odometry_noise_from_dict(model.to_dict()) == model
    assert odometry_noise_from_dict(GaussianIncrementNoise().to_dict()) == GaussianIncrementNoise()


@pytest.mark.parametrize("model", [GaussianIncrementNoise(), ThrunOdometryNoise()])
def test_samples_are_drawn_step_by_step(model: GaussianIncrementNoise | ThrunOdometryNoise) -> None:
    inc = np.random.default_rng(4).normal(size=(50, 3)) * 0.1
    a = model.sample_increments(inc[:20], np.random.default_rng(5))
    b = model.sample_increments(inc, np.random.default_rng(5))
    np.testing.assert_array_equal(a, b[:20])
