"""Scan-matching odometry (``crlam.slam.scan_odometry``, ``crlam slam --odometry``): a simulated log
with its odometry withheld, and bags written here without an odometry topic, with and without an
IMU."""

from __future__ import annotations

import json
import math
import sys
from dataclasses import replace
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from crlam import _native
from crlam.cli import main
from crlam.errors import ConfigError, DataFormatError
from crlam.io import ImuReading, LaserScan, open_log, read_scans_any
from crlam.io.rosbag_writer import McapBagWriter
from crlam.io.tum import read_tum
from crlam.pose import between, compose
from crlam.slam import SlamConfig
from crlam.slam.grid_alignment import frame_from_record, from_map_frame
from crlam.slam.scan_odometry import (
    SCAN_MATCH_MOTION_PARAMS,
    ImuYaw,
    ScanMatchOdometry,
    ScanOdometryConfig,
    resolve_odometry,
    scan_match_filter_config,
    scan_match_odometry,
)

if sys.version_info >= (3, 11):
    import tomllib
else:  # pragma: no cover
    import tomli as tomllib

N_SCANS = 200
#: Bag stamps are the log's plus this (a header stamp of 0 reads as "no stamp").
BAG_T0 = 1000.0


@pytest.fixture(scope="module")
def sim(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A simulated log (office world, SICK-like laser, 200 scans at 10 Hz, about 6 m)."""
    out = tmp_path_factory.mktemp("sim")
    argv = ["simulate", "--scans", str(N_SCANS), "--world", "office", "--sensor", "sick", "--out", str(out), "--quiet"]
    assert main(argv) == 0
    return out


def _truth(sim: Path, stamps: list[float], t0: float = 0.0) -> np.ndarray:
    """The ground-truth poses at the log's scan stamps (``stamps - t0``)."""
    ref = read_tum(sim / "groundtruth.tum")
    k = np.searchsorted(ref.timestamps, np.asarray(stamps) - t0 - 1e-6)
    assert np.allclose(ref.timestamps[k], np.asarray(stamps) - t0, atol=1e-6)
    return ref.poses[k]


def _errors(poses: np.ndarray, truth: np.ndarray) -> tuple[float, float]:
    """Largest position (m) and heading (rad) error once the first poses are made to coincide."""
    aligned = np.array([compose(truth[0], between(poses[0], p)) for p in poses])
    d = aligned - truth
    heading = np.abs((d[:, 2] + math.pi) % (2 * math.pi) - math.pi)
    return float(np.max(np.hypot(d[:, 0], d[:, 1]))), float(np.max(heading))


def test_front_end_follows_the_truth_and_ignores_the_logs_odometry(sim: Path) -> None:
    scans = list(read_scans_any(sim / "log.clf"))
    stamps = [s.timestamp for s in scans]
    truth = _truth(sim, stamps)
    fe = ScanMatchOdometry()
    poses = np.array([s.odom for s in scan_match_odometry(scans, front_end=fe)])
    # Odometry withheld: the same scans with nonsense odometry after the first give the same poses.
    garbage = [s if i == 0 else replace(s, odom=np.array([10.0 * i, -3.0, 0.7 * i])) for i, s in enumerate(scans)]
    again = np.array([s.odom for s in scan_match_odometry(garbage)])
    np.testing.assert_array_equal(poses, again)
    np.testing.assert_array_equal(poses[0], scans[0].odom)  # starts at the first scan's odometry pose
    pos_err, head_err = _errors(poses, truth)
    wheel_pos, wheel_head = _errors(np.array([s.odom for s in scans]), truth)
    assert pos_err < 0.1 and head_err < math.radians(1.5), (pos_err, math.degrees(head_err))
    assert pos_err < wheel_pos and head_err < wheel_head
    st = fe.stats
    assert st.n_scans == N_SCANS and st.n_matched >= N_SCANS - 5
    assert st.n_keyframes > 10 and st.n_imu_scans == 0
    assert st.path_length_m == pytest.approx(json.loads((sim / "simulation.json").read_text())["path_length_m"], rel=0.3)


def test_local_map_is_rebuilt_from_its_last_key_scans(sim: Path) -> None:
    fe = ScanMatchOdometry(ScanOdometryConfig(window=3, keyframe_distance=0.05))
    for _ in scan_match_odometry(read_scans_any(sim / "log.clf"), front_end=fe):
        pass
    assert fe.stats.n_rebuilds >= 5
    assert 3 <= fe.n_key_scans_mapped <= 6  # between window and 2 x window key scans


def test_local_map_matcher_keeps_the_start_on_an_empty_map() -> None:
    m = _native.LocalMapMatcher()
    angles = np.linspace(-1.5, 1.5, 31)
    start = np.array([1.0, 2.0, 0.3])
    pose, score, matched, used = m.match_scan(start, angles, np.full(31, 2.0), np.zeros(3))
    assert pose == tuple(start) and score == 0.0 and matched == 0 and used == 31
    with pytest.raises(ConfigError):
        m.insert(start, angles, np.ones(30), np.zeros(3))


def test_imu_yaw_integrates_the_rate() -> None:
    imu = ImuYaw()
    assert not imu and imu.change(0.0, 1.0) == 0.0
    for k in range(11):
        imu.add(0.1 * k, 0.5 + 0.2 * (0.1 * k))  # a linear ramp: trapezoids are exact
    assert imu.change(0.25, 0.75) == pytest.approx(0.5 * 0.5 + 0.1 * (0.75**2 - 0.25**2))
    assert imu.change(0.5, 0.5) == 0.0 and imu.change(0.7, 0.2) == 0.0
    assert imu.change(1.0, 2.0) == pytest.approx(0.7)  # the last rate held after the readings


def test_front_end_config_is_checked() -> None:
    with pytest.raises(ConfigError, match="window"):
        ScanOdometryConfig(window=0)
    with pytest.raises(ConfigError, match="resolution"):
        ScanOdometryConfig(resolution=-1.0)


def test_motion_noise_rule() -> None:
    robust = SlamConfig.from_preset()
    assert scan_match_filter_config(robust).motion_params == SCAN_MATCH_MOTION_PARAMS
    paper = SlamConfig.from_preset("paper")
    ruled = scan_match_filter_config(paper)
    assert ruled.motion == "gmapping" and ruled.motion_params == SCAN_MATCH_MOTION_PARAMS
    given = SlamConfig.from_preset(motion_params=(0.2, 0.2, 0.2, 0.2))
    assert scan_match_filter_config(given) == given
    # The wheel-odometry fit does not apply: the front end's own stated noise does.
    fitted = scan_match_filter_config(SlamConfig.from_preset(motion_noise="estimate"))
    assert fitted.motion_params == SCAN_MATCH_MOTION_PARAMS and fitted.motion_noise == "model"


def test_slam_with_scan_matching_odometry_on_a_simulated_log(sim: Path, tmp_path: Path) -> None:
    run = tmp_path / "run"
    argv = ["slam", str(sim / "log.clf"), "--out", str(run), "--odometry", "scan_match", "--particles", "5", "--quiet"]
    assert main([*argv, "--reference", str(sim / "groundtruth.tum")]) == 0
    cfg = tomllib.loads((run / "config.toml").read_text())
    assert {k: cfg["input"][k] for k in ("format", "odometry", "odometry_choice")} == {
        "format": "carmen",
        "odometry": "scan_match",
        "odometry_choice": "given",
    }
    assert set(cfg["input"]) == {"format", "odometry", "odometry_choice", "lidar"}
    assert tuple(cfg["slam"]["motion_params"]) == SCAN_MATCH_MOTION_PARAMS and cfg["slam"]["motion"] == "gmapping"
    assert cfg["scan_odometry"]["window"] == ScanOdometryConfig().window
    m = json.loads((run / "metrics.json").read_text())
    assert m["input"]["odometry"] == "scan_match" and m["scan_odometry"]["n_matched"] >= N_SCANS - 5
    assert m["reference"]["rmse_position_m"] < 0.1
    # --config repeats the odometry choice.
    assert (
        main(["slam", str(sim / "log.clf"), "--out", str(tmp_path / "again"), "--config", str(run / "config.toml"), "--quiet"])
        == 0
    )
    assert (tmp_path / "again" / "trajectory.tum").read_text() == (run / "trajectory.tum").read_text()
    # The wheel odometry is the default for a CARMEN log.
    assert resolve_odometry(sim / "log.clf") == ("wheel", "auto: a CARMEN log has odometry in every scan record")


def _imu_message(w: McapBagWriter, t: float, rate_xyz: tuple[float, float, float]) -> Any:
    T = w.types
    vec = T["geometry_msgs/msg/Vector3"]
    return T["sensor_msgs/msg/Imu"](
        header=w.header(t, "imu_link"),
        orientation=T["geometry_msgs/msg/Quaternion"](x=0.0, y=0.0, z=0.0, w=1.0),
        orientation_covariance=np.full(9, -1.0),
        angular_velocity=vec(x=rate_xyz[0], y=rate_xyz[1], z=rate_xyz[2]),
        angular_velocity_covariance=np.zeros(9),
        linear_acceleration=vec(x=0.0, y=0.0, z=9.81),
        linear_acceleration_covariance=np.zeros(9),
    )


def write_scan_bag(sim: Path, path: Path, *, imu: bool = False) -> tuple[Path, list[float], np.ndarray]:
    """The simulated log's scans as a ROS 2 bag with no odometry (/scan, /tf_static
    base_link -> laser, and with ``imu`` an IMU mounted upside down on /imu at twice the scan
    rate, its yaw rates from the ground truth; stamps shifted by ``BAG_T0``). Returns the path,
    the IMU stamps and the base frame's yaw rates written."""
    scans = list(read_scans_any(sim / "log.clf"))
    ref = read_tum(sim / "groundtruth.tum")
    t_imu = np.arange(ref.timestamps[0], ref.timestamps[-1], 0.05)
    yaw = np.unwrap(ref.poses[:, 2])
    rates = np.interp(t_imu, 0.5 * (ref.timestamps[1:] + ref.timestamps[:-1]), np.diff(yaw) / np.diff(ref.timestamps))
    with McapBagWriter(path) as w:
        T = w.types
        mount = w.transform(0.0, "base_link", "laser", scans[0].laser_offset)
        # The IMU upside down (roll pi): its z axis points down, so it reads minus the yaw rate.
        q = T["geometry_msgs/msg/Quaternion"](x=1.0, y=0.0, z=0.0, w=0.0)
        imu_mount = T["geometry_msgs/msg/TransformStamped"](
            header=w.header(0.0, "base_link"),
            child_frame_id="imu_link",
            transform=T["geometry_msgs/msg/Transform"](
                translation=T["geometry_msgs/msg/Vector3"](x=0.0, y=0.0, z=0.1), rotation=q
            ),
        )
        w.write("/tf_static", "tf2_msgs/msg/TFMessage", 0, w.tf([mount, imu_mount]), latched=True)
        events: list[tuple[float, str, Any]] = []
        for s in scans:
            t = s.timestamp + BAG_T0
            events.append((t, "/scan", w.laser_scan(t, "laser", s.ranges, s.angle_min, s.angle_increment, s.max_range)))
        if imu:
            for t, r in zip(t_imu + BAG_T0, rates):
                events.append((float(t), "/imu", _imu_message(w, float(t), (0.0, 0.0, -float(r)))))
        for t, topic, msg in sorted(events, key=lambda e: e[0]):
            kind = "sensor_msgs/msg/Imu" if topic == "/imu" else "sensor_msgs/msg/LaserScan"
            w.write(topic, kind, round(t * 1e9) + 1, msg)
    return path, [float(t) + BAG_T0 for t in t_imu], rates


def test_bag_without_odometry_selects_scan_matching(sim: Path, tmp_path: Path) -> None:
    bag, _, _ = write_scan_bag(sim, tmp_path / "bag")
    assert resolve_odometry(bag)[0] == "scan_match"
    with pytest.raises(DataFormatError, match="--odometry scan_match"):
        list(open_log(bag))
    run = tmp_path / "run"
    assert main(["slam", str(bag), "--out", str(run), "--particles", "5", "--quiet"]) == 0
    cfg = tomllib.loads((run / "config.toml").read_text())
    assert cfg["input"]["odometry"] == "scan_match" and cfg["input"]["odometry_choice"].startswith("auto")
    assert cfg["input"]["odom_topic"] == "" and cfg["input"]["imu_topic"] == ""
    assert cfg["input"]["base_frame"] == "base_link" and cfg["input"]["mount_source"] == "tf_static"
    est = read_tum(run / "trajectory.tum")
    # The run writes its map's frame (turned onto the first scan's walls); in the odometry's frame,
    # with no odometry, it starts at the origin.
    frame = frame_from_record(json.loads((run / "metrics.json").read_text())["map_frame"])
    poses = from_map_frame(frame, est.poses)
    np.testing.assert_allclose(poses[0], np.zeros(3), atol=1e-9)
    pos_err, _ = _errors(poses, _truth(sim, list(est.timestamps), BAG_T0))
    assert pos_err < 0.15
    assert main(["slam", str(bag), "--out", str(tmp_path / "wheel"), "--odometry", "wheel", "--quiet"]) == 2  # no odometry


def test_bag_with_an_imu(sim: Path, tmp_path: Path) -> None:
    bag, t_imu, rates = write_scan_bag(sim, tmp_path / "bag", imu=True)
    records = list(open_log(bag, odometry=False, imu=True))
    imu = [r for r in records if isinstance(r, ImuReading)]
    scans = [r for r in records if isinstance(r, LaserScan)]
    assert len(scans) == N_SCANS and all(np.all(np.isnan(s.odom)) for s in scans)
    # The upside-down mount is undone: the yaw rates read back are the base frame's.
    np.testing.assert_allclose([r.yaw_rate for r in imu], rates, atol=1e-12)
    np.testing.assert_allclose([r.timestamp for r in imu], t_imu, atol=1e-9)
    fe = ScanMatchOdometry()
    poses = np.array([s.odom for s in scan_match_odometry(records, front_end=fe)])
    assert fe.stats.n_imu_readings == len(imu) and fe.stats.n_imu_scans == N_SCANS - 1
    pos_err, head_err = _errors(poses, _truth(sim, [s.timestamp for s in scans], BAG_T0))
    assert pos_err < 0.1 and head_err < math.radians(1.5)
    run = tmp_path / "run"
    assert main(["slam", str(bag), "--out", str(run), "--particles", "5", "--max-scans", "50", "--quiet"]) == 0
    m = json.loads((run / "metrics.json").read_text())
    assert m["input"]["imu_topic"] == "/imu" and m["scan_odometry"]["n_imu_scans"] == 49
