"""Semi-real logs (``crlam.experiments.semireal``, ``crlam semireal``): real scans at corrected poses with a
drifting odometry of our own and an optional laser lag."""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pytest

from crlam.errors import ConfigError
from crlam.experiments.semireal import SemiRealSettings, make_semireal
from crlam.io.carmen_types import LaserScan
from crlam.io.tum import read_tum
from crlam.pose import between


def _corrected_scans(n: int = 400) -> list[LaserScan]:
    """Scans along a square path (four 90 deg turns), stamps 0.2 s apart, as a corrected log holds them."""
    poses = []
    x, y, th = 0.0, 0.0, 0.0
    for k in range(n):
        if k % 100 in range(90, 100):
            th += math.pi / 20  # ten steps of 9 deg: a turn
        else:
            x, y = x + 0.1 * math.cos(th), y + 0.1 * math.sin(th)
        poses.append((x, y, th))
    return [
        LaserScan(np.full(5, 2.0), -0.2, 0.1, 80.0, pose=np.array(p), odom=np.array(p), timestamp=0.2 * k)
        for k, p in enumerate(poses)
    ]


def test_odometry_drifts_as_specified_and_the_truth_is_the_corrected_path() -> None:
    scans = _corrected_scans()
    s = SemiRealSettings(seed=1, trans_noise=0.0, rot_noise=0.0, rot_per_trans=0.0, turn_slip=0.0, heading_bias=0.01)
    log = make_semireal(scans, s)
    assert np.allclose(log.truth, [sc.odom for sc in scans])
    assert log.stamps_source == "log"
    for k in (5, 95):
        u = between(log.truth[k - 1], log.truth[k])
        v = between(log.odometry_poses[k - 1], log.odometry_poses[k])
        d = math.hypot(u[0], u[1])
        assert math.hypot(v[0], v[1]) == pytest.approx(d * 1.02)
        assert v[2] == pytest.approx(u[2] * 1.02 + 0.01 * d)
    # Deterministic for a seed, different for another.
    noisy = SemiRealSettings(seed=1)
    assert np.array_equal(make_semireal(scans, noisy).odometry_poses, make_semireal(scans, noisy).odometry_poses)
    assert not np.array_equal(
        make_semireal(scans, noisy).odometry_poses, make_semireal(scans, SemiRealSettings(seed=2)).odometry_poses
    )


def test_slip_in_turns_only() -> None:
    scans = _corrected_scans()
    quiet = dict(trans_noise=0.0, rot_noise=0.0, rot_per_trans=0.0, heading_bias=0.0, rot_scale=0.0, trans_scale=0.0)
    a = make_semireal(scans, SemiRealSettings(seed=0, turn_slip=0.0, **quiet))
    b = make_semireal(scans, SemiRealSettings(seed=0, turn_slip=0.3, **quiet))
    inc_a = np.array([between(a.odometry_poses[k - 1], a.odometry_poses[k]) for k in range(1, len(scans))])
    inc_b = np.array([between(b.odometry_poses[k - 1], b.odometry_poses[k]) for k in range(1, len(scans))])
    differs = np.abs(inc_a[:, 2] - inc_b[:, 2]) > 1e-12
    turning = np.array([abs(between(a.truth[k - 1], a.truth[k])[2]) > 0 for k in range(1, len(scans))])
    assert np.array_equal(differs, turning)


def test_laser_lag_on_real_scans_is_undone_by_the_time_offset(data_dir: Path, tmp_path: Path) -> None:
    """A corrected log's real scans with a 0.15 s laser lag: each scan's odometry field is the
    odometry 0.15 s after the scan was taken; re-attached at the offset -0.15 s it is the odometry
    of the instant the scan was taken."""
    from crlam.experiments.semireal import write_semireal
    from crlam.experiments.stress_variants import load_records
    from crlam.slam.time_offset import retime_odometry

    log = data_dir / "corrected" / "intel-corrected.log.gz"
    summary = write_semireal(log, tmp_path / "semi", SemiRealSettings(laser_lag=0.15, stamps="synthetic"), max_scans=300)
    assert summary["time_offset_s"] == -0.15 and summary["stamps"] == "synthetic"
    truth = read_tum(tmp_path / "semi" / "groundtruth.tum")
    odometry = read_tum(tmp_path / "semi" / "odometry.tum")
    assert len(truth.timestamps) == summary["n_scans"] == 300
    assert np.allclose(truth.timestamps - odometry.timestamps, 0.15, atol=1e-6)
    records = load_records(tmp_path / "semi" / "log.clf")
    scans = [r for r in records if isinstance(r, LaserScan)]
    moved = [np.hypot(*(s.odom[:2] - o[:2])) for s, o in zip(scans, odometry.poses, strict=True)]
    assert np.median(moved) > 0.01  # the lag shows in the attached odometry
    fixed = [r for r in retime_odometry(iter(records), -0.15) if isinstance(r, LaserScan)]
    err = [np.hypot(*(s.odom[:2] - o[:2])) for s, o in zip(fixed, odometry.poses, strict=True)]
    assert max(err[1:-1]) < 1e-3


def test_cli_writes_the_files(tmp_path: Path) -> None:
    from crlam.cli import main
    from crlam.io.carmen_writer import write_carmen

    src = tmp_path / "corrected.clf"
    write_carmen(src, _corrected_scans(50))
    out = tmp_path / "semi"
    assert main(["semireal", str(src), "--out", str(out), "--seed", "3", "--laser-lag", "0.1", "--quiet"]) == 0
    summary = json.loads((out / "semireal.json").read_text())
    assert summary["n_scans"] == 50 and summary["settings"]["seed"] == 3
    assert {p.name for p in out.iterdir()} >= {"log.clf", "groundtruth.tum", "odometry.tum", "semireal.json"}
    # The summary names its files inside the folder, not in the staging folder it was written to.
    assert all((out / name).is_file() for name in summary["files"].values())


def test_settings_are_checked() -> None:
    with pytest.raises(ConfigError):
        SemiRealSettings(laser_lag=-0.1)
    with pytest.raises(ConfigError):
        SemiRealSettings(stamps="sometimes")
