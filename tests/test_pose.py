"""Property tests of the SE(2) pose algebra."""

from __future__ import annotations

import numpy as np
from hypothesis import given
from hypothesis import strategies as st
from hypothesis.extra.numpy import arrays

from crlam.pose import between, compose, inverse, transform_points, wrap_angle

coord = st.floats(-1e3, 1e3, allow_nan=False)
angle = st.floats(-20.0, 20.0, allow_nan=False)
pose = st.tuples(coord, coord, angle).map(lambda t: np.array(t, dtype=np.float64))


def close(a: np.ndarray, b: np.ndarray) -> bool:
    d = np.asarray(a) - np.asarray(b)
    d[..., 2] = wrap_angle(d[..., 2])
    return bool(np.allclose(d, 0.0, atol=1e-7))


@given(pose)
def test_inverse_is_a_two_sided_inverse(a: np.ndarray) -> None:
    assert close(compose(a, inverse(a)), np.zeros(3))
    assert close(compose(inverse(a), a), np.zeros(3))


@given(pose, pose)
def test_between_then_compose_round_trips(a: np.ndarray, b: np.ndarray) -> None:
    assert close(compose(a, between(a, b)), b)


@given(pose, pose, pose)
def test_composition_is_associative(a: np.ndarray, b: np.ndarray, c: np.ndarray) -> None:
    assert close(compose(compose(a, b), c), compose(a, compose(b, c)))


@given(pose, arrays(np.float64, (5, 2), elements=coord))
def test_transform_points_matches_composition(a: np.ndarray, pts: np.ndarray) -> None:
    as_poses = np.concatenate([pts, np.zeros((5, 1))], axis=1)
    np.testing.assert_allclose(transform_points(a, pts), compose(a, as_poses)[:, :2], atol=1e-7)


@given(st.floats(-1e4, 1e4, allow_nan=False))
def test_wrap_angle_range_and_equivalence(t: float) -> None:
    w = float(wrap_angle(t))
    assert -np.pi < w <= np.pi
    assert np.isclose(np.cos(w), np.cos(t), atol=1e-6) and np.isclose(np.sin(w), np.sin(t), atol=1e-6)


def test_broadcasting_over_leading_axes() -> None:
    a = np.random.default_rng(0).normal(size=(4, 7, 3))
    assert compose(a, inverse(a)).shape == (4, 7, 3)
    assert close(compose(a, inverse(a)), np.zeros((4, 7, 3)))
