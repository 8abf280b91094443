"""The poses of the scans a filter skips (crlam.slam.fill) and how SlamRun records them."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from crlam.cli import main
from crlam.errors import CrlamError
from crlam.io.carmen import read_scans
from crlam.io.tum import read_tum
from crlam.pose import between, compose, wrap_angle
from crlam.sim.simulate import SimulationConfig, simulate, write_simulation
from crlam.slam import SlamConfig, SlamRun
from crlam.slam.fill import FILLS, fill_rule, fill_skipped


def _straight(n: int, step: float = 0.1) -> tuple[np.ndarray, np.ndarray]:
    """Odometry along x, one scan every 0.1 s."""
    odometry = np.column_stack([np.arange(n) * step, np.zeros(n), np.zeros(n)])
    return odometry, np.arange(n) * 0.1


def test_the_correction_is_shared_by_the_distance_towards_the_next_update() -> None:
    odometry, stamps = _straight(11)
    processed = np.zeros(11, dtype=bool)
    processed[[0, 5, 10]] = True
    # The filter says the robot went 0.6 m, not 0.5 m, in the first segment and turned 0.1 rad.
    path = np.array([[0.0, 0.0, 0.0], [0.6, 0.05, 0.1], [0.6 + 0.5 * np.cos(0.1), 0.05 + 0.5 * np.sin(0.1), 0.1]])
    poses = fill_skipped(path, processed, odometry, stamps, "interpolate", 0.5, 0.25)
    np.testing.assert_array_equal(poses[processed], path)
    for i in range(1, 5):
        share = i / 5  # 0.1 m per scan of the 0.5 m to the update
        np.testing.assert_allclose(poses[i], [i * 0.1 + share * 0.1, share * 0.05, share * 0.1], atol=1e-12)
    # Second segment: the odometry prediction from scan 5 lands on the estimate of scan 10, so
    # there is nothing to correct and the scans follow the odometry.
    for i in range(6, 10):
        np.testing.assert_allclose(poses[i], compose(path[1], [(i - 5) * 0.1, 0.0, 0.0]), atol=1e-12)


def test_odometry_rule_and_the_last_segment_carry_the_estimate_by_odometry() -> None:
    odometry, stamps = _straight(9)
    processed = np.zeros(9, dtype=bool)
    processed[[0, 4]] = True
    path = np.array([[0.0, 0.0, 0.0], [0.5, -0.1, 0.2]])
    carried = compose(np.repeat(path[[0]], 9, 0), odometry)
    carried[4:] = compose(np.repeat(path[[1]], 5, 0), between(np.repeat(odometry[[4]], 5, 0), odometry[4:]))
    np.testing.assert_allclose(fill_skipped(path, processed, odometry, stamps, "odometry", 0.5, 0.25), carried, atol=1e-12)
    interpolated = fill_skipped(path, processed, odometry, stamps, "interpolate", 0.5, 0.25)
    np.testing.assert_allclose(interpolated[4:], carried[4:], atol=1e-12)  # nothing after the last update
    assert not np.allclose(interpolated[1:4], carried[1:4])


def test_turning_on_the_spot_shares_by_angle_and_standing_still_by_time() -> None:
    # Scans 0-4 turn 0.05 rad each on the spot, scans 4-8 stand still (the shares do not depend
    # on why a scan was processed).
    odometry = np.zeros((9, 3))
    odometry[:5, 2] = np.arange(5) * 0.05
    odometry[5:, 2] = 0.2
    stamps = np.array([0.0, 0.1, 0.2, 0.3, 0.4, 0.5, 1.5, 1.7, 2.5])
    processed = np.zeros(9, dtype=bool)
    processed[[0, 4, 8]] = True
    path = np.array([[0.0, 0.0, 0.0], [0.0, 0.0, 0.16], [0.1, 0.0, 0.16]])
    poses = fill_skipped(path, processed, odometry, stamps, "interpolate", 0.5, 0.25)
    for i in range(1, 4):
        assert poses[i, 2] == pytest.approx(i * 0.05 + (i / 4) * (0.16 - 0.2), abs=1e-12)
    for i in range(5, 8):
        assert poses[i, 0] == pytest.approx(0.1 * (stamps[i] - stamps[4]) / (stamps[8] - stamps[4]), abs=1e-12)


finite = st.floats(-2.0, 2.0, allow_nan=False)


@settings(max_examples=60, deadline=None)
@given(
    steps=st.lists(st.tuples(finite, finite, st.floats(-0.3, 0.3)), min_size=2, max_size=25),
    chosen=st.lists(st.booleans(), min_size=25, max_size=25),
    corrections=st.lists(st.tuples(finite, finite, st.floats(-1.0, 1.0)), min_size=25, max_size=25),
)
def test_properties_of_the_interpolated_fill(
    steps: list[tuple[float, float, float]], chosen: list[bool], corrections: list[tuple[float, float, float]]
) -> None:
    n = len(steps) + 1
    odometry = np.zeros((n, 3))
    for i, s in enumerate(steps):
        odometry[i + 1] = compose(odometry[i], np.array(s) * 0.1)
    stamps = np.arange(n) * 0.1
    processed = np.array([True] + chosen[: n - 1])
    index = np.flatnonzero(processed)
    # Estimates consistent with the odometry: no correction, so both rules agree.
    consistent = compose(np.repeat([[0.3, -0.2, 1.0]], index.size, 0), odometry[index])
    a = fill_skipped(consistent, processed, odometry, stamps, "interpolate", 0.5, 0.25)
    b = fill_skipped(consistent, processed, odometry, stamps, "odometry", 0.5, 0.25)
    np.testing.assert_allclose(a, b, atol=1e-9)
    # Any estimates: processed scans keep theirs; a skipped scan's pose lies between the odometry
    # fill (share 0) and the fill moved by the whole correction (share 1).
    path = consistent + np.array(corrections[: index.size]) * 0.2
    a = fill_skipped(path, processed, odometry, stamps, "interpolate", 0.5, 0.25)
    b = fill_skipped(path, processed, odometry, stamps, "odometry", 0.5, 0.25)
    np.testing.assert_array_equal(a[processed], path)
    segment = np.cumsum(processed) - 1
    for i in np.flatnonzero(~processed):
        k = segment[i]
        if k + 1 >= index.size:
            np.testing.assert_allclose(a[i], b[i], atol=1e-12)
            continue
        predicted = compose(path[k], between(odometry[index[k]], odometry[index[k + 1]]))
        full = np.r_[path[k + 1, :2] - predicted[:2], wrap_angle(path[k + 1, 2] - predicted[2])]
        moved = np.r_[a[i, :2] - b[i, :2], wrap_angle(a[i, 2] - b[i, 2])]
        share = np.array([m / f for m, f in zip(moved, full) if abs(f) > 1e-9])
        assert np.all((share >= -1e-9) & (share <= 1 + 1e-9))
        if share.size:
            assert np.ptp(share) < 1e-6  # one share for x, y and heading


def test_bad_input_is_a_clean_error() -> None:
    odometry, stamps = _straight(4)
    processed = np.array([True, False, True, False])
    with pytest.raises(CrlamError, match="2 processed scans"):
        fill_skipped(np.zeros((3, 3)), processed, odometry, stamps, "interpolate", 0.5, 0.25)
    with pytest.raises(CrlamError, match="first scan"):
        fill_skipped(np.zeros((1, 3)), np.array([False, True, False, False]), odometry, stamps, "odometry", 0.5, 0.25)
    with pytest.raises(CrlamError, match="unknown fill"):
        fill_skipped(np.zeros((2, 3)), processed, odometry, stamps, "spline", 0.5, 0.25)
    with pytest.raises(CrlamError, match="fill"):
        SlamConfig(fill="spline")
    assert [fill_rule(f) for f in FILLS][0].endswith("get no correction")


@pytest.fixture(scope="module")
def office(tmp_path_factory: pytest.TempPathFactory) -> Path:
    d = tmp_path_factory.mktemp("office_fill")
    write_simulation(simulate(SimulationConfig(world="office", n_scans=160, seed=4)), d)
    return d


TRIGGERS = {"linear_update": 0.3, "angular_update": 0.3, "particles": 8, "seed": 2}


def test_slam_run_records_the_fill_and_keeps_the_online_estimates(office: Path) -> None:
    runs = {}
    for fill in FILLS:
        run = SlamRun(SlamConfig(fill=fill, **TRIGGERS))
        for s in read_scans(office / "log.clf"):
            run.step(s.odom, s.angles, s.ranges, s.laser_offset, s.timestamp)
        runs[fill] = run
    online = np.array(runs["interpolate"].estimates)
    # The same filter either way; the odometry rule is the filter's own online carry.
    np.testing.assert_array_equal(online, np.array(runs["odometry"].estimates))
    np.testing.assert_allclose(runs["odometry"].trajectory()[1], online, atol=1e-9)
    interpolated = runs["interpolate"].trajectory()[1]
    processed = np.array(runs["interpolate"].processed)
    assert 10 < processed.sum() < processed.size / 2
    np.testing.assert_array_equal(interpolated[processed], online[processed])
    assert np.abs(interpolated[~processed] - online[~processed]).max() > 1e-4
    # The other recorded estimates follow the same rule.
    best = runs["interpolate"].best_path_trajectory()[1]
    assert not np.allclose(best[~processed], runs["odometry"].best_path_trajectory()[1][~processed])


def test_the_run_folder_records_the_rule_and_the_cli_flag_sets_it(office: Path, tmp_path: Path) -> None:
    common = ["--particles", "8", "--linear-update", "0.3", "--angular-update", "0.3", "--max-scans", "60", "--quiet"]
    for fill in FILLS:
        out = tmp_path / fill
        argv = ["slam", str(office / "log.clf"), "--out", str(out), "--fill", fill, *common]
        assert main([*argv, "--reference", str(office / "groundtruth.tum")]) == 0
        metrics = json.loads((out / "metrics.json").read_text())
        assert metrics["fill_rule"] == fill_rule(fill)
        assert "fill" not in " ".join(metrics["deviations_from_paper"])
        assert f'fill = "{fill}"' in (out / "config.toml").read_text()
    again = tmp_path / "again"
    first = tmp_path / "odometry"
    assert main(["slam", str(office / "log.clf"), "--out", str(again), "--config", str(first / "config.toml"), "--quiet"]) == 0
    assert (again / "trajectory.tum").read_bytes() == (first / "trajectory.tum").read_bytes()
    assert not np.allclose(read_tum(first / "trajectory.tum").poses, read_tum(tmp_path / "interpolate" / "trajectory.tum").poses)
