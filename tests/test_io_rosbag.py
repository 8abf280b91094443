"""ROS bag input: small bags written here with rosbags' writers (ROS 2 sqlite3 and MCAP, ROS 1),
and the recorded bags of the shared data folder (``realdata``)."""

from __future__ import annotations

import json
import math
import sys
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from rosbags.rosbag1 import Writer as Writer1
from rosbags.rosbag2 import StoragePlugin
from rosbags.rosbag2 import Writer as Writer2
from rosbags.typesys import Stores, get_types_from_msg, get_typestore

from crlam.cli import main
from crlam.errors import ConfigError, DataFormatError
from crlam.experiments.known_poses import map_log
from crlam.io import LaserScan, OdometryReading, RosbagReader, is_bag, open_log, read_scans_any
from crlam.mapping import MappingConfig
from crlam.pose import compose

if sys.version_info >= (3, 11):
    import tomllib
else:  # pragma: no cover
    import tomli as tomllib


LASER = "sensor_msgs/msg/LaserScan"
MULTI = "sensor_msgs/msg/MultiEchoLaserScan"
ODOM = "nav_msgs/msg/Odometry"
TF = "tf2_msgs/msg/TFMessage"


def _quat(roll: float = 0.0, pitch: float = 0.0, yaw: float = 0.0) -> tuple[float, float, float, float]:
    cr, sr = math.cos(roll / 2), math.sin(roll / 2)
    cp, sp = math.cos(pitch / 2), math.sin(pitch / 2)
    cy, sy = math.cos(yaw / 2), math.sin(yaw / 2)
    return (
        sr * cp * cy - cr * sp * sy,
        cr * sp * cy + sr * cp * sy,
        cr * cp * sy - sr * sp * cy,
        cr * cp * cy + sr * sp * sy,
    )


def _rot(roll: float, pitch: float, yaw: float) -> np.ndarray:
    rx = np.array([[1, 0, 0], [0, math.cos(roll), -math.sin(roll)], [0, math.sin(roll), math.cos(roll)]])
    ry = np.array([[math.cos(pitch), 0, math.sin(pitch)], [0, 1, 0], [-math.sin(pitch), 0, math.cos(pitch)]])
    rz = np.array([[math.cos(yaw), -math.sin(yaw), 0], [math.sin(yaw), math.cos(yaw), 0], [0, 0, 1]])
    return rz @ ry @ rx


@dataclass
class BagSpec:
    """What a synthetic bag holds. The robot drives along x at 0.5 m/s turning at 0.2 rad/s;
    odometry at 20 Hz from t = 100 s, scans at 5 Hz stamped between odometry readings."""

    scan_topics: tuple[str, ...] = ("/scan",)
    scan_type: str = LASER
    odom_topic: str | None = "/odom"
    odom_in_tf: bool = False
    static: list[tuple[str, str, tuple[float, float, float], tuple[float, float, float]]] = field(default_factory=list)
    laser_frame: str = "laser"
    base_frame: str = "base_link"
    ranges: np.ndarray | None = None
    angle_min: float = -math.pi / 2
    angle_increment: float = math.pi / 8
    n_beams: int = 9
    range_min: float = 0.1
    range_max: float = 10.0
    n_scans: int = 10
    first_scan: float = 100.11
    odom_clock_offset: float = 0.0
    swap_odom_pairs: bool = False
    # Transforms published on /tf with every odometry step (a fixed mount that is not on
    # /tf_static); with tf_fixed_drift the last one moves by 1 mm a step.
    tf_fixed: list[tuple[str, str, tuple[float, float, float], tuple[float, float, float]]] = field(default_factory=list)
    tf_fixed_drift: bool = False
    echo_intensities: tuple[float, float] = (0.0, 0.0)


def odom_pose(t: float) -> np.ndarray:
    dt = t - 100.0
    return np.array([0.5 * dt, 0.1 * dt * dt, 0.2 * dt])


def _header(ts: Any, t: float, frame: str) -> Any:
    Header = ts.types["std_msgs/msg/Header"]
    Time = ts.types["builtin_interfaces/msg/Time"]
    sec = int(math.floor(t))
    stamp = Time(sec=sec, nanosec=int(round((t - sec) * 1e9)))
    if "seq" in Header.__dataclass_fields__:
        return Header(seq=0, stamp=stamp, frame_id=frame)
    return Header(stamp=stamp, frame_id=frame)


def _transform_stamped(ts: Any, t: float, parent: str, child: str, xyz: tuple, rpy: tuple) -> Any:
    T = ts.types
    q = _quat(*rpy)
    return T["geometry_msgs/msg/TransformStamped"](
        header=_header(ts, t, parent),
        child_frame_id=child,
        transform=T["geometry_msgs/msg/Transform"](
            translation=T["geometry_msgs/msg/Vector3"](x=xyz[0], y=xyz[1], z=xyz[2]),
            rotation=T["geometry_msgs/msg/Quaternion"](x=q[0], y=q[1], z=q[2], w=q[3]),
        ),
    )


def _messages(spec: BagSpec, ts: Any) -> list[tuple[str, str, float, Any]]:
    """(topic, type, receive time, message) in time order."""
    T = ts.types
    out: list[tuple[str, str, float, Any]] = []
    if spec.static:
        tfs = [_transform_stamped(ts, 99.0, p, c, xyz, rpy) for p, c, xyz, rpy in spec.static]
        out.append(("/tf_static", TF, 99.0, T[TF](transforms=tfs)))
    for k in range(41):
        t = t_recv = 100.0 + 0.05 * k
        if spec.swap_odom_pairs and k < 40:  # stamps of readings 0 and 1, 2 and 3, ... arrive swapped
            t += 0.05 if k % 2 == 0 else -0.05
        x, y, th = odom_pose(t)
        t += spec.odom_clock_offset  # the stamp (a clock other than the scans' when nonzero)
        t = round(t, 6)
        tfs = []
        if spec.odom_in_tf:
            tfs = [
                _transform_stamped(ts, t, "odom", spec.base_frame, (x, y, 0.0), (0.0, 0.0, th)),
                _transform_stamped(ts, t, "odom", "base_footprint", (x + 5, y, 0.0), (0.0, 0.0, th)),
            ]
        for i, (p, c, xyz, rpy) in enumerate(spec.tf_fixed):
            shift = 0.001 * k if spec.tf_fixed_drift and i == len(spec.tf_fixed) - 1 else 0.0
            tfs.append(_transform_stamped(ts, t, p, c, (xyz[0] + shift, xyz[1], xyz[2]), rpy))
        if tfs:
            out.append(("/tf", TF, t_recv, T[TF](transforms=tfs)))
        if spec.odom_topic is not None:
            q = _quat(yaw=th)
            pose = T["geometry_msgs/msg/Pose"](
                position=T["geometry_msgs/msg/Point"](x=x, y=y, z=0.0),
                orientation=T["geometry_msgs/msg/Quaternion"](x=q[0], y=q[1], z=q[2], w=q[3]),
            )
            vec = T["geometry_msgs/msg/Vector3"]
            msg = T[ODOM](
                header=_header(ts, t, "odom"),
                child_frame_id=spec.base_frame,
                pose=T["geometry_msgs/msg/PoseWithCovariance"](pose=pose, covariance=np.zeros(36)),
                twist=T["geometry_msgs/msg/TwistWithCovariance"](
                    twist=T["geometry_msgs/msg/Twist"](linear=vec(x=0.5, y=0.0, z=0.0), angular=vec(x=0.0, y=0.0, z=0.2)),
                    covariance=np.zeros(36),
                ),
            )
            out.append((spec.odom_topic, ODOM, t_recv, msg))
    ranges = spec.ranges if spec.ranges is not None else np.linspace(1.0, 3.0, spec.n_beams)
    for k in range(spec.n_scans):
        t = spec.first_scan + 0.2 * k
        common = dict(
            header=_header(ts, t, spec.laser_frame),
            angle_min=spec.angle_min,
            angle_max=spec.angle_min + spec.angle_increment * (len(ranges) - 1),
            angle_increment=spec.angle_increment,
            time_increment=0.0,
            scan_time=0.2,
            range_min=spec.range_min,
            range_max=spec.range_max,
        )
        for topic in spec.scan_topics:
            if spec.scan_type == MULTI:
                Echo = T["sensor_msgs/msg/LaserEcho"]
                msg = T[MULTI](
                    **common,
                    ranges=[Echo(echoes=np.array([r, r + 1.0], dtype=np.float32)) for r in ranges],
                    intensities=[Echo(echoes=np.array(spec.echo_intensities, dtype=np.float32)) for _ in ranges],
                )
            else:
                msg = T[LASER](**common, ranges=np.asarray(ranges, dtype=np.float32), intensities=np.zeros(0, dtype=np.float32))
            out.append((topic, spec.scan_type, t + 0.01, msg))
    out.sort(key=lambda m: m[2])
    return out


def write_bag(path: Path, spec: BagSpec, kind: str = "sqlite3") -> Path:
    """Write a ROS 2 bag folder (``sqlite3`` or ``mcap``) or a ROS 1 ``.bag`` (``ros1``)."""
    if kind == "ros1":
        ts = get_typestore(Stores.ROS1_NOETIC)
        ts.register(get_types_from_msg("geometry_msgs/TransformStamped[] transforms", TF))
        path = path.with_suffix(".bag")
        with Writer1(path) as w:
            conns: dict[str, Any] = {}
            for topic, typ, t, msg in _messages(spec, ts):
                if topic not in conns:
                    conns[topic] = w.add_connection(topic, typ, typestore=ts)
                w.write(conns[topic], int(t * 1e9), ts.serialize_ros1(msg, typ))
        return path
    ts = get_typestore(Stores.ROS2_HUMBLE)
    plugin = StoragePlugin.MCAP if kind == "mcap" else StoragePlugin.SQLITE3
    with Writer2(path, version=9, storage_plugin=plugin) as w:
        conns = {}
        for topic, typ, t, msg in _messages(spec, ts):
            if topic not in conns:
                conns[topic] = w.add_connection(topic, typ, typestore=ts)
            w.write(conns[topic], int(t * 1e9), ts.serialize_cdr(msg, typ))
    return path


def scans_of(path: Path, **options: Any) -> tuple[list[LaserScan], RosbagReader]:
    reader = open_log(path, **options)
    assert isinstance(reader, RosbagReader)
    scans = [r for r in reader if isinstance(r, LaserScan)]
    return scans, reader


# -- formats, odometry and dispatch -------------------------------------------------------------


@pytest.mark.parametrize("kind", ["sqlite3", "mcap", "ros1"])
def test_every_format_gives_scans_with_interpolated_odometry(tmp_path: Path, kind: str) -> None:
    bag = write_bag(tmp_path / "bag", BagSpec(), kind)
    assert is_bag(bag)
    reader = open_log(bag)
    records = list(reader)
    scans = [r for r in records if isinstance(r, LaserScan)]
    odom = [r for r in records if isinstance(r, OdometryReading)]
    assert len(scans) == 10 and len(odom) == 41
    st = reader.stats
    assert st.n_scans == 10 and st.n_odometry == 41
    assert (st.scan_topic, st.odom_topic, st.base_frame, st.laser_frame) == ("/scan", "/odom", "base_link", "laser")
    for s in scans:
        # Odometry is linear in x inside each 50 ms step; y and yaw are close to linear.
        np.testing.assert_allclose(s.odom, odom_pose(s.timestamp), atol=2e-3)
        np.testing.assert_allclose(s.pose, s.odom)  # no /tf_static: the laser at the base origin
        assert s.kind == "LaserScan" and s.max_range == pytest.approx(10.0)
    assert st.mount_source.startswith("none")
    assert scans[0].timestamp == pytest.approx(100.11)
    np.testing.assert_allclose(scans[0].angles, -math.pi / 2 + math.pi / 8 * np.arange(9), atol=1e-6)


def test_a_plain_mcap_file_is_a_bag(tmp_path: Path) -> None:
    folder = write_bag(tmp_path / "bag", BagSpec(), "mcap")
    (mcap,) = folder.glob("*.mcap")
    assert is_bag(mcap)
    scans = list(read_scans_any(mcap))
    assert len(scans) == 10


def test_scans_beyond_the_odometry_are_skipped_and_counted(tmp_path: Path) -> None:
    # Odometry spans 100..102 s; scans at 99.5 .. 103.1 s: 99.5 and 99.7 are too early
    # (more than 0.25 s before), 99.9 takes the first reading, 102.1 the last, later ones are skipped.
    bag = write_bag(tmp_path / "bag", BagSpec(first_scan=99.5, n_scans=19))
    scans, reader = scans_of(bag)
    st = reader.stats
    assert st.skipped_before_odometry == 2
    assert st.skipped_after_odometry == 19 - 2 - len(scans)
    assert [round(s.timestamp, 1) for s in scans][:2] == [99.9, 100.1]
    np.testing.assert_allclose(scans[0].odom, odom_pose(100.0), atol=1e-9)
    np.testing.assert_allclose(scans[-1].odom, odom_pose(102.0), atol=1e-9)


@pytest.mark.parametrize("history", [4096, 8])
def test_odometry_out_of_stamp_order_is_sorted(tmp_path: Path, monkeypatch: pytest.MonkeyPatch, history: int) -> None:
    import crlam.io.rosbag as rb

    monkeypatch.setattr(rb, "_ODOM_HISTORY", history)  # 8: the history is full when readings come out of order
    bag = write_bag(tmp_path / "bag", BagSpec(swap_odom_pairs=True))
    scans, reader = scans_of(bag)
    assert len(scans) == 10 and reader.stats.n_odometry == 41
    for s in scans:
        np.testing.assert_allclose(s.odom, odom_pose(s.timestamp), atol=2e-3)


def test_odometry_on_another_clock_is_an_error_that_says_so(tmp_path: Path) -> None:
    bag = write_bag(tmp_path / "bag", BagSpec(odom_clock_offset=-1000.0))
    with pytest.raises(DataFormatError, match=r"10 after the odometry.*same clock"):
        list(open_log(bag))


def test_odometry_only_in_tf(tmp_path: Path) -> None:
    spec = BagSpec(odom_topic=None, odom_in_tf=True, static=[("base_link", "laser", (0.2, 0.0, 0.1), (0.0, 0.0, 0.0))])
    bag = write_bag(tmp_path / "bag", spec)
    scans, reader = scans_of(bag)
    st = reader.stats
    assert st.odom_topic == "/tf" and st.n_odometry == 41
    # base_link (reached by /tf_static from the laser) wins over base_footprint (shifted by 5 m).
    assert st.base_frame == "base_link"
    for s in scans:
        np.testing.assert_allclose(s.odom, odom_pose(s.timestamp), atol=2e-3)
        np.testing.assert_allclose(s.pose, compose(s.odom, np.array([0.2, 0.0, 0.0])), atol=1e-9)
    # --base-frame picks the other child of odom.
    scans, reader = scans_of(bag, base_frame="base_footprint")
    assert reader.stats.base_frame == "base_footprint"
    assert scans[0].odom[0] == pytest.approx(odom_pose(scans[0].timestamp)[0] + 5, abs=2e-3)


def test_a_base_frame_other_than_the_odometry_child_is_refused(tmp_path: Path) -> None:
    bag = write_bag(tmp_path / "bag", BagSpec())
    with pytest.raises(ConfigError, match="child frame of /odom, base_link"):
        list(open_log(bag, base_frame="base_footprint"))
    _, reader = scans_of(bag, base_frame="base_link")
    assert reader.stats.base_frame == "base_link"


def test_odom_topic_tf_forces_tf_odometry(tmp_path: Path) -> None:
    bag = write_bag(tmp_path / "bag", BagSpec(odom_in_tf=True))
    _, reader = scans_of(bag, odom_topic="/tf")
    assert reader.stats.odom_topic == "/tf"


# -- invalid readings and angle layouts -------------------------------------------------------


def test_every_invalid_reading_becomes_a_no_return(tmp_path: Path) -> None:
    ranges = np.array([1.0, np.inf, np.nan, 0.0, -1.0, 0.05, 12.0, 10.0, -np.inf, 2.5], dtype=np.float32)
    bag = write_bag(tmp_path / "bag", BagSpec(ranges=ranges, n_scans=3))
    scans, reader = scans_of(bag)
    expected = np.array([1.0, 10, 10, 10, 10, 10, 10, 10, 10, 2.5])
    for s in scans:
        np.testing.assert_allclose(s.ranges, expected, rtol=1e-6)
        assert np.all(np.isfinite(s.ranges))
    st = reader.stats
    assert (st.n_inf_ranges, st.n_nan_ranges, st.n_nonpositive_ranges) == (3, 3, 9)
    assert (st.n_below_min_ranges, st.n_above_max_ranges) == (3, 3)
    assert st.n_no_return_ranges == 3 * 8  # the reading at exactly range_max included
    # Downstream, every one of them is a no-return (inf), the valid ones are kept.
    from crlam.experiments.known_poses import mapping_ranges

    r = mapping_ranges(scans[0])
    assert np.isinf(r[1:9]).all() and r[0] == pytest.approx(1.0) and r[9] == pytest.approx(2.5)


def _bearing_ranges(s: LaserScan) -> dict[int, float]:
    """Range per bearing (quarter degrees, rounded, in [0, 1440))."""
    return {int(round(4 * math.degrees(a))) % 1440: float(r) for a, r in zip(s.angles, s.ranges)}


@pytest.mark.parametrize(
    ("angle_min", "increment"),
    [
        (-math.pi / 2, math.pi / 8),  # -90..+90
        (math.pi / 2, -math.pi / 8),  # reversed: +90..-90
        (0.0, math.pi / 4),  # 0..360 layout (0..320 deg here)
        (-math.pi, math.pi / 4),  # -180..180
    ],
)
def test_any_angle_layout_keeps_each_range_at_its_bearing(tmp_path: Path, angle_min: float, increment: float) -> None:
    ranges = np.linspace(1.0, 3.0, 9)
    bag = write_bag(tmp_path / "bag", BagSpec(ranges=ranges, angle_min=angle_min, angle_increment=increment, n_scans=2))
    scans, _ = scans_of(bag)
    s = scans[0]
    assert s.angle_increment > 0
    want = {int(round(4 * math.degrees(angle_min + increment * i))) % 1440: float(r) for i, r in enumerate(ranges)}
    got = _bearing_ranges(s)
    assert got.keys() == want.keys()
    for k in want:
        assert got[k] == pytest.approx(want[k], rel=1e-6)


def test_multi_echo_scans_use_the_first_echo(tmp_path: Path) -> None:
    bag = write_bag(tmp_path / "bag", BagSpec(scan_type=MULTI, n_scans=2), "mcap")
    scans, _ = scans_of(bag)
    assert scans[0].kind == "MultiEchoLaserScan"
    np.testing.assert_allclose(scans[0].ranges, np.linspace(1.0, 3.0, 9), rtol=1e-6)


# -- laser mount --------------------------------------------------------------------------------


def _world_endpoints_3d(odom: np.ndarray, xyz: tuple, rpy: tuple, angles: np.ndarray, ranges: np.ndarray) -> np.ndarray:
    """Beam endpoints in the odometry frame, computed in 3D from the mount (x, y only)."""
    rot = _rot(*rpy)
    pts = np.stack([ranges * np.cos(angles), ranges * np.sin(angles), np.zeros_like(angles)])
    base = (rot @ pts)[:2] + np.array(xyz[:2])[:, None]
    c, s = math.cos(odom[2]), math.sin(odom[2])
    return (np.array([[c, -s], [s, c]]) @ base + odom[:2, None]).T


def _same_points(got: np.ndarray, want: np.ndarray) -> None:
    """The same set of 2D points, in any order (a mirrored scan is stored reversed)."""
    assert got.shape == want.shape
    d = np.linalg.norm(got[:, None, :] - want[None, :, :], axis=2)
    assert d.min(axis=0).max() < 1e-6 and d.min(axis=1).max() < 1e-6


def _endpoints(s: LaserScan) -> np.ndarray:
    sensor = compose(s.odom, s.laser_offset)
    a = sensor[2] + s.angles
    return np.stack([sensor[0] + s.ranges * np.cos(a), sensor[1] + s.ranges * np.sin(a)], axis=1)


@pytest.mark.parametrize(
    "rpy",
    [(0.0, 0.0, 0.3), (math.pi, 0.0, 0.3), (0.0, math.pi, -0.5)],
    ids=["upright", "upside-down-roll", "upside-down-pitch"],
)
def test_mount_from_tf_static_through_a_chain(tmp_path: Path, rpy: tuple) -> None:
    xyz = (0.15, -0.05, 0.3)
    # base_link -> plate (static, pure translation) -> laser (the rotation): composed along the chain.
    static = [
        ("base_link", "plate", (0.05, 0.0, 0.2), (0.0, 0.0, 0.0)),
        ("plate", "laser", (xyz[0] - 0.05, xyz[1], xyz[2] - 0.2), rpy),
    ]
    ranges = np.linspace(1.0, 3.0, 9)
    bag = write_bag(tmp_path / "bag", BagSpec(static=static, ranges=ranges, n_scans=3), "sqlite3")
    scans, reader = scans_of(bag)
    st = reader.stats
    assert st.mount_source == "tf_static"
    assert st.upside_down == (rpy != (0.0, 0.0, 0.3))
    for s in scans:
        want = _world_endpoints_3d(s.odom, xyz, rpy, -math.pi / 2 + math.pi / 8 * np.arange(9), ranges)
        _same_points(_endpoints(s), want)


def test_user_mount_and_upside_down_flag(tmp_path: Path) -> None:
    static = [("base_link", "laser", (0.3, 0.0, 0.0), (0.0, 0.0, 0.0))]
    ranges = np.linspace(1.0, 3.0, 9)
    bag = write_bag(tmp_path / "bag", BagSpec(static=static, ranges=ranges, n_scans=2))
    scans, reader = scans_of(bag, laser_mount=(0.1, 0.2, 0.5), upside_down=True)
    assert reader.stats.mount_source == "user" and reader.stats.upside_down
    np.testing.assert_allclose(scans[0].laser_offset, [0.1, 0.2, 0.5])
    # the flag mirrors: the message's bearing b is seen at -b
    b = -math.pi / 2 + math.pi / 8 * np.arange(9)
    want = _world_endpoints_3d(scans[0].odom, (0.1, 0.2, 0.0), (math.pi, 0.0, 0.5), b, ranges)
    _same_points(_endpoints(scans[0]), want)


# -- topic detection errors ---------------------------------------------------------------------


def test_missing_scan_topic_lists_the_topics(tmp_path: Path) -> None:
    bag = write_bag(tmp_path / "bag", BagSpec(scan_topics=()))
    with pytest.raises(DataFormatError, match=r"no sensor_msgs/msg/LaserScan topic.*/odom \(nav_msgs/msg/Odometry\)"):
        list(open_log(bag))
    bag2 = write_bag(tmp_path / "bag2", BagSpec())
    with pytest.raises(DataFormatError, match=r"'/front_scan' not in the bag.*/scan \(sensor_msgs/msg/LaserScan\)"):
        list(open_log(bag2, scan_topic="/front_scan"))
    with pytest.raises(DataFormatError, match=r"not nav_msgs/msg/Odometry"):
        list(open_log(bag2, odom_topic="/scan"))


def test_missing_odometry_lists_the_topics(tmp_path: Path) -> None:
    bag = write_bag(tmp_path / "bag", BagSpec(odom_topic=None))
    with pytest.raises(DataFormatError, match=r"no odometry.*/scan \(sensor_msgs/msg/LaserScan\)"):
        list(open_log(bag))


def test_two_scan_topics_are_ambiguous_until_one_is_chosen(tmp_path: Path) -> None:
    bag = write_bag(tmp_path / "bag", BagSpec(scan_topics=("/scan_front", "/scan_rear")))
    with pytest.raises(DataFormatError, match=r"several laser topics.*--scan-topic"):
        list(open_log(bag))
    scans, reader = scans_of(bag, scan_topic="/scan_rear")
    assert len(scans) == 10 and reader.stats.scan_topic == "/scan_rear"


def test_bag_options_are_refused_for_a_carmen_log(tmp_path: Path) -> None:
    log = tmp_path / "log.clf"
    log.write_text("ODOM 0 0 0 0 0 0 1.0 host 1.0\n")
    with pytest.raises(ConfigError, match="scan_topic"):
        open_log(log, scan_topic="/scan")
    folder = tmp_path / "folder"
    folder.mkdir()
    with pytest.raises(FileNotFoundError, match="metadata.yaml"):
        open_log(folder)


# -- commands -------------------------------------------------------------------------------------


def test_crlam_map_takes_a_bag_and_records_the_input(tmp_path: Path) -> None:
    bag = write_bag(tmp_path / "bag", BagSpec(static=[("base_link", "laser", (0.2, 0.0, 0.0), (0.0, 0.0, 0.0))]), "ros1")
    run, files = map_log(bag, tmp_path / "out", MappingConfig(resolution=0.1, max_range=10.0), progress=False)
    assert run.n_scans == 10
    summary = json.loads(files["mapping.json"].read_text())
    assert summary["input"]["format"] == "rosbag" and summary["input"]["scan_topic"] == "/scan"
    assert summary["input"]["laser_mount"] == pytest.approx([0.2, 0.0, 0.0])
    rc = main(
        [
            "map",
            str(bag),
            "--out",
            str(tmp_path / "cli"),
            "--quiet",
            "--resolution",
            "0.1",
            "--laser-mount",
            "0.1",
            "0",
            "0",
            "--upside-down",
        ]
    )
    assert rc == 0
    info = json.loads((tmp_path / "cli" / "mapping.json").read_text())["input"]
    assert info["mount_source"] == "user" and info["upside_down"] is True


def test_crlam_slam_takes_a_bag_and_writes_the_topics_to_config(tmp_path: Path) -> None:
    bag = write_bag(tmp_path / "bag", BagSpec(n_scans=10), "mcap")
    out = tmp_path / "run"
    rc = main(["slam", str(bag), "--out", str(out), "--particles", "3", "--quiet", "--odom-topic", "/odom"])
    assert rc == 0
    cfg = tomllib.loads((out / "config.toml").read_text())
    assert cfg["input"]["format"] == "rosbag" and cfg["input"]["odom_topic"] == "/odom"
    assert len((out / "trajectory.tum").read_text().strip().splitlines()) >= 10


def test_crlam_slam_keeps_z_max_within_the_sensors_range(tmp_path: Path) -> None:
    # A 3.5 m laser under the robust preset's 8 m: no-returns must not clear cells the laser
    # cannot see, so the run's z_max is the sensor's (recorded, so --config repeats it).
    bag = write_bag(tmp_path / "bag", BagSpec(n_scans=6, range_max=3.5), "mcap")
    out = tmp_path / "run"
    assert main(["slam", str(bag), "--out", str(out), "--particles", "3", "--quiet"]) == 0
    cfg = tomllib.loads((out / "config.toml").read_text())
    assert cfg["slam"]["max_range"] == 3.5
    # A sensor that sees farther than the preset's z_max leaves it alone.
    bag = write_bag(tmp_path / "bag12", BagSpec(n_scans=6, range_max=12.0), "mcap")
    assert main(["slam", str(bag), "--out", str(tmp_path / "run12"), "--particles", "3", "--quiet"]) == 0
    assert tomllib.loads((tmp_path / "run12" / "config.toml").read_text())["slam"]["max_range"] == 8.0


def test_crlam_slam_reports_a_missing_topic(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    bag = write_bag(tmp_path / "bag", BagSpec())
    rc = main(["slam", str(bag), "--out", str(tmp_path / "run"), "--quiet", "--scan-topic", "/nope"])
    assert rc == 2
    err = capsys.readouterr().err
    assert "'/nope' not in the bag" in err and "/odom (nav_msgs/msg/Odometry)" in err


# -- recorded bags ------------------------------------------------------------------------------


def _trajectory_rows(path: Path) -> np.ndarray:
    rows = [ln.split() for ln in path.read_text().splitlines() if ln and not ln.startswith("#")]
    return np.array(rows, dtype=np.float64)


@pytest.mark.realdata
def test_turtlebot4_bag_counts_and_mount(data_dir: Path) -> None:
    bag = data_dir / "bags" / "turtlebot4-mac-floor"
    if not bag.is_dir():
        pytest.skip(f"{bag} not found")
    scans, reader = scans_of(bag)
    st = reader.stats
    assert st.n_odometry == 920
    assert st.n_scans + st.skipped_before_odometry + st.skipped_after_odometry == 357
    assert st.n_scans >= 350
    assert (st.scan_topic, st.odom_topic, st.base_frame, st.laser_frame) == ("/scan", "/odom", "base_link", "rplidar_link")
    assert st.mount_source == "tf_static" and not st.upside_down
    assert st.laser_offset[2] == pytest.approx(math.pi / 2, abs=1e-6)  # the RPLIDAR is mounted turned by 90 deg
    assert scans[0].n_beams == 720 and scans[0].max_range == pytest.approx(12.0)
    invalid = st.n_no_return_ranges / (st.n_scans * 720)
    assert 0.2 < invalid < 0.3  # "about 24 % invalid returns"
    travelled = sum(float(np.hypot(*(b.odom[:2] - a.odom[:2]))) for a, b in zip(scans, scans[1:]))
    assert 7.5 < travelled < 9.5  # "driving 8.4 m"


@pytest.mark.realdata
def test_turtlebot3_ros1_bag_counts(data_dir: Path) -> None:
    bag = data_dir / "bags" / "turtlebot3-sim-loop.bag"
    if not bag.is_file():
        pytest.skip(f"{bag} not found")
    scans, reader = scans_of(bag)
    st = reader.stats
    assert st.n_odometry == 2741
    assert st.n_scans + st.skipped_before_odometry + st.skipped_after_odometry == 457
    assert st.n_scans >= 450
    assert st.base_frame == "base_footprint" and st.mount_source.startswith("none")
    assert scans[0].n_beams == 360 and scans[0].max_range == pytest.approx(3.5)
    # The loop ends near its start (0.06 m by the README; odometry drifts a little more).
    assert float(np.hypot(*(scans[-1].odom[:2] - scans[0].odom[:2]))) < 0.5


@pytest.mark.realdata
@pytest.mark.parametrize(
    ("name", "extra"),
    [("turtlebot4-mac-floor", ["--max-range", "12"]), ("turtlebot3-sim-loop.bag", ["--max-range", "3.5"])],
)
def test_crlam_slam_runs_on_the_recorded_bags(data_dir: Path, tmp_path: Path, name: str, extra: list[str]) -> None:
    bag = data_dir / "bags" / name
    if not bag.exists():
        pytest.skip(f"{bag} not found")
    out = tmp_path / "run"
    rc = main(["slam", str(bag), "--out", str(out), "--particles", "5", "--max-scans", "60", "--quiet", *extra])
    assert rc == 0
    traj = _trajectory_rows(out / "trajectory.tum")
    assert traj.shape == (60, 8) and np.all(np.isfinite(traj))
    cfg = tomllib.loads((out / "config.toml").read_text())
    assert cfg["input"]["format"] == "rosbag" and cfg["input"]["scan_topic"] == "/scan"
    assert (out / "map.pgm").stat().st_size > 0


def test_eval_fills_a_trajectory_from_a_bag_and_diagnose_reads_one(tmp_path: Path) -> None:
    bag = write_bag(tmp_path / "bag", BagSpec(n_scans=10))
    run = tmp_path / "run"
    assert main(["slam", str(bag), "--out", str(run), "--particles", "3", "--max-scans", "4", "--quiet"]) == 0
    report = tmp_path / "eval.json"
    args = ["eval", str(run / "trajectory.tum"), "--reference", str(run / "trajectory.tum"), "--raw-log", str(bag)]
    assert main([*args, "--out", str(report)]) == 0
    fill = json.loads(report.read_text())["fill"]
    assert fill["n_scans"] == 10 and fill["n_processed"] == 4
    out = tmp_path / "diag"
    assert main(["diagnose", "likelihood-bias", str(bag), "--log-poses", "--out", str(out), "--warmup", "2"]) == 0


@pytest.mark.parametrize("kind", ["sqlite3", "mcap", "ros1"])
def test_scan_count_is_read_from_the_index_for_a_progress_total(tmp_path: Path, kind: str) -> None:
    from crlam.io.logs import count_scans

    bag = write_bag(tmp_path / "bag", BagSpec(scan_topics=("/scan", "/scan2"), n_scans=7), kind)
    # Two scan topics: the one the run would read is named; each holds n_scans messages.
    assert count_scans(bag, bag_options={"scan_topic": "/scan2"}) == 7
    assert count_scans(bag, max_scans=3, bag_options={"scan_topic": "/scan"}) == 3
    assert RosbagReader(bag, scan_topic="/scan").scan_count() == len(scans_of(bag, scan_topic="/scan")[0])
    # A topic the bag lacks: no total (the run itself then names the bag's topics).
    assert count_scans(bag, bag_options={"scan_topic": "/nope"}) is None
