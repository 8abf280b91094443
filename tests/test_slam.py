"""SLAM runs end to end: the run folder, the CLI, config checks, and a smoke test on ACES."""

from __future__ import annotations

import json
import re
from pathlib import Path

try:
    import tomllib
except ModuleNotFoundError:  # Python 3.10
    import tomli as tomllib
from typing import Any

import numpy as np
import pytest

from crlam.cli import main
from crlam.errors import ConfigError
from crlam.eval.trajectory import relations_error
from crlam.experiments.slam_run import run_slam_log
from crlam.io.carmen import read_scans
from crlam.io.relations import read_relations, write_relations
from crlam.io.tum import read_tum
from crlam.pose import between, compose
from crlam.sim.simulate import SimulationConfig, simulate, write_simulation
from crlam.slam import SlamConfig, SlamRun, particle_spread


@pytest.fixture(scope="module")
def office(tmp_path_factory: pytest.TempPathFactory) -> Path:
    d = tmp_path_factory.mktemp("office")
    write_simulation(simulate(SimulationConfig(world="office", n_scans=120, seed=4)), d)
    return d


def _slam_paper(office: Path) -> list[str]:
    """``crlam slam`` on the office log with the paper's settings (the tests below were written for
    them) and the paper's reading of the laser mount: the log's own (``--laser-mount data``, as in
    docs/method/lidar-readings.md's paper run). The mount check (an ICP over the log's first
    scans, tested in test_lidar_readings.py) would cost each of these runs more than its filter."""
    return ["slam", str(office / "log.clf"), "--preset", "paper", "--laser-mount", "data"]


def test_run_folder_is_complete_and_beats_odometry(office: Path, tmp_path: Path) -> None:
    # Relations between ground-truth poses 10 scans apart, as the real logs' relations files.
    gt = read_tum(office / "groundtruth.tum")
    write_relations(tmp_path / "gt.relations", gt.timestamps[:-10], gt.timestamps[10:], between(gt.poses[:-10], gt.poses[10:]))
    run_slam_log(
        office / "log.clf",
        tmp_path,
        SlamConfig(particles=20, seed=1),
        reference=office / "groundtruth.tum",
        relations=tmp_path / "gt.relations",
        progress=False,
    )
    for name in (
        "config.toml",
        "trajectory.tum",
        "estimates/best_path.tum",
        "relations_errors.png",
        "metrics.json",
        "map.pgm",
        "map.yaml",
        "belief.npz",
        "trajectory.png",
        "errors.png",
    ):
        assert (tmp_path / name).stat().st_size > 0, name
    m = json.loads((tmp_path / "metrics.json").read_text())
    for key in ("wall_time_s", "scans_per_s", "peak_rss_mb", "n_scans", "n_processed", "neff_mean", "n_resamples", "reference"):
        assert key in m, key
    assert m["relations"]["n"] == m["relations_best_path"]["n"] == 110
    path = read_tum(tmp_path / "estimates/best_path.tum")
    assert path.poses.shape == (120, 3) and np.array_equal(path.timestamps, read_tum(tmp_path / "trajectory.tum").timestamps)
    assert m["n_scans"] == m["n_processed"] == 120
    traj = read_tum(tmp_path / "trajectory.tum")
    assert traj.poses.shape == (120, 3)
    gt, odo = read_tum(office / "groundtruth.tum"), read_tum(office / "odometry.tum")
    odo_rmse = float(np.sqrt(np.mean(np.sum((odo.poses[:, :2] - gt.poses[:, :2]) ** 2, axis=1))))
    assert m["reference"]["rmse_position_m"] < odo_rmse, (m["reference"], odo_rmse)
    assert m["reference_best_path"]["rmse_position_m"] < odo_rmse, (m["reference_best_path"], odo_rmse)
    assert "[slam]" in (tmp_path / "config.toml").read_text()


def test_windowed_and_full_ray_kernels_track_alike(office: Path, tmp_path: Path) -> None:
    """The default batch kernel and the reference sweep weigh and update alike to rounding; over
    a short run the filter makes the same choices, so the trajectories coincide."""
    traj = {}
    for kernel in ("windowed", "full_ray"):
        out = tmp_path / kernel
        run_slam_log(office / "log.clf", out, SlamConfig(particles=10, seed=2, batch_kernel=kernel), max_scans=60, progress=False)
        traj[kernel] = read_tum(out / "trajectory.tum").poses
        assert f'batch_kernel = "{kernel}"' in (out / "config.toml").read_text()
    assert traj["windowed"].shape == (60, 3)
    np.testing.assert_allclose(traj["windowed"], traj["full_ray"], rtol=0, atol=1e-6)


def test_triggers_carry_odometry_between_processed_scans(office: Path, tmp_path: Path) -> None:
    res = run_slam_log(
        office / "log.clf", tmp_path, SlamConfig(particles=5, linear_update=0.3, angular_update=0.3), progress=False
    )
    m = res.metrics
    assert m["n_scans"] == 120 and 2 <= m["n_processed"] < 120
    assert any("linear_update" in d for d in m["deviations_from_paper"])
    assert read_tum(tmp_path / "trajectory.tum").poses.shape == (120, 3)


def _feed(scans: list[Any], config: SlamConfig) -> SlamRun:
    """A SlamRun fed every scan of ``scans``."""
    run = SlamRun(config)
    for s in scans:
        run.step(s.odom, s.angles, s.ranges, s.laser_offset, s.timestamp)
    return run


def test_best_path_trajectory_follows_the_fill_rule(office: Path, tmp_path: Path) -> None:
    scans = list(read_scans(office / "log.clf"))[:60]

    # One particle: its path and the weighted mean are the same poses.
    one = _feed(scans, SlamConfig(particles=1, linear_update=0.3, angular_update=0.3))
    np.testing.assert_allclose(one.best_path_trajectory()[1], one.trajectory()[1], atol=1e-9)
    run = _feed(scans, SlamConfig(particles=8, seed=3, linear_update=0.3, angular_update=0.3, fill="odometry"))
    assert run.filter is not None
    processed = np.array(run.processed)
    assert 2 <= processed.sum() < len(scans)
    stamps, poses = run.best_path_trajectory()
    np.testing.assert_array_equal(poses[processed], run.filter.best_path())
    i = int(np.argmin(processed[1:])) + 1  # an unprocessed scan
    j = int(np.flatnonzero(processed[:i])[-1])  # the processed scan before it
    expected = compose(poses[j], between(scans[j].odom, scans[i].odom))
    np.testing.assert_allclose(poses[i], expected, atol=1e-12)
    assert np.array_equal(stamps, run.trajectory()[0])


def test_best_path_means_are_the_proposal_means_of_the_same_lineage(office: Path, tmp_path: Path) -> None:
    scans = list(read_scans(office / "log.clf"))[:60]

    # The odometry fill between processed scans, whose rule tests/test_fill.py checks in full.
    triggers = {"linear_update": 0.3, "angular_update": 0.3, "particles": 6, "seed": 3, "fill": "odometry"}
    # The odometry proposal and a kept match have no means apart from their poses.
    assert _feed(scans, SlamConfig(**triggers)).best_path_means_trajectory() is None
    kept_match = SlamConfig(proposal="likelihood_mode", proposal_pose="match", **triggers)
    assert _feed(scans, kept_match).best_path_means_trajectory() is None
    for method in ("clam", "ogm"):
        extra = {"proposal": "likelihood_mode"} if method == "clam" else {}
        run = _feed(scans, SlamConfig(method=method, **extra, **triggers))
        assert run.filter is not None
        means_traj = run.best_path_means_trajectory()
        assert means_traj is not None
        stamps, means = means_traj
        _, path = run.best_path_trajectory()
        processed = np.array(run.processed)
        assert 2 <= processed.sum() < len(scans)
        np.testing.assert_array_equal(means[processed], run.filter.best_path_means())
        assert np.array_equal(stamps, run.trajectory()[0])
        k = np.flatnonzero(processed)
        # The first scan is not proposed; every later pose is a draw near (not at) its mean.
        np.testing.assert_array_equal(means[k[0]], path[k[0]])
        gap = np.hypot(*(means[k[1:], :2] - path[k[1:], :2]).T)
        assert np.all(gap > 0) and np.all(gap < 0.2), (method, gap)
        # Between processed scans, the same odometry fill as the path's.
        i = int(np.argmin(processed[1:])) + 1
        j = int(np.flatnonzero(processed[:i])[-1])
        np.testing.assert_allclose(means[i], compose(means[j], between(scans[j].odom, scans[i].odom)), atol=1e-12)
    out = tmp_path / "run"
    gt = read_tum(office / "groundtruth.tum")
    write_relations(tmp_path / "gt.relations", gt.timestamps[:-10], gt.timestamps[10:], between(gt.poses[:-10], gt.poses[10:]))
    run_slam_log(
        office / "log.clf",
        out,
        SlamConfig(proposal="likelihood_mode", **triggers),
        reference=office / "groundtruth.tum",
        relations=tmp_path / "gt.relations",
        max_scans=60,
        progress=False,
    )
    written = read_tum(out / "estimates/best_path_means.tum")
    assert written.poses.shape == (60, 3)
    m = json.loads((out / "metrics.json").read_text())
    assert m["relations_best_path_means"]["n"] == m["relations_best_path"]["n"] > 0
    assert m["reference_best_path_means"]["rmse_position_m"] != m["reference_best_path"]["rmse_position_m"]


def test_particle_spread_matches_hand_values() -> None:
    # Two equally weighted particles 2 m apart, headings +-0.3 rad: RMS distance 1 m, R = cos 0.3.
    poses = np.array([[1.0, 5.0, 0.3], [3.0, 5.0, -0.3]])
    xy, th = particle_spread(poses, np.array([7.0, 7.0]))
    assert xy == pytest.approx(1.0)
    assert th == pytest.approx(np.sqrt(-2 * np.log(np.cos(0.3))))
    # Weights 3:1 (log-weights unnormalised): the mean sits 0.5 m from the heavier particle.
    xy, _ = particle_spread(poses, np.log([3.0, 1.0]) - 40.0)
    assert xy == pytest.approx(np.sqrt(0.75 * 0.5**2 + 0.25 * 1.5**2))
    # A headings set across ±π is one cluster, not a spread of 2π.
    xy, th = particle_spread(np.array([[0.0, 0.0, np.pi - 0.01], [0.0, 0.0, -np.pi + 0.01]]), np.zeros(2))
    assert xy == 0.0 and th == pytest.approx(0.01, rel=1e-3)


def test_particle_set_records_and_max_weight_trajectory(office: Path, tmp_path: Path) -> None:
    scans = list(read_scans(office / "log.clf"))[:60]
    config = SlamConfig(
        particles=8, seed=3, linear_update=0.3, angular_update=0.3, init_sigma=(0.05, 0.05, 0.02), fill="odometry"
    )
    run = _feed(scans, config)
    assert run.filter is not None
    processed = np.flatnonzero(run.processed)
    assert [r.scan_index for r in run.particle_sets] == processed.tolist()
    np.testing.assert_array_equal(np.array([r.estimate for r in run.particle_sets]), run.trajectory()[1][processed])
    # The initial spread shows; a resampling onto one parent collapses the set (N_eff = 1 here).
    assert run.particle_sets[0].spread_xy > 0.05 and all(r.spread_xy >= 0 and r.spread_theta >= 0 for r in run.particle_sets)
    assert any(r.neff < 1.01 and r.resampled and r.spread_xy < 1e-9 for r in run.particle_sets)
    stamps, mw = run.max_weight_trajectory()
    # The last record is the filter's current best particle.
    np.testing.assert_array_equal(mw[processed[-1]], run.filter.particle_poses()[run.filter.best_index])
    i = int(np.argmin(run.processed[1:])) + 1
    j = int(np.flatnonzero(run.processed[:i])[-1])
    np.testing.assert_allclose(mw[i], compose(mw[j], between(scans[j].odom, scans[i].odom)), atol=1e-12)
    # One particle: the highest-weight particle is the estimate, and the set has no spread.
    one = _feed(scans, SlamConfig(particles=1, linear_update=0.3, angular_update=0.3))
    np.testing.assert_allclose(one.max_weight_trajectory()[1], one.trajectory()[1], atol=1e-9)
    assert all(r.spread_xy == 0.0 for r in one.particle_sets)

    out = tmp_path / "run"
    run_slam_log(
        office / "log.clf",
        out,
        config,
        reference=office / "groundtruth.tum",
        max_scans=60,
        progress=False,
    )
    rows = np.genfromtxt(out / "steps.csv", delimiter=",", names=True)
    np.testing.assert_array_equal(rows["scan_index"], processed)
    np.testing.assert_allclose(rows["spread_xy_m"], [r.spread_xy for r in run.particle_sets], atol=1e-6)
    np.testing.assert_allclose(read_tum(out / "estimates/max_weight.tum").poses, mw, atol=1e-6)
    m = json.loads((out / "metrics.json").read_text())
    assert m["particle_set"]["spread_xy_mean_m"] == pytest.approx(np.mean(rows["spread_xy_m"]), rel=1e-5)
    assert "rmse_position_m" in m["reference_max_weight"]


def test_cli_slam_and_clean_errors(office: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    out = tmp_path / "run"
    assert main([*_slam_paper(office), "--out", str(out), "--particles", "3", "--max-scans", "30", "--quiet"]) == 0
    assert json.loads((out / "metrics.json").read_text())["n_scans"] == 30
    wide = tmp_path / "wide"
    # --force: each variant replaces the folder of the one before.
    args = [*_slam_paper(office), "--out", str(wide), "--particles", "3", "--max-scans", "5", "--quiet", "--force"]
    assert main([*args, "--sigma-range", "0.05"]) == 0
    text = (wide / "config.toml").read_text()  # no tomllib: Python 3.10 is supported
    hit = re.search(r"^sigma_hit_resolved = (\S+)$", text, re.M)
    assert "\nsigma_range = 0.05\n" in text and hit and float(hit.group(1)) == pytest.approx((0.05**2 + 0.2**2 / 12) ** 0.5)
    with pytest.raises(SystemExit):
        main([*args, "--sigma-range", "-1"])
    assert main([*args, "--cause-kernel", "chord"]) == 0
    text = (wide / "config.toml").read_text()
    assert 'cause_kernel = "chord"' in text and "\nsigma_hit_resolved = 0.01\n" in text
    deviations = json.loads((wide / "metrics.json").read_text())["deviations_from_paper"]
    assert deviations == ["particles = 3 (paper: 100)", "cause_kernel = 'chord' (paper: 'midpoint')"]
    for method in ("clam", "ogm"):
        args_m = [*args, "--method", method, "--proposal", "likelihood_mode", "--proposal-pose", "match"]
        assert main(args_m) == 0
        assert 'proposal_pose = "match"' in (wide / "config.toml").read_text()
        deviations = json.loads((wide / "metrics.json").read_text())["deviations_from_paper"]
        assert "proposal_pose = 'match' (paper: 'sample')" in deviations
    with pytest.raises(SystemExit):
        main([*args, "--match-stride", "0"])
    empty = tmp_path / "empty.clf"
    empty.write_text("")
    assert main(["slam", str(empty), "--out", str(tmp_path / "x"), "--quiet"]) == 2
    assert "empty.clf" in capsys.readouterr().err


@pytest.mark.parametrize(
    ("field", "value"),
    [
        ("particles", 0),
        ("tempering", 0.0),
        ("proposal", "magic"),
        ("motion_params", (1.0,)),
        ("motion", "ackermann"),
        ("cause_kernel", "box"),
        ("batch_kernel", "fast"),
        ("proposal_pose", "mean"),
        ("match_stride", 0),
        ("match_stride", 1.5),
        ("lattice_step", (0.01,)),
        ("lattice_step", (0.01, 0.0)),
        ("lattice_step", (float("nan"), 0.005)),
        ("tempering_beams", 0.5),
        ("scan_match_weight", "gmapping"),
        ("tempering_beams", float("inf")),
        ("motion_outlier", 1.0),
        ("motion_outlier", -0.1),
        ("motion_outlier", float("nan")),
        ("mode_bandwidth", (0.05,)),
        ("mode_bandwidth", (0.0, 0.025)),
        ("mode_bandwidth", (0.05, float("nan"))),
        ("ogm_map", "counts"),
        ("ogm_motion_draws", "sometimes"),
        ("ogm_weight_smoothing", -1.0),
        ("ogm_weight_smoothing", float("inf")),
        # The paper's odometry proposal has no match to keep.
        ("proposal_pose", "match"),
        ("hits_first", 1),
    ],
)
def test_bad_slam_config_names_the_field(field: str, value: object) -> None:
    with pytest.raises(ConfigError, match=field):
        SlamConfig(**{field: value})  # type: ignore[arg-type]


def test_hits_first_needs_the_batch_update() -> None:
    with pytest.raises(ConfigError, match="hits_first"):
        SlamConfig(hits_first=True, scan_update="sequential")
    assert SlamConfig(hits_first=True).mapping_config().hits_first


def test_the_native_filters_check_the_proposal_pose() -> None:
    from crlam import _native

    sensor = SlamConfig().mapping_config().sensor_model("ijrr")
    pose = np.zeros(3)
    with pytest.raises(ValueError, match="likelihood_mode"):
        _native.ClamFilter(pose, sensor, sensor, n_particles=2, proposal="odometry", proposal_pose="match")
    with pytest.raises(ValueError, match="proposal_pose"):
        _native.ClamFilter(pose, sensor, sensor, n_particles=2, proposal="likelihood_mode", proposal_pose="mean")
    with pytest.raises(ValueError, match="match stride"):
        _native.ClamFilter(pose, sensor, sensor, n_particles=2, proposal="likelihood_mode", match_stride=0)
    with pytest.raises(ValueError, match="lattice"):
        _native.ClamFilter(pose, sensor, sensor, n_particles=2, proposal="likelihood_mode", lattice_step=(0.01, -0.005))
    with pytest.raises(ValueError, match="motion_outlier"):
        _native.ClamFilter(pose, sensor, sensor, n_particles=2, proposal="likelihood_mode", motion_outlier=1.0)
    with pytest.raises(ValueError, match="motion_outlier"):
        _native.ClamFilter(pose, sensor, sensor, n_particles=2, proposal="scan_match", motion_outlier=0.1)
    with pytest.raises(ValueError, match="scan_match_weight"):
        _native.ClamFilter(pose, sensor, sensor, n_particles=2, proposal="scan_match", scan_match_weight="grid")
    with pytest.raises(ValueError, match="tempering_beams"):
        _native.ClamFilter(pose, sensor, sensor, n_particles=2, tempering_beams=0.0)
    with pytest.raises(ValueError, match="beam_stride"):
        _native.ClamFilter(pose, sensor, sensor, n_particles=2, proposal="scan_match", match_stride=0)
    with pytest.raises(ValueError, match="proposal_pose"):
        _native.OgmFilter(pose, n_particles=2, proposal_pose="mean")
    assert _native.OgmFilter(pose, n_particles=2, proposal_pose="match").n_particles == 2
    with pytest.raises(ValueError, match="gmapping"):
        _native.OgmFilter(pose, n_particles=2, motion="gmapping", motion_params=[0.1, 0.2, 0.1])
    with pytest.raises(ValueError, match="finite"):
        _native.OgmFilter(pose, n_particles=2, motion="gmapping", motion_params=[0.1, -0.2, 0.1, 0.2])
    with pytest.raises(ValueError, match="map_model"):
        _native.OgmFilter(pose, n_particles=2, map_model="counts")
    with pytest.raises(ValueError, match="motion_draws"):
        _native.OgmFilter(pose, n_particles=2, motion_draws="sometimes")
    with pytest.raises(ValueError, match="weight_smoothing"):
        _native.OgmFilter(pose, n_particles=2, weight_smoothing=float("nan"))


def test_hit_rate_cells_reach_the_ogm_run(office: Path, tmp_path: Path) -> None:
    # GMapping's counting cells through the CLI: recorded in the config, and they change the
    # baseline's matches (so its trajectory), not RBPF-CLAM's.
    trajs = {}
    runs = (("ogm", "hit_rate"), ("ogm", "gmapping"), ("ogm", "log_odds"), ("clam", "hit_rate"), ("clam", "log_odds"))
    for method, cells in runs:
        out = tmp_path / f"{method}_{cells}"
        argv = [*_slam_paper(office), "--out", str(out), "--method", method, "--particles", "4"]
        argv += ["--resolution", "0.1", "--max-scans", "40", "--motion", "thrun", "--ogm-map", cells, "--quiet"]
        assert main(argv) == 0
        assert f'\nogm_map = "{cells}"\n' in (out / "config.toml").read_text()
        trajs[method, cells] = read_tum(out / "trajectory.tum").poses
    assert not np.allclose(trajs["ogm", "hit_rate"], trajs["ogm", "log_odds"])
    # The hit means move the matches (distances to the hits, not to cell centres).
    assert not np.allclose(trajs["ogm", "gmapping"], trajs["ogm", "hit_rate"])
    np.testing.assert_array_equal(trajs["clam", "hit_rate"], trajs["clam", "log_odds"])


def test_per_scan_motion_draws_reach_the_ogm_run(office: Path, tmp_path: Path) -> None:
    # GMapping's draw at every scan: with a trigger that skips scans, the particles differ from
    # per-update draws; recorded in the config.
    trajs = {}
    for draws in ("per_scan", "per_update"):
        out = tmp_path / draws
        argv = [*_slam_paper(office), "--out", str(out), "--method", "ogm", "--particles", "4"]
        argv += ["--resolution", "0.1", "--max-scans", "40", "--motion", "gmapping"]
        argv += ["--linear-update", "0.3", "--angular-update", "0.3", "--ogm-motion-draws", draws, "--quiet"]
        assert main(argv) == 0
        assert f'\nogm_motion_draws = "{draws}"\n' in (out / "config.toml").read_text()
        metrics = json.loads((out / "metrics.json").read_text())
        assert 1 < metrics["n_processed"] < metrics["n_scans"]
        trajs[draws] = read_tum(out / "trajectory.tum").poses
    assert np.isfinite(trajs["per_scan"]).all()
    assert not np.allclose(trajs["per_scan"], trajs["per_update"])


def test_weight_smoothing_sets_how_often_the_ogm_run_resamples(office: Path, tmp_path: Path) -> None:
    # GMapping's ogain flattens the weights: the stronger the smoothing, the fewer resamplings;
    # plain weights (0) resample the most. Recorded in the config; ignored by RBPF-CLAM.
    resamples = {}
    for ogain in ("0", "3", "1000"):
        out = tmp_path / f"ogain_{ogain}"
        argv = [*_slam_paper(office), "--out", str(out), "--method", "ogm", "--particles", "8"]
        argv += ["--resolution", "0.1", "--max-scans", "60", "--ogm-weight-smoothing", ogain, "--quiet"]
        assert main(argv) == 0
        assert f"\nogm_weight_smoothing = {float(ogain)}\n" in (out / "config.toml").read_text()
        resamples[ogain] = json.loads((out / "metrics.json").read_text())["n_resamples"]
    assert resamples["0"] > resamples["3"] >= resamples["1000"]
    assert resamples["1000"] == 0
    with pytest.raises(SystemExit):
        main([*_slam_paper(office), "--out", str(tmp_path / "bad"), "--ogm-weight-smoothing", "-1"])


def test_gmapping_motion_model_runs_both_filters(office: Path, tmp_path: Path) -> None:
    # GMapping's own noise model, through the CLI to the run folder, for either filter; a
    # different model draws different particles, so the trajectories differ from Thrun's.
    trajs = {}
    for method, motion in (("ogm", "gmapping"), ("ogm", "thrun"), ("clam", "gmapping")):
        out = tmp_path / f"{method}_{motion}"
        argv = [*_slam_paper(office), "--out", str(out), "--method", method, "--particles", "4"]
        argv += ["--resolution", "0.1", "--max-scans", "40", "--motion", motion, "--quiet"]
        assert main(argv) == 0
        assert f'\nmotion = "{motion}"\n' in (out / "config.toml").read_text()
        trajs[method, motion] = read_tum(out / "trajectory.tum").poses
    assert not np.allclose(trajs["ogm", "gmapping"], trajs["ogm", "thrun"])
    assert np.isfinite(trajs["clam", "gmapping"]).all()
    assert SlamConfig(motion="gmapping", motion_params=(0.05, 0.1, 0.05, 0.1)).motion_params == (0.05, 0.1, 0.05, 0.1)


@pytest.mark.realdata
@pytest.mark.slow
def test_aces_smoke_first_1000_scans(data_dir: Path, tmp_path: Path) -> None:
    log = data_dir / "aces" / "aces.clf.bz2"
    cfg = SlamConfig(particles=5, max_range=8.0, resolution=0.2, motion="thrun")
    res = run_slam_log(log, tmp_path, cfg, relations=data_dir / "aces" / "aces.relations", max_scans=1000, progress=False)
    m = res.metrics
    assert m["n_scans"] == 1000 and np.isfinite(m["relations"]["trans_mean_m"])
    # The same relations on raw odometry, for comparison: the filter must not be worse.
    scans = [s for _, s in zip(range(1000), read_scans(log))]
    odo = relations_error(
        np.array([s.timestamp for s in scans]),
        np.array([s.odom for s in scans]),
        read_relations(data_dir / "aces" / "aces.relations"),
        on_missing="skip",
    )
    assert m["relations"]["n"] == odo.n > 50
    # Five particles and the paper's weights do not beat ACES's good short-term odometry (0.032 m here; the
    # filter gets about 0.07 m): the smoke test checks that it stays on track, not that it wins.
    assert m["relations"]["trans_mean_m"] < max(0.3, 3.0 * odo.summary()["trans_mean_m"]), (m["relations"], odo.summary())


def test_the_match_stride_reaches_the_likelihood_mode_climb(office: Path, tmp_path: Path) -> None:
    # The climb's beam stride changes where the climbs end, so the trajectories differ; the
    # setting is recorded with the run. The odometry proposal has no climb: the stride is inert.
    trajectories = {}
    for proposal in ("likelihood_mode", "odometry"):
        for stride in (1, 3):
            out = tmp_path / f"{proposal}{stride}"
            args = [*_slam_paper(office), "--out", str(out), "--particles", "4", "--max-scans", "25", "--quiet"]
            assert main([*args, "--proposal", proposal, "--match-stride", str(stride), "--seed", "2"]) == 0
            assert f"\nmatch_stride = {stride}\n" in (out / "config.toml").read_text()
            trajectories[proposal, stride] = read_tum(out / "trajectory.tum").poses
    assert not np.array_equal(trajectories["likelihood_mode", 1], trajectories["likelihood_mode", 3])
    np.testing.assert_array_equal(trajectories["odometry", 1], trajectories["odometry", 3])


def test_the_lattice_step_reaches_the_likelihood_mode_fit(office: Path, tmp_path: Path) -> None:
    # The lattice decides the fitted Gaussian and the weights, so the trajectories differ; the
    # default is the lattice of earlier versions (half the climb's first step), and the setting is
    # recorded with the run. The odometry proposal has no lattice: the setting is inert.
    trajectories = {}
    for proposal in ("likelihood_mode", "odometry"):
        for lattice in (None, ("0.01", "0.005")):
            out = tmp_path / f"{proposal}{lattice is None}"
            args = [*_slam_paper(office), "--out", str(out), "--particles", "4", "--max-scans", "25", "--quiet"]
            extra = [] if lattice is None else ["--lattice-step", *lattice]
            assert main([*args, "--proposal", proposal, "--seed", "2", *extra]) == 0
            want = [0.05, 0.025] if lattice is None else [0.01, 0.005]
            assert tomllib.loads((out / "config.toml").read_text())["slam"]["lattice_step"] == want
            trajectories[proposal, lattice] = read_tum(out / "trajectory.tum").poses
    fine = ("0.01", "0.005")
    assert not np.array_equal(trajectories["likelihood_mode", None], trajectories["likelihood_mode", fine])
    np.testing.assert_array_equal(trajectories["odometry", None], trajectories["odometry", fine])
    with pytest.raises(SystemExit):
        main([*_slam_paper(office), "--out", str(tmp_path / "bad"), "--lattice-step", "0.01"])


def test_the_motion_outlier_reaches_the_likelihood_mode_climb(office: Path, tmp_path: Path) -> None:
    # A floor under the motion density changes the climb's target and the lattice, so the
    # trajectories differ; 0 is the motion model alone, bit for bit the run without the option,
    # and the setting is recorded with the run. The odometry proposal has no climb: inert.
    trajectories = {}
    for proposal in ("likelihood_mode", "odometry"):
        for eps in (None, "0", "0.2"):
            out = tmp_path / f"{proposal}{eps}"
            args = [*_slam_paper(office), "--out", str(out), "--particles", "4", "--max-scans", "25", "--quiet"]
            extra = [] if eps is None else ["--motion-outlier", eps]
            assert main([*args, "--proposal", proposal, "--seed", "2", *extra]) == 0
            want = "0.2" if eps == "0.2" else "0.0"
            assert f"\nmotion_outlier = {want}\n" in (out / "config.toml").read_text()
            trajectories[proposal, eps] = read_tum(out / "trajectory.tum").poses
    np.testing.assert_array_equal(trajectories["likelihood_mode", None], trajectories["likelihood_mode", "0"])
    assert not np.array_equal(trajectories["likelihood_mode", None], trajectories["likelihood_mode", "0.2"])
    np.testing.assert_array_equal(trajectories["odometry", None], trajectories["odometry", "0.2"])
