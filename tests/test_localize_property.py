"""Property test of the localizer's inputs (issue 49, with the Rust proptest
``mcl::likelihood::tests::any_pose_and_scan_gives_a_result_or_an_error``): an initial pose and
covariance of any magnitude (huge, tiny, negative, non-finite), maps of any size and resolution,
scans of any length with any readings and bearings, and any odometry. ``Localizer`` either runs
(every estimate it returns is a number, a finite pose when the inputs were finite) or raises a
:class:`crlam.errors.CrlamError`: never a panic (``InternalError``), a bare ``ValueError`` or a
hang. A huge initial covariance once put particles at cells near i64::MAX, where the likelihood
read out of bounds (``crlam localize --initial-cov 1e300 1e300 1e300`` panicked)."""

from __future__ import annotations

import math
import os
from pathlib import Path

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from hypothesis.extra import numpy as hnp

from crlam.errors import CrlamError, InternalError
from crlam.io.nav2 import Nav2Map
from crlam.localize import LocalizeConfig, Localizer
from crlam.localize.map import LocalizationMap, crm_from_nav2

PROPERTY = settings(
    max_examples=int(os.environ.get("CRLAM_FUZZ_EXAMPLES", "150")) // 3,
    deadline=None,
    derandomize=True,
    suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large],
)

ANY_FLOAT = st.one_of(
    st.floats(-10.0, 10.0),
    st.floats(allow_nan=True, allow_infinity=True),
    st.sampled_from([0.0, 1e-300, 1e150, -1e150, 1e300, 1.7e308, 9.3e18, -9.3e18, math.nan, math.inf, -math.inf]),
)
VARIANCE = st.one_of(
    st.floats(0.0, 1.0), st.sampled_from([0.0, 1e-30, 1e6, 1e30, 1e150, 1e300, 1.7e308, -1.0, math.nan, math.inf])
)


def _map(ny: int, nx: int, resolution: float, occupied: list[tuple[int, int]]) -> LocalizationMap:
    occ = np.zeros((ny, nx))
    for iy, ix in occupied:
        occ[iy % ny, ix % nx] = 1.0
    nav = Nav2Map(occupancy=occ, resolution=resolution, origin=np.array([-1.0, -1.0, 0.0]), image_path=Path("hyp.pgm"))
    crm, rect = crm_from_nav2(nav, max_range=4.0)
    return LocalizationMap(crm=crm, rect=rect, source="hypothesis", kind="nav2")


@PROPERTY
@given(
    shape=st.tuples(st.integers(1, 60), st.integers(1, 60)),
    resolution=st.sampled_from([0.05, 0.1, 0.5]),
    occupied=st.lists(st.tuples(st.integers(0, 59), st.integers(0, 59)), max_size=40),
    pose=st.one_of(st.none(), st.tuples(ANY_FLOAT, ANY_FLOAT, ANY_FLOAT)),
    cov=st.one_of(
        st.none(),
        st.tuples(VARIANCE, VARIANCE, VARIANCE),
        hnp.arrays(np.float64, (3, 3), elements=ANY_FLOAT),
    ),
    scans=st.lists(
        st.integers(0, 400).flatmap(
            lambda n: st.tuples(
                st.tuples(ANY_FLOAT, ANY_FLOAT, ANY_FLOAT),
                hnp.arrays(np.float64, n, elements=st.one_of(st.floats(-3.2, 3.2), ANY_FLOAT)),
                hnp.arrays(np.float64, n, elements=st.one_of(st.floats(0.0, 6.0), ANY_FLOAT)),
                st.tuples(ANY_FLOAT, ANY_FLOAT, ANY_FLOAT),
            )
        ),
        min_size=1,
        max_size=3,
    ),
)
def test_the_localizer_runs_or_refuses_any_input(
    shape: tuple[int, int],
    resolution: float,
    occupied: list[tuple[int, int]],
    pose: tuple[float, float, float] | None,
    cov: object,
    scans: list[tuple[tuple[float, float, float], np.ndarray, np.ndarray, tuple[float, float, float]]],
) -> None:
    loc_map = _map(shape[0], shape[1], resolution, occupied)
    config = LocalizeConfig(max_particles=200, min_particles=50, spread_particles=0, max_beams=60, seed=3)
    try:
        loc = Localizer(loc_map, config, initial_pose=pose, initial_cov=None if pose is None else cov, laser_max_range=4.0)
    except InternalError:
        raise
    except CrlamError:
        return
    inputs_finite = True
    for k, (odom, angles, ranges, offset) in enumerate(scans):
        try:
            step = loc.step(odom, angles, ranges, offset, float(k))
        except InternalError:
            raise
        except CrlamError:
            return
        inputs_finite = inputs_finite and all(math.isfinite(v) for v in (*odom, *offset)) and bool(np.isfinite(angles).all())
        assert step.estimate.shape == (3,)
        if inputs_finite and pose is not None and all(math.isfinite(v) for v in pose):
            assert not np.isnan(step.estimate).any()


@pytest.mark.parametrize("variance", [1e300, 1.7e308, 1e30])
def test_a_huge_initial_covariance_runs(variance: float) -> None:
    """The command of the issue: particles spread beyond the map and any grid index."""
    loc_map = _map(40, 40, 0.1, [(i, 0) for i in range(40)] + [(0, i) for i in range(40)])
    config = LocalizeConfig(max_particles=300, min_particles=50, spread_particles=0, seed=1)
    try:
        loc = Localizer(loc_map, config, initial_pose=(0.0, 0.0, 0.0), initial_cov=[variance] * 3, laser_max_range=4.0)
    except CrlamError:
        return  # refusing a covariance whose draws overflow is a clean outcome
    angles = np.linspace(-math.pi, math.pi, 180, endpoint=False)
    for k in range(3):
        step = loc.step((0.1 * k, 0.0, 0.0), angles, np.full(180, 1.5), (0.0, 0.0, 0.0), float(k))
        assert step.estimate.shape == (3,)
