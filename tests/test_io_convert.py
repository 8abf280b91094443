"""``crlam convert``: a simulated CARMEN log to a ROS 2 bag (MCAP) and back, and ``crlam slam`` on both."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

from crlam.cli import main
from crlam.errors import ConfigError, DataFormatError
from crlam.io import LaserScan, OdometryReading, open_log
from crlam.io.carmen import CarmenReader, write_carmen
from crlam.io.convert import carmen_to_bag, convert
from crlam.io.rosbag_writer import ros_time, yaw_quaternion


@pytest.fixture(scope="module")
def sim_log(tmp_path_factory: pytest.TempPathFactory) -> Path:
    out = tmp_path_factory.mktemp("sim")
    assert main(["simulate", "--scans", "30", "--world", "office", "--out", str(out), "--quiet"]) == 0
    return out / "log.clf"


def _scans(path: Path) -> list[LaserScan]:
    return [r for r in open_log(path) if isinstance(r, LaserScan)]


def _trajectory_rows(run: Path) -> list[str]:
    # The first line names the input file; every pose line must be the same bytes.
    lines = (run / "trajectory.tum").read_text().splitlines()
    return [ln for ln in lines if not ln.startswith("#")]


def test_carmen_to_bag_and_back_keeps_the_scans(sim_log: Path, tmp_path: Path) -> None:
    bag = tmp_path / "bag"
    assert main(["convert", str(sim_log), "-o", str(bag)]) == 0
    assert (bag / "metadata.yaml").is_file() and len(list(bag.glob("*.mcap"))) == 1
    back = tmp_path / "back.clf"
    assert main(["convert", str(bag), "-o", str(back)]) == 0
    original, in_bag, again = _scans(sim_log), _scans(bag), _scans(back)
    assert len(original) == len(in_bag) == len(again) == 30
    for a, b, c in zip(original, in_bag, again):
        # Stamps and odometry are exact: each scan's odometry is written at its own stamp.
        assert a.timestamp == b.timestamp == c.timestamp
        np.testing.assert_array_equal(a.odom, b.odom)
        np.testing.assert_array_equal(a.odom, c.odom)
        np.testing.assert_allclose(b.laser_offset, a.laser_offset, atol=1e-12)
        # The bag stores ranges and bearings as float32: within float32 precision there, and the
        # CARMEN log written back has the log's own 0.1 mm ranges.
        np.testing.assert_allclose(b.ranges, a.ranges, rtol=1e-7, atol=0)
        np.testing.assert_array_equal(c.ranges, a.ranges)
        np.testing.assert_allclose(b.angles, a.angles, atol=5e-7)
        np.testing.assert_allclose(c.angles, a.angles, atol=5e-7)
        assert b.max_range == a.max_range == c.max_range
    odom = [r for r in open_log(bag) if isinstance(r, OdometryReading)]
    assert len(odom) == 30  # the simulated ODOM records share the scans' stamps: one reading each


def test_slam_on_the_log_and_on_its_bag_gives_the_same_trajectory(sim_log: Path, tmp_path: Path) -> None:
    """Bit for bit, for a log whose values the bag stores exactly.

    ``sensor_msgs/msg/LaserScan`` holds the ranges, ``angle_min`` and ``angle_increment`` as
    float32; the simulated log's ``%.4f`` ranges and ``%.9f`` bearings are not float32 values,
    so the filter would see readings 1e-7 apart. Here the simulated scans are snapped to values
    both formats hold exactly (ranges in 1/16 m, bearings in 2^-9 rad); stamps, odometry and
    the laser mount are the simulation's own."""
    records = []
    for rec in CarmenReader(sim_log):
        if isinstance(rec, LaserScan):
            rec.angle_min = -1206 / 512
            rec.angle_increment = 2 / 512
            rec.ranges = np.round(rec.ranges * 16.0) / 16.0
        records.append(rec)
    log = tmp_path / "snapped.clf"
    write_carmen(log, records)
    bag = tmp_path / "snapped_bag"
    carmen_to_bag(log, bag)
    flags = ["--particles", "3", "--max-scans", "30", "--quiet"]
    for source, run in ((log, "run_log"), (bag, "run_bag")):
        assert main(["slam", str(source), "--out", str(tmp_path / run), *flags]) == 0
    rows = _trajectory_rows(tmp_path / "run_log")
    assert len(rows) == 30
    assert rows == _trajectory_rows(tmp_path / "run_bag")
    # Every scan, not only those after enough travel, through the filter.
    every = ["--linear-update", "0", "--angular-update", "0"]
    for source, run in ((log, "all_log"), (bag, "all_bag")):
        assert main(["slam", str(source), "--out", str(tmp_path / run), *flags, *every]) == 0
    assert _trajectory_rows(tmp_path / "all_log") == _trajectory_rows(tmp_path / "all_bag")


def test_single_mcap_file_and_errors(sim_log: Path, tmp_path: Path) -> None:
    out = tmp_path / "log.mcap"
    summary = convert(sim_log, out)
    assert out.is_file() and summary.n_scans == 30
    assert [p.name for p in tmp_path.iterdir()] == ["log.mcap"]  # no temporary folder left
    assert len(_scans(out)) == 30
    with pytest.raises(ConfigError, match="exists already"):
        convert(sim_log, tmp_path)
    with pytest.raises(ConfigError, match="options for a ROS bag"):
        convert(sim_log, tmp_path / "x", scan_topic="/scan")
    # A laser offset that changes cannot be one static transform.
    recs = list(CarmenReader(sim_log))
    scans = [r for r in recs if isinstance(r, LaserScan)]
    scans[5].laser_offset = np.array([0.2, 0.0, 0.0])
    moved = tmp_path / "moved.clf"
    write_carmen(moved, recs, robotlaser_pose="odom")
    with pytest.raises(DataFormatError, match="laser offset changes"):
        convert(moved, tmp_path / "moved_bag")


def test_stamps_and_yaw_read_back_exactly() -> None:
    from types import SimpleNamespace

    from crlam.io.rosbag import _stamp, _yaw_of

    rng = np.random.default_rng(1)
    for t in [0.0, 0.1, 1.000001, 1_700_000_000.123456, *np.round(rng.uniform(0, 1e5, 200), 6)]:
        sec, nsec = ros_time(float(t))
        assert 0 <= nsec < 1_000_000_000
        assert _stamp(SimpleNamespace(stamp=SimpleNamespace(sec=sec, nanosec=nsec))) == float(t)
    yaws = np.round(rng.uniform(-math.pi, math.pi, 2000), 6)
    exact = 0
    for th in yaws:
        x, y, z, w = yaw_quaternion(float(th))
        got = _yaw_of(SimpleNamespace(x=x, y=y, z=z, w=w))
        assert got == pytest.approx(th, abs=1e-15)
        exact += got == th
    assert exact >= 0.99 * len(yaws)


def test_flaser_log_round_trips_as_flaser(tmp_path: Path) -> None:
    """FLASER scans (implicit 180-deg geometry, forward laser offset) come back as FLASER lines
    with the same ranges, poses, odometry and stamps; ODOM records between scans stay."""
    from crlam.io.carmen import flaser_geometry
    from crlam.pose import compose

    amin, inc = flaser_geometry(180, math.pi)
    records: list[LaserScan | OdometryReading] = []
    for k in range(20):
        odom = np.array([0.1 * k, 0.01 * k, 0.05 * k])
        offset = np.array([0.2, 0.0, 0.0])
        t = 1_000_000_000.0 + 0.05 * k
        ranges = np.linspace(1.0, 80.0, 180)
        ranges[::7] = 81.0  # no-returns
        records.append(LaserScan(ranges, amin, inc, 81.0, compose(odom, offset), odom, offset, timestamp=t))
        records.append(OdometryReading(odom + 0.01, tv=0.5, rv=0.1, timestamp=t + 0.02))
    log = tmp_path / "flaser.clf"
    write_carmen(log, records)
    summary = convert(log, tmp_path / "flaser.mcap")
    assert summary.n_scans == 20 and summary.n_odometry == 40 and summary.laser_offset == (0.2, 0.0, 0.0)
    back = tmp_path / "back.clf.gz"
    convert(tmp_path / "flaser.mcap", back)
    original = list(CarmenReader(log))
    again = list(CarmenReader(back))
    a = [r for r in original if isinstance(r, LaserScan)]
    b = [r for r in again if isinstance(r, LaserScan)]
    assert len(a) == len(b) == 20 and {s.kind for s in b} == {"FLASER"}
    for x, y in zip(a, b):
        assert x.timestamp == y.timestamp
        for name in ("ranges", "angles", "pose", "odom", "laser_offset"):
            np.testing.assert_array_equal(getattr(x, name), getattr(y, name), err_msg=name)
    odom_a = {r.timestamp: r for r in original if isinstance(r, OdometryReading)}
    odom_b = {r.timestamp: r for r in again if isinstance(r, OdometryReading)}
    assert set(odom_a) <= set(odom_b)  # plus one reading per scan (its own odometry)
    for t, r in odom_a.items():
        np.testing.assert_array_equal(r.pose, odom_b[t].pose)
        assert (r.tv, r.rv) == (odom_b[t].tv, odom_b[t].rv)
