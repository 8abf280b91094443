"""Ray casting: ``crlam._native.cast_ranges`` and the numpy fallback against an exact reference.

The reference is independent of both implementations: for every ray it intersects the ray with
*every* occupied cell square (slab method) and keeps the smallest entry distance. It is slow but
exact, and shares no traversal logic with a DDA.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from crlam.sim import (
    World,
    cast_ranges_numpy,
    museum_world,
    native_cast_available,
    paper_lidar,
    true_ranges,
)

needs_native = pytest.mark.skipif(not native_cast_available(), reason="crlam._native.cast_ranges not built")


def slab_reference(
    occ: np.ndarray, ox: float, oy: float, res: float, poses: np.ndarray, angles: np.ndarray, max_range: float
) -> np.ndarray:
    """Exact first-hit distances by intersecting each ray with every occupied square."""
    ys, xs = np.nonzero(occ)
    x0, y0 = ox + xs * res, oy + ys * res
    x1, y1 = x0 + res, y0 + res
    out = np.full((len(poses), len(angles)), np.inf)
    for i, (px, py, th) in enumerate(poses):
        # A start inside an occupied cell (half-open cell extents) reads 0.
        inside = (px >= x0) & (px < x1) & (py >= y0) & (py < y1)
        if inside.any():
            out[i] = 0.0
            continue
        for j, a in enumerate(angles):
            dx, dy = math.cos(th + a), math.sin(th + a)
            with np.errstate(divide="ignore", invalid="ignore"):
                tx0, tx1 = (x0 - px) / dx, (x1 - px) / dx
                ty0, ty1 = (y0 - py) / dy, (y1 - py) / dy
            if dx == 0.0:
                tx0 = np.where((px >= x0) & (px <= x1), -np.inf, np.inf)
                tx1 = np.where((px >= x0) & (px <= x1), np.inf, -np.inf)
            if dy == 0.0:
                ty0 = np.where((py >= y0) & (py <= y1), -np.inf, np.inf)
                ty1 = np.where((py >= y0) & (py <= y1), np.inf, -np.inf)
            t_in = np.maximum(np.minimum(tx0, tx1), np.minimum(ty0, ty1))
            t_out = np.minimum(np.maximum(tx0, tx1), np.maximum(ty0, ty1))
            hit = (t_in <= t_out) & (t_out > 0.0)
            if hit.any():
                t = float(np.max([t_in[hit].min(), 0.0]))
                out[i, j] = t if t <= max_range else np.inf
    return out


def _compare(got: np.ndarray, ref: np.ndarray, res: float, max_range: float) -> None:
    tol = res / 100.0
    both = np.isfinite(got) & np.isfinite(ref)
    np.testing.assert_allclose(got[both], ref[both], atol=tol, rtol=0)
    # Where only one side found a hit, the hit must sit at the range limit (a tie at max_range).
    lone = np.isfinite(got) != np.isfinite(ref)
    edge = np.where(np.isfinite(got), got, ref)[lone]
    assert np.all(np.abs(edge - max_range) < tol), edge


def _random_case(seed: int, res: float) -> tuple[np.ndarray, float, float, np.ndarray, np.ndarray, float]:
    rng = np.random.default_rng(seed)
    ny, nx = rng.integers(1, 25, 2)
    occ = rng.random((ny, nx)) < rng.uniform(0.02, 0.4)
    ox, oy = rng.uniform(-2.0, 2.0, 2)
    # Poses inside and around the grid (outside cells are free, rays may enter the grid).
    n = 6
    px = ox + rng.uniform(-0.3, 1.3, n) * nx * res
    py = oy + rng.uniform(-0.3, 1.3, n) * ny * res
    poses = np.stack([px, py, rng.uniform(-math.pi, math.pi, n)], axis=1)
    angles = np.sort(rng.uniform(-math.pi, math.pi, 24))
    max_range = float(rng.uniform(0.2, 1.5) * max(nx, ny) * res)
    return occ, float(ox), float(oy), poses, angles, max_range


@needs_native
@settings(max_examples=120, deadline=None)
@given(seed=st.integers(0, 2**32 - 1), res=st.sampled_from([0.05, 0.1, 0.2, 0.37, 1.0]))
def test_native_cast_ranges_matches_reference(seed: int, res: float) -> None:
    import crlam._native as native

    occ, ox, oy, poses, angles, max_range = _random_case(seed, res)
    got = native.cast_ranges(np.ascontiguousarray(occ, dtype=np.uint8), ox, oy, res, poses, angles, max_range)
    assert got.shape == (len(poses), len(angles)) and got.dtype == np.float64
    _compare(got, slab_reference(occ, ox, oy, res, poses, angles, max_range), res, max_range)


@settings(max_examples=120, deadline=None)
@given(seed=st.integers(0, 2**32 - 1), res=st.sampled_from([0.05, 0.1, 0.2, 0.37, 1.0]))
def test_numpy_cast_ranges_matches_reference(seed: int, res: float) -> None:
    occ, ox, oy, poses, angles, max_range = _random_case(seed, res)
    got = cast_ranges_numpy(occ, ox, oy, res, poses, angles, max_range)
    _compare(got, slab_reference(occ, ox, oy, res, poses, angles, max_range), res, max_range)


@pytest.mark.parametrize("backend", ["numpy", pytest.param("native", marks=needs_native)])
def test_axis_aligned_and_special_cases(backend: str) -> None:
    occ = np.zeros((10, 10), dtype=bool)
    occ[:, 9] = True  # east wall, x in [0.9, 1.0)
    occ[5, 5] = True
    world = World(occ, 0.1, np.zeros(2))
    poses = np.array([[0.25, 0.25, 0.0], [0.55, 0.55, 0.0], [-0.5, 0.25, 0.0], [0.25, 0.25, math.pi]])
    r = true_ranges(world, poses, np.array([0.0]), max_range=5.0, backend=backend)
    np.testing.assert_allclose(r[0, 0], 0.65, atol=1e-9)  # to the entry face at x = 0.9
    assert r[1, 0] == 0.0  # starts inside an occupied cell
    np.testing.assert_allclose(r[2, 0], 1.4, atol=1e-9)  # starts outside the grid, enters it
    assert np.isinf(r[3, 0])  # looks west out of the grid: nothing
    short = true_ranges(world, poses[:1], np.array([0.0]), max_range=0.6, backend=backend)
    assert np.isinf(short[0, 0])  # the wall is beyond max_range


@needs_native
def test_native_and_numpy_agree_on_the_museum() -> None:
    world = museum_world(0)
    rng = np.random.default_rng(7)
    iy, ix = np.nonzero(~world.occupied)
    k = rng.choice(len(iy), 20, replace=False)
    xy = world.cell_centers(ix[k], iy[k]) + rng.uniform(-0.02, 0.02, (20, 2))
    poses = np.column_stack([xy, rng.uniform(-math.pi, math.pi, 20)])
    sensor = paper_lidar()
    a = sensor.true_ranges(world, poses, backend="native")
    b = sensor.true_ranges(world, poses, backend="numpy")
    _compare(a, b, world.resolution, sensor.max_range)
