"""The laser-to-odometry time offset (``crlam.slam.time_offset``, ``crlam slam --time-offset``): the
estimate recovers an injected offset on a simulated log and on the real logs, refuses what it
cannot identify, and the re-attached odometry is the odometry at the corrected stamp."""

from __future__ import annotations

import json
import math
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from crlam.errors import ConfigError
from crlam.experiments.stress_variants import StressSettings, build_variant, load_records
from crlam.io.carmen_types import CarmenRecord, LaserScan, OdometryReading
from crlam.slam import SlamConfig
from crlam.slam.time_offset import (
    RetimeStats,
    TimeOffsetSettings,
    estimate_time_offset,
    interpolate_pose,
    parse_time_offset,
    retime_odometry,
)

#: Scans of the simulated log: 160 s at 10 Hz, every scan matched by the estimate.
N_SIM = 1600


@pytest.fixture(scope="module")
def sim_records(tmp_path_factory: pytest.TempPathFactory) -> list[CarmenRecord]:
    """A simulated log (office world, SICK-like laser) whose odometry heading drifts 0.003 rad
    per 0.1 s step (about wheel odometry's; the simulator's default, 0.01, is three times that)."""
    from crlam.sim.odometry import GaussianIncrementNoise
    from crlam.sim.simulate import SimulationConfig, simulate, write_simulation

    cfg = SimulationConfig(
        world="office",
        n_scans=N_SIM,
        sensor="sick",
        seed=0,
        odometry=GaussianIncrementNoise(sigma_x=0.005, sigma_y=0.005, sigma_theta=0.003),
    )
    out = tmp_path_factory.mktemp("sim")
    paths = write_simulation(simulate(cfg), out)
    return load_records(paths["carmen"])


def shift_odometry_records(records: list[CarmenRecord], shift: float) -> list[CarmenRecord]:
    """The log with only its odometry records' stamps moved by ``shift`` s (scans untouched)."""
    return [replace(r, timestamp=r.timestamp + shift) if isinstance(r, OdometryReading) else r for r in records]


def _n_scans(records: list[CarmenRecord]) -> int:
    return sum(isinstance(r, LaserScan) for r in records)


@pytest.mark.parametrize("shift", [0.15, -0.1])
def test_estimate_recovers_an_injected_offset_on_a_simulated_log(sim_records: list[CarmenRecord], shift: float) -> None:
    # The stress variant: odometry records stamped `shift` later, the scans' own odometry fields
    # the odometry `shift` earlier; the true offset is `shift` (the simulated log has none).
    variant = build_variant(sim_records, "odom_shift", StressSettings(odom_shift_s=shift))
    est = estimate_time_offset(iter(variant), n_scans=_n_scans(variant))
    assert est.identified, est.reason
    assert est.estimate_s is not None and abs(est.estimate_s - shift) <= 0.02
    assert est.applied_s == est.estimate_s and est.retimed
    assert est.ci95_s is not None and est.ci95_s[0] <= est.estimate_s <= est.ci95_s[1]
    assert est.heading_scale is not None and 0.9 < est.heading_scale < 1.1


def test_the_estimate_does_not_depend_on_the_thread_count(
    sim_records: list[CarmenRecord], monkeypatch: pytest.MonkeyPatch
) -> None:
    # Four runs of 100 scans, matched on one thread and on two: the same pairs, the same estimate.
    variant = build_variant(sim_records, "odom_shift", StressSettings(odom_shift_s=0.1))
    settings = TimeOffsetSettings(max_scans=400, segments=4)
    estimates = []
    for threads in ("1", "2"):
        monkeypatch.setenv("RAYON_NUM_THREADS", threads)
        estimates.append(estimate_time_offset(iter(variant), settings, n_scans=_n_scans(variant)))
    one, two = estimates
    assert one.n_pairs == two.n_pairs > 0 and one.n_scans_matched == two.n_scans_matched
    assert one.estimate_s == two.estimate_s and one.ci95_s == two.ci95_s


def test_estimate_on_the_unshifted_simulated_log_is_near_zero(sim_records: list[CarmenRecord]) -> None:
    est = estimate_time_offset(iter(sim_records), n_scans=_n_scans(sim_records))
    assert est.estimate_s is not None and abs(est.estimate_s) <= 0.02, est.reason


def test_a_mirrored_laser_still_gives_the_offset_with_a_negative_heading_scale(sim_records: list[CarmenRecord]) -> None:
    variant = build_variant(build_variant(sim_records, "odom_shift"), "mount_flip")
    est = estimate_time_offset(iter(variant), n_scans=_n_scans(variant))
    assert est.heading_scale is not None and est.heading_scale < -0.9
    assert est.identified and est.estimate_s is not None and abs(est.estimate_s - 0.15) <= 0.02, est.reason


def test_unrelated_odometry_is_not_identified_and_not_applied(sim_records: list[CarmenRecord]) -> None:
    # Odometry whose heading has nothing to do with the scans' turns: a random walk of its own.
    rng = np.random.default_rng(1)
    out: list[CarmenRecord] = []
    heading = 0.0
    for r in sim_records:
        if isinstance(r, OdometryReading):
            heading += float(rng.normal(0.0, 0.1))
            out.append(replace(r, pose=np.array([r.pose[0], r.pose[1], heading])))
        else:
            out.append(r)
    est = estimate_time_offset(iter(out), n_scans=_n_scans(out))
    assert not est.identified
    assert est.reason.startswith("not identified")
    assert est.applied_s == 0.0 and not est.retimed


def test_a_log_without_odometry_is_not_identified(sim_records: list[CarmenRecord]) -> None:
    scans = [replace(r, odom=np.zeros(3), pose=np.zeros(3)) for r in sim_records if isinstance(r, LaserScan)]
    est = estimate_time_offset(iter(scans), TimeOffsetSettings(max_scans=400))
    assert not est.identified and est.odometry_source == "scan odometry fields"


def test_retimed_odometry_is_the_odometry_at_the_corrected_stamp(sim_records: list[CarmenRecord]) -> None:
    original = [r for r in sim_records if isinstance(r, LaserScan)]
    variant = build_variant(sim_records, "odom_shift")
    stats = RetimeStats()
    retimed = [r for r in retime_odometry(iter(variant), 0.15, stats=stats) if isinstance(r, LaserScan)]
    assert [r.timestamp for r in retimed] == [r.timestamp for r in original]
    err = np.array([math.hypot(*(a.odom[:2] - b.odom[:2])) for a, b in zip(original, retimed, strict=True)])
    dth = np.array([abs(math.remainder(a.odom[2] - b.odom[2], 2 * math.pi)) for a, b in zip(original, retimed, strict=True)])
    # Every scan but the last two (whose corrected stamp lies past the last odometry record).
    assert np.all(err[:-2] < 1e-6) and np.all(dth[:-2] < 1e-6)
    assert stats.n_scans == len(original) and stats.n_interpolated >= len(original) - 2
    # Without the correction the scans' odometry is 0.15 s of motion off.
    plain = [r for r in variant if isinstance(r, LaserScan)]
    off = np.array([math.hypot(*(a.odom[:2] - b.odom[:2])) for a, b in zip(original, plain, strict=True)])
    assert np.median(off) > 0.02


def test_scans_with_stamps_out_of_order_keep_their_logged_odometry() -> None:
    # Odometry at 10 Hz along x at 1 m/s; the third scan's stamp jumps 0.4 s ahead of its place.
    odo = [OdometryReading(pose=np.array([0.1 * k, 0.0, 0.0]), timestamp=0.1 * k) for k in range(30)]
    stamps = [0.5, 0.7, 1.3, 1.1, 1.3, 1.5]
    records: list[CarmenRecord] = []
    for k in range(30):
        records.append(odo[k])
        t = 0.1 * k
        for j, s in enumerate(stamps):
            place = 0.9 if j == 2 else s
            if abs(place - t) < 1e-9:
                records.append(
                    LaserScan(
                        np.ones(3), -0.1, 0.1, 10.0, pose=np.array([place, 0, 0]), odom=np.array([place, 0, 0]), timestamp=s
                    )
                )
    stats = RetimeStats()
    out = [r for r in retime_odometry(iter(records), 0.0, stats=stats) if isinstance(r, LaserScan)]
    assert [round(float(r.odom[0]), 6) for r in out] == [0.5, 0.7, 0.9, 1.1, 1.3, 1.5]
    assert stats.n_suspect_stamps >= 1


def test_interpolate_pose_takes_the_shortest_arc() -> None:
    t = np.array([0.0, 1.0])
    p = np.array([[0.0, 0.0, math.pi - 0.1], [1.0, 2.0, -math.pi + 0.1]])
    q = interpolate_pose(t, p, 0.5)
    assert q[:2] == pytest.approx([0.5, 1.0])
    assert abs(abs(q[2]) - math.pi) < 1e-9
    assert interpolate_pose(t, p, -1.0) == pytest.approx(p[0])
    assert interpolate_pose(t, p, 5.0) == pytest.approx(p[1])


def test_setting_is_checked() -> None:
    assert parse_time_offset("auto") == "auto" and parse_time_offset("off") == "off"
    assert parse_time_offset("-0.13") == pytest.approx(-0.13)
    import argparse

    for bad in ("soon", "nan", "inf", "100"):
        with pytest.raises(argparse.ArgumentTypeError):
            parse_time_offset(bad)
    with pytest.raises(ConfigError, match="time_offset"):
        SlamConfig(time_offset="sometimes")
    with pytest.raises(ConfigError, match="time_offset"):
        SlamConfig(time_offset=float("nan"))
    assert SlamConfig().time_offset == "off" and SlamConfig.from_preset().time_offset == "auto"


def test_slam_records_and_applies_the_estimate(sim_records: list[CarmenRecord], tmp_path: Path) -> None:
    from crlam.experiments.slam_run import run_slam_log
    from crlam.experiments.stress_variants import write_variant

    log = write_variant(build_variant(sim_records[: 2 * 400], "odom_shift"), tmp_path / "shifted.clf", "odom_shift")
    config = SlamConfig.from_preset(particles=2, time_offset=0.15)
    res = run_slam_log(log, tmp_path / "run", config, progress=False, figures=False)
    m = json.loads((tmp_path / "run" / "metrics.json").read_text())
    assert m["time_offset"]["applied_s"] == pytest.approx(0.15) and m["time_offset"]["retimed"]
    assert m["time_offset"]["retime"]["n_scans"] == res.run.n_scans == 400
    off = run_slam_log(log, tmp_path / "off", replace(config, time_offset="off"), progress=False, figures=False)
    assert off.metrics["time_offset"]["retimed"] is False
    # The filter saw the corrected odometry: the run's odometry differs from the log's.
    assert not np.allclose(np.array(res.run.odometry), np.array(off.run.odometry))


def test_the_two_pre_passes_side_by_side_give_what_each_gives_alone(
    sim_records: list[CarmenRecord], tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """With more than one thread the odometry-noise fit and the time-offset estimate run at once;
    the run must be the one a single thread makes, estimates and trajectory alike."""
    from crlam.experiments.slam_run import run_slam_log
    from crlam.experiments.stress_variants import write_variant

    log = write_variant(build_variant(sim_records[: 2 * 400], "odom_shift"), tmp_path / "shifted.clf", "odom_shift")
    config = SlamConfig.from_preset(particles=2, loop_closing="off")
    runs = {}
    for threads in ("1", "2"):
        monkeypatch.setenv("RAYON_NUM_THREADS", threads)
        runs[threads] = run_slam_log(log, tmp_path / threads, config, progress=False, figures=False)
    one, two = runs["1"].metrics, runs["2"].metrics
    assert one["motion_noise_estimate"]["fitted"]
    assert one["motion_noise_estimate"] == two["motion_noise_estimate"]
    assert one["time_offset"]["identified"] and one["time_offset"]["retimed"]
    assert one["time_offset"] == two["time_offset"]
    assert (tmp_path / "1" / "trajectory.tum").read_bytes() == (tmp_path / "2" / "trajectory.tum").read_bytes()


def test_cli_flag(tmp_path: Path, sim_records: list[CarmenRecord]) -> None:
    from crlam.cli import main
    from crlam.experiments.stress_variants import write_variant

    log = write_variant(sim_records[: 2 * 300], tmp_path / "log.clf", "none")
    assert main(["slam", str(log), "--out", str(tmp_path / "run"), "--particles", "2", "--time-offset", "off", "--quiet"]) == 0
    m = json.loads((tmp_path / "run" / "metrics.json").read_text())
    assert m["time_offset"]["setting"] == "off"
    with pytest.raises(SystemExit):
        main(["slam", str(log), "--out", str(tmp_path / "bad"), "--time-offset", "later"])


# -- real logs ------------------------------------------------------------------------------------


@pytest.mark.parametrize("name", ["intel", "aces"])
def test_real_log_odometry_stamps_shifted_by_015_s_are_recovered(data_dir: Path, name: str) -> None:
    """The log's ODOM lines stamped 0.15 s later: the estimate moves by 0.15 s (within 0.02)."""
    records = load_records(data_dir / name / f"{name}.clf.bz2", max_scans=3000)
    n = _n_scans(records)
    base = estimate_time_offset(iter(records), n_scans=n)
    shifted = estimate_time_offset(iter(shift_odometry_records(records, 0.15)), n_scans=n)
    assert base.identified and shifted.identified, (base.reason, shifted.reason)
    assert base.estimate_s is not None and shifted.estimate_s is not None
    assert abs((shifted.estimate_s - base.estimate_s) - 0.15) <= 0.02


def test_localize_applies_the_offset(tmp_path: Path) -> None:
    from crlam.experiments.localize_run import run_localize_log
    from crlam.experiments.stress_variants import write_variant
    from crlam.io.tum import read_tum
    from crlam.localize import LocalizeConfig
    from crlam.sim.simulate import SimulationConfig, simulate, write_simulation

    paths = write_simulation(simulate(SimulationConfig(world="office", n_scans=120, sensor="sick", seed=2)), tmp_path / "sim")
    records = load_records(paths["carmen"])
    log = write_variant(build_variant(records, "odom_shift"), tmp_path / "shifted.clf", "odom_shift")
    start = read_tum(paths["groundtruth"]).poses[0]
    config = LocalizeConfig(max_beams=45, max_particles=500, min_particles=100, spread_particles=0, seed=1)
    kwargs = dict(initial_pose=start, initial_cov=np.array([0.01, 0.01, 0.005]), progress=False, figures=False)
    res = run_localize_log(log, paths["world_yaml"], tmp_path / "loc", config, time_offset=0.15, **kwargs)  # type: ignore[arg-type]
    assert res.metrics["time_offset"]["retimed"] and res.metrics["time_offset"]["applied_s"] == 0.15
    original = np.array([r.odom for r in records if isinstance(r, LaserScan)])
    used = np.array(res.localizer.odometry)
    assert np.allclose(used[1:-2, :2], original[1:-2, :2], atol=1e-4)
    off = run_localize_log(log, paths["world_yaml"], tmp_path / "off", config, time_offset="off", **kwargs)  # type: ignore[arg-type]
    assert not off.metrics["time_offset"]["retimed"]
    assert not np.allclose(np.array(off.localizer.odometry)[1:-2, :2], original[1:-2, :2], atol=1e-3)
