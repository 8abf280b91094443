"""The candidate rule shared by the simulated explorer and the ROS explorer
(crlam.experiments.explore_candidates): how many near and frontier cells it takes, where their
centres are, and that a seed repeats the draw."""

from __future__ import annotations

import numpy as np
import pytest

from crlam.experiments.explore_candidates import pick_candidates, sorted_unique


def _grid() -> tuple[np.ndarray, np.ndarray]:
    """A 20 x 30 window, all reachable; the frontier is its last column."""
    reach = np.ones((20, 30), dtype=bool)
    frontier = np.zeros_like(reach)
    frontier[:, -1] = True
    return reach, frontier


def test_half_near_half_frontier_sorted_and_without_repeats() -> None:
    reach, frontier = _grid()
    c = pick_candidates(reach, frontier, (5, 7), (-1.0, 2.0), 0.5, np.array([2.0, 6.0, 0.3]), 3.0, 10, np.random.default_rng(0))
    assert len(c.wy) == len(c.wx) == len(c.centres) == reach.sum()
    assert np.array_equal(c.idx, np.unique(c.idx)) and len(c.idx) == 10
    is_fr = frontier[c.wy[c.idx], c.wx[c.idx]]
    near = np.hypot(*(c.centres[c.idx] - [2.0, 6.0]).T) <= 3.0
    assert is_fr.sum() == 5 and (near & ~is_fr).sum() == 5  # the frontier column is far from (2, 6)
    # Cell centres: grid origin + (window origin + window cell + 1/2) * resolution.
    k = c.idx[0]
    assert c.centres[k] == pytest.approx([-1.0 + (7 + c.wx[k] + 0.5) * 0.5, 2.0 + (5 + c.wy[k] + 0.5) * 0.5])


def test_a_short_half_is_topped_up_from_the_other() -> None:
    reach, frontier = _grid()
    # Radius 0: no near cell, so every candidate is a frontier cell (the column has 20).
    c = pick_candidates(reach, frontier, (0, 0), (0.0, 0.0), 1.0, np.array([-50.0, -50.0]), 0.0, 12, np.random.default_rng(1))
    assert len(c.idx) == 12 and frontier[c.wy[c.idx], c.wx[c.idx]].all()
    # No frontier: every candidate is near.
    c = pick_candidates(
        reach, np.zeros_like(frontier), (0, 0), (0.0, 0.0), 1.0, np.array([10.0, 10.0]), 100.0, 12, np.random.default_rng(1)
    )
    assert len(c.idx) == 12
    # Fewer cells than candidates: all of them.
    small = np.zeros_like(reach)
    small[3, 4:7] = True
    c = pick_candidates(
        small, np.zeros_like(small), (0, 0), (0.0, 0.0), 1.0, np.array([5.0, 3.0]), 100.0, 12, np.random.default_rng(1)
    )
    assert np.array_equal(c.idx, [0, 1, 2])


def test_the_same_generator_state_draws_the_same_candidates() -> None:
    reach, frontier = _grid()
    args = (reach, frontier, (0, 0), (0.0, 0.0), 0.5, np.array([4.0, 4.0]), 2.0, 8)
    a = pick_candidates(*args, np.random.default_rng(7)).idx
    b = pick_candidates(*args, np.random.default_rng(7)).idx
    c = pick_candidates(*args, np.random.default_rng(8)).idx
    assert np.array_equal(a, b) and not np.array_equal(a, c)


@pytest.mark.parametrize("values", [[], [3], [5, 1, 5, 2, 1], [0, 0, 0]])
def test_sorted_unique_is_numpy_unique(values: list[int]) -> None:
    a = np.array(values, dtype=np.int64)
    assert np.array_equal(sorted_unique(a), np.unique(a))
