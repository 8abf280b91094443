"""Estimates beside the weighted mean: the mode-seeking pose and the lineage smoother."""

from __future__ import annotations

import json
from pathlib import Path

try:
    import tomllib
except ModuleNotFoundError:  # Python 3.10
    import tomli as tomllib

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from crlam.errors import CrlamError
from crlam.experiments.slam_run import run_slam_log
from crlam.io.carmen import read_scans
from crlam.io.tum import read_tum
from crlam.pose import between, compose
from crlam.sim.simulate import SimulationConfig, simulate, write_simulation
from crlam.slam import SlamConfig, SlamRun, mode_seeking_pose

INF = (float("inf"), float("inf"))


def weighted_mean(poses: np.ndarray, w: np.ndarray) -> np.ndarray:
    w = w / w.sum()
    return np.array([w @ poses[:, 0], w @ poses[:, 1], np.arctan2(w @ np.sin(poses[:, 2]), w @ np.cos(poses[:, 2]))])


def test_two_groups_give_the_heavier_groups_mean_not_the_point_between() -> None:
    a = np.array([[0.00, 0.0, 0.00], [0.01, 0.0, 0.00], [0.02, 0.0, 0.01]])
    b = np.array([[0.50, 0.0, 0.05], [0.51, 0.01, 0.05]])
    wa, wb = np.array([0.1, 0.3, 0.2]), np.array([0.25, 0.15])
    poses, w = np.vstack([a, b]), np.concatenate([wa, wb])
    m = mode_seeking_pose(poses, w, (0.05, 0.025))
    np.testing.assert_allclose(m, weighted_mean(a, wa), atol=1e-3)
    # The weighted mean sits 0.2 m from group A (0.003 + 0.004 + 0.125 + 0.0765), where no particle is.
    assert weighted_mean(poses, w)[0] == pytest.approx(0.2085, abs=1e-9)
    # Swap the group weights: the mode moves to B.
    m = mode_seeking_pose(poses, np.concatenate([wa / 3, wb * 2]), (0.05, 0.025))
    np.testing.assert_allclose(m, weighted_mean(b, wb), atol=1e-3)


def test_limits_of_the_bandwidth() -> None:
    rng = np.random.default_rng(2)
    poses = np.column_stack([rng.normal(0, 0.3, 20), rng.normal(0, 0.3, 20), rng.uniform(-3.1, 3.1, 20)])
    w = rng.uniform(0.1, 1.0, 20)
    np.testing.assert_allclose(mode_seeking_pose(poses, w, INF), weighted_mean(poses, w), atol=1e-12)
    np.testing.assert_allclose(mode_seeking_pose(poses, w, (1e-6, 1e-6)), poses[np.argmax(w)], atol=1e-12)


pose_st = st.tuples(
    st.floats(-1.0, 1.0),
    st.floats(-1.0, 1.0),
    st.floats(-3.0, 3.0),
)


@settings(max_examples=60, deadline=None)
@given(
    st.lists(pose_st, min_size=1, max_size=12),
    st.floats(-5, 5),
    st.floats(-5, 5),
    st.floats(-3.1, 3.1),
    st.floats(0.01, 100.0),
    st.integers(0, 2**31),
)
def test_equivariant_under_rigid_motion_and_weight_scale(
    pose_list: list[tuple[float, float, float]], tx: float, ty: float, tth: float, scale: float, seed: int
) -> None:
    poses = np.array(pose_list)
    w = np.random.default_rng(seed).uniform(0.05, 1.0, len(poses))
    bw = (0.3, 0.4)
    m = mode_seeking_pose(poses, w, bw)
    t = np.array([tx, ty, tth])
    moved = mode_seeking_pose(compose(t, poses), scale * w, bw)
    d = between(compose(t, m), moved)
    assert np.hypot(d[0], d[1]) < 1e-6 and abs(d[2]) < 1e-6
    # A kernel-weighted mean: inside the bounding box of the positions.
    assert poses[:, 0].min() - 1e-9 <= m[0] <= poses[:, 0].max() + 1e-9
    assert poses[:, 1].min() - 1e-9 <= m[1] <= poses[:, 1].max() + 1e-9


@pytest.mark.parametrize(
    ("poses", "weights", "bandwidth"),
    [
        (np.zeros((0, 3)), np.zeros(0), (0.05, 0.025)),
        (np.zeros((2, 3)), np.ones(3), (0.05, 0.025)),
        (np.zeros((2, 2)), np.ones(2), (0.05, 0.025)),
        (np.zeros(3), np.ones(1), (0.05, 0.025)),
        (np.zeros((2, 3)), np.zeros(2), (0.05, 0.025)),
        (np.zeros((2, 3)), np.array([1.0, -1.0]), (0.05, 0.025)),
        (np.zeros((2, 3)), np.array([1.0, np.nan]), (0.05, 0.025)),
        (np.array([[0.0, np.inf, 0.0]]), np.ones(1), (0.05, 0.025)),
        (np.zeros((2, 3)), np.ones(2), (0.0, 0.025)),
        (np.zeros((2, 3)), np.ones(2), (0.05, float("nan"))),
    ],
)
def test_bad_input_is_a_clean_error(poses: np.ndarray, weights: np.ndarray, bandwidth: tuple[float, float]) -> None:
    with pytest.raises(CrlamError):
        mode_seeking_pose(poses, weights, bandwidth)


@pytest.fixture(scope="module")
def office(tmp_path_factory: pytest.TempPathFactory) -> Path:
    d = tmp_path_factory.mktemp("office_mode")
    write_simulation(simulate(SimulationConfig(world="office", n_scans=80, seed=5)), d)
    return d


def _feed(log: Path, config: SlamConfig, n: int = 60) -> SlamRun:
    run = SlamRun(config)
    for s in list(read_scans(log))[:n]:
        run.step(s.odom, s.angles, s.ranges, s.laser_offset, s.timestamp)
    return run


TRIGGERS = {"linear_update": 0.3, "angular_update": 0.3, "init_sigma": (0.05, 0.05, 0.02)}


def test_infinite_bandwidth_reproduces_the_weighted_mean_trajectory(office: Path) -> None:
    # The mode is taken from the set the filter's own estimate was taken from (before
    # resampling), so with an infinite kernel the two trajectories agree scan by scan.
    run = _feed(office / "log.clf", SlamConfig(particles=8, seed=3, mode_bandwidth=INF, **TRIGGERS))
    np.testing.assert_allclose(run.mode_trajectory()[1], run.trajectory()[1], atol=1e-9)
    assert run.filter is not None
    poses, w = run.filter.weighed_set()
    assert poses.shape == (8, 3) and w.sum() == pytest.approx(1.0)


def test_mode_records_follow_the_fill_rule_and_reach_the_run_folder(office: Path, tmp_path: Path) -> None:
    config = SlamConfig(particles=8, seed=3, fill="odometry", **TRIGGERS)
    run = _feed(office / "log.clf", config)
    processed = np.flatnonzero(run.processed)
    stamps, mode = run.mode_trajectory()
    np.testing.assert_array_equal(mode[processed], np.array([r.mode for r in run.particle_sets]))
    i = int(np.argmin(run.processed[1:])) + 1
    j = int(np.flatnonzero(run.processed[:i])[-1])
    scans = list(read_scans(office / "log.clf"))
    np.testing.assert_allclose(mode[i], compose(mode[j], between(scans[j].odom, scans[i].odom)), atol=1e-12)
    # The initial spread (5 cm) is comparable to the bandwidth: the mode is not the mean there.
    assert not np.allclose(mode[processed[0]], run.trajectory()[1][processed[0]], atol=1e-6)

    out = tmp_path / "run"
    run_slam_log(office / "log.clf", out, config, reference=office / "groundtruth.tum", max_scans=60, progress=False)
    np.testing.assert_allclose(read_tum(out / "estimates/mode.tum").poses, mode, atol=1e-6)
    rows = np.genfromtxt(out / "steps.csv", delimiter=",", names=True)
    np.testing.assert_allclose(rows["mode_x"], mode[processed, 0], atol=1e-6)
    m = json.loads((out / "metrics.json").read_text())
    assert m["reference_mode"]["rmse_position_m"] > 0
    assert tomllib.loads((out / "config.toml").read_text())["slam"]["mode_bandwidth"] == [0.05, 0.025]


def test_ogm_records_the_mode_too(office: Path) -> None:
    run = _feed(office / "log.clf", SlamConfig(method="ogm", particles=4, seed=1, resolution=0.1, **TRIGGERS), n=30)
    assert run.filter is not None
    _, w = run.filter.weighed_set()
    assert w.sum() == pytest.approx(1.0)
    assert np.isfinite(run.mode_trajectory()[1]).all()


def test_ogm_spread_uses_the_smoothed_weights_the_filter_uses(office: Path) -> None:
    # RBPF-OGM stores log-likelihoods before GMapping's weight smoothing (divided by ogain · n);
    # the spread must weigh the particles as the estimate does, or one particle takes all the
    # weight and the set looks collapsed while the estimate averages a wide set.
    config = SlamConfig(method="ogm", particles=6, seed=2, resolution=0.1, **TRIGGERS)
    scans = list(read_scans(office / "log.clf"))[:40]
    run = SlamRun(config)
    checked = 0
    for s in scans:
        step = run.step(s.odom, s.angles, s.ranges, s.laser_offset, s.timestamp)
        if not step.processed or step.resampled or len(run.particle_sets) < 2:
            continue
        assert run.filter is not None
        poses, w = run.filter.weighed_set()
        np.testing.assert_allclose(run.filter.weights(), w, atol=1e-12)
        expected = np.sqrt(w @ np.sum((poses[:, :2] - w @ poses[:, :2]) ** 2, axis=1))
        assert run.particle_sets[-1].spread_xy == pytest.approx(expected, rel=1e-9, abs=1e-12)
        # The stored log-weights are sharper than the smoothed weights.
        raw = np.exp(run.filter.log_weights() - np.max(run.filter.log_weights()))
        assert np.max(raw / raw.sum()) >= np.max(w) - 1e-12
        checked += 1
    assert checked > 0
    assert sum(float(x) for x in run.filter.weights()) == pytest.approx(1.0)  # type: ignore[union-attr]


def test_lineage_smoother_limits_and_lags(office: Path) -> None:
    log = office / "log.clf"
    cfg = {"particles": 8, "seed": 3, **TRIGGERS}
    lag0 = _feed(log, SlamConfig(smoothing_lag=0, **cfg))
    traj = lag0.smoothed_trajectory()
    assert traj is not None
    # Lag 0 weighs each scan's own particles with their own weights: the weighted mean.
    np.testing.assert_allclose(traj[1], lag0.trajectory()[1], atol=1e-9)
    full = _feed(log, SlamConfig(**cfg))
    n_processed = int(sum(full.processed))
    sm_full = full.smoothed_trajectory()
    assert sm_full is not None
    processed = np.flatnonzero(full.processed)
    # The last processed scan is weighed with its own weights in every variant.
    np.testing.assert_allclose(sm_full[1][processed[-1]], full.trajectory()[1][processed[-1]], atol=1e-9)
    # Hindsight changes earlier scans (lineages that died drop out).
    assert not np.allclose(sm_full[1][processed[:-1]], full.trajectory()[1][processed[:-1]], atol=1e-6)
    # A lag longer than the run is full smoothing; a lag L agrees with it on the last L scans.
    long = _feed(log, SlamConfig(smoothing_lag=n_processed + 5, **cfg)).smoothed_trajectory()
    assert long is not None
    np.testing.assert_allclose(long[1], sm_full[1], atol=1e-12)
    lag3 = _feed(log, SlamConfig(smoothing_lag=3, **cfg)).smoothed_trajectory()
    assert lag3 is not None
    np.testing.assert_allclose(lag3[1][processed[-3:]], sm_full[1][processed[-3:]], atol=1e-12)
    # One particle: every smoother is its path.
    one = _feed(log, SlamConfig(particles=1, linear_update=0.3, angular_update=0.3))
    sm_one = one.smoothed_trajectory()
    assert sm_one is not None
    np.testing.assert_allclose(sm_one[1], one.best_path_trajectory()[1], atol=1e-12)
    # The odometry proposal draws from no fitted Gaussian: no proposal means to smooth.
    assert full.smoothed_trajectory(proposal_means=True) is None


def test_smoothed_trajectories_reach_the_run_folder(office: Path, tmp_path: Path) -> None:
    out = tmp_path / "run"
    cfg = SlamConfig(particles=6, seed=2, proposal="likelihood_mode", smoothing_lag=5, **TRIGGERS)
    run = run_slam_log(office / "log.clf", out, cfg, reference=office / "groundtruth.tum", max_scans=50, progress=False).run
    for name, use_means in (("estimates/smoothed.tum", False), ("estimates/smoothed_means.tum", True)):
        traj = run.smoothed_trajectory(proposal_means=use_means)
        assert traj is not None
        np.testing.assert_allclose(read_tum(out / name).poses, traj[1], atol=1e-6)
    m = json.loads((out / "metrics.json").read_text())
    assert {"reference_smoothed", "reference_smoothed_means"} <= set(m)
    assert "smoothing_lag = 5" in (out / "config.toml").read_text()


@pytest.mark.parametrize("lag", [-1, 1.5, True])
def test_bad_smoothing_lag_is_a_config_error(lag: object) -> None:
    with pytest.raises(CrlamError, match="smoothing_lag"):
        SlamConfig(smoothing_lag=lag)  # type: ignore[arg-type]
