"""Tests of the CARMEN reader/writer (crlam.io.carmen, crlam.io.carmen_writer)."""

from __future__ import annotations

import bz2
import gzip
import math
import string
import tempfile
from collections.abc import Iterator
from pathlib import Path

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from hypothesis.extra.numpy import arrays

from crlam.errors import DataFormatError
from crlam.io import (
    DATASETS,
    CarmenReader,
    CarmenWriter,
    DatasetNotFoundError,
    LaserScan,
    OdometryReading,
    data_root,
    dataset_path,
    flaser_geometry,
    load_log,
    read_carmen,
    read_scans,
    write_carmen,
)
from crlam.pose import compose, wrap_angle

# ----------------------------------------------------------------------------- helpers

RANGES = [round(1.0 + 0.01 * i, 2) for i in range(180)]


def flaser_line(
    ranges: list[float] | list[object] | None = None,
    n: int | None = None,
    pose: str = "1.0 2.0 0.5",
    odom: str = "1.1 2.1 0.6",
    stamps: str = "100.5 nohost 0.25",
    kind: str = "FLASER",
) -> str:
    r = RANGES if ranges is None else ranges
    count = len(r) if n is None else n
    return f"{kind} {count} {' '.join(str(v) for v in r)} {pose} {odom} {stamps}"


def vec(*values: float) -> np.ndarray:
    return np.array(values, dtype=np.float64)


ODOM_LINE = "ODOM 0.5 -0.25 0.1 0.2 0.01 0.0 99.75 nohost 0.1"


def write_text(path: Path, lines: list[str]) -> Path:
    path.write_text("".join(line + "\n" for line in lines), encoding="utf-8")
    return path


def real(relative: str) -> Path:
    root = data_root()
    if root is None:
        pytest.skip("real datasets not found: set CRLAM_DATA to the data folder (default ../shared/data beside the repository)")
    path = root / relative
    if not path.exists():
        pytest.skip(f"dataset file {path} is missing")
    return path


# ----------------------------------------------------------------------------- parsing


def test_parse_mixed_log(tmp_path: Path) -> None:
    p = write_text(
        tmp_path / "a.log",
        [
            "# a comment",
            "",
            "PARAM robot_frontlaser_offset 0.15 nohost 0",
            "PARAM robot_use_laser on nohost 0",
            ODOM_LINE,
            flaser_line(),
            "NEFF 30",
            "TRUEPOS 1 2 3 4 5 6 7 h 8",
            "SONAR 1 2 3",
        ],
    )
    reader = CarmenReader(p)
    recs = list(reader)
    assert [type(r) for r in recs] == [OdometryReading, LaserScan]
    odo, scan = recs
    assert isinstance(odo, OdometryReading)
    np.testing.assert_array_equal(odo.pose, [0.5, -0.25, 0.1])
    assert (odo.tv, odo.rv, odo.accel, odo.timestamp, odo.host, odo.logger_timestamp, odo.line) == (
        0.2,
        0.01,
        0.0,
        99.75,
        "nohost",
        0.1,
        5,
    )
    assert isinstance(scan, LaserScan)
    assert scan.n_beams == 180 and scan.kind == "FLASER" and scan.line == 6
    np.testing.assert_array_equal(scan.ranges, RANGES)
    np.testing.assert_array_equal(scan.pose, [1.0, 2.0, 0.5])
    np.testing.assert_array_equal(scan.odom, [1.1, 2.1, 0.6])
    np.testing.assert_array_equal(scan.laser_offset, [0.15, 0.0, 0.0])
    assert scan.max_range == 81.0 and scan.timestamp == 100.5 and scan.logger_timestamp == 0.25
    np.testing.assert_allclose(scan.angles[[0, 90, 179]], np.deg2rad([-90.0, 0.0, 89.0]))
    s = reader.stats
    assert s.records == {"ODOM": 1, "FLASER": 1} and s.n_scans == 1 and s.n_odometry == 1
    assert s.ignored == {"comment": 1, "blank": 1, "PARAM": 2, "NEFF": 1, "TRUEPOS": 1}
    assert s.unknown_kinds == {"SONAR": 1}
    assert s.params["robot_frontlaser_offset"] == "0.15" and s.n_lines == 9


def test_flaser_geometry_conventions() -> None:
    assert flaser_geometry(180) == pytest.approx((-math.pi / 2, math.radians(1.0)))
    assert flaser_geometry(360) == pytest.approx((-math.pi / 2, math.radians(0.5)))
    assert flaser_geometry(181) == pytest.approx((-math.pi / 2, math.radians(1.0)))


def test_flaser_options_and_rlaser(tmp_path: Path) -> None:
    p = write_text(
        tmp_path / "a.log",
        [
            "PARAM robot_rearlaser_offset 0.2 nohost 0",
            flaser_line([1.0] * 360, kind="RLASER"),
        ],
    )
    (scan,) = read_scans(p, flaser_max_range=30.0, flaser_fov=math.radians(180))
    assert scan.kind == "RLASER" and scan.max_range == 30.0
    assert scan.angle_increment == pytest.approx(math.radians(0.5))
    np.testing.assert_allclose(scan.laser_offset, [-0.2, 0.0, math.pi])


def robotlaser_line(n: int = 5, m: int = 2, laser: str = "1.2 2.0 0.5", robot: str = "1.0 2.0 0.5") -> str:
    ranges = " ".join(f"{1.0 + i:.3f}" for i in range(n))
    rem = " ".join("0.5" for _ in range(m))
    return f"ROBOTLASER1 0 -2.0 4.0 0.01 30.0 0.01 0 {n} {ranges} {m} {rem} {laser} {robot} 0.1 0.2 0.3 0.4 0.5 123.25 myhost 1.5"


def test_robotlaser1(tmp_path: Path) -> None:
    p = write_text(tmp_path / "r.log", [robotlaser_line()])
    (scan,) = read_carmen(p)
    assert isinstance(scan, LaserScan)
    assert scan.kind == "ROBOTLASER1" and scan.n_beams == 5 and scan.max_range == 30.0
    assert scan.angle_min == -2.0 and scan.angle_increment == 0.01
    np.testing.assert_array_equal(scan.pose, [1.0, 2.0, 0.5])
    np.testing.assert_array_equal(scan.odom, scan.pose)
    # The laser sits 0.2 m along the robot heading: offset (0.2 cos 0.5, -0.2 sin 0.5, 0)
    # expressed in the robot frame.
    np.testing.assert_allclose(scan.laser_offset, [0.2 * math.cos(0.5), -0.2 * math.sin(0.5), 0], atol=1e-12)
    assert (scan.timestamp, scan.host, scan.logger_timestamp) == (123.25, "myhost", 1.5)


def test_rawlaser_ignored_or_included(tmp_path: Path) -> None:
    raw = "RAWLASER1 0 -1.5 3.0 0.5 20.0 0.01 0 3 1.0 2.0 3.0 0 55.5 h 0.5"
    p = write_text(tmp_path / "r.log", [raw, ODOM_LINE])
    reader = CarmenReader(p)
    assert [type(r) for r in reader] == [OdometryReading]
    assert reader.stats.ignored == {"RAWLASER1": 1}
    scans = list(read_scans(p, include_raw=True))
    assert len(scans) == 1 and scans[0].kind == "RAWLASER1" and np.isnan(scans[0].pose).all()
    np.testing.assert_array_equal(scans[0].ranges, [1.0, 2.0, 3.0])


def test_bad_ranges_become_no_returns(tmp_path: Path) -> None:
    r = [2.0] * 180
    r[3], r[4], r[5], r[6], r[7], r[8] = math.nan, math.inf, -1.0, 0.0, 81.0, 90.0
    line = flaser_line([0.0] * 180).replace(" ".join(["0.0"] * 180), " ".join(str(v) for v in r))
    p = write_text(tmp_path / "a.log", [line])
    reader = CarmenReader(p)
    (scan,) = list(reader)
    assert isinstance(scan, LaserScan)
    np.testing.assert_array_equal(scan.ranges[3:9], [81.0, 81.0, 81.0, 81.0, 81.0, 90.0])
    s = reader.stats
    assert (s.n_nonfinite_ranges, s.n_nonpositive_ranges, s.n_no_return_ranges) == (2, 2, 6)


# ----------------------------------------------------------------------------- malformed

MALFORMED = {
    "truncated_in_ranges": (flaser_line()[:400], "range["),
    "truncated_at_end": (flaser_line().rsplit(" ", 1)[0], "logger_timestamp"),
    "fewer_beams": (flaser_line(RANGES[:179], n=180), "n_beams"),
    "more_beams": (flaser_line(RANGES + [3.0], n=180), "n_beams"),
    "non_numeric_range": (flaser_line([*RANGES[:17], "abc", *RANGES[18:]]), "range[17]"),
    "nan_odom_theta": (flaser_line(odom="1.0 2.0 nan"), "odom_theta"),
    "inf_x": (flaser_line(pose="inf 2.0 0.1"), "x"),
    "inf_stamp": (flaser_line(stamps="inf nohost 0.0"), "ipc_timestamp"),
    "bad_logger_stamp": (flaser_line(stamps="1.0 nohost x"), "logger_timestamp"),
    "n_not_integer": (flaser_line().replace("FLASER 180", "FLASER 18x", 1), "n_beams"),
    "n_zero": ("FLASER 0 1 2 3 4 5 6 7.0 h 8.0", "n_beams"),
    "odom_missing_field": (ODOM_LINE.replace(" 0.2 ", " "), "n_fields"),
    "odom_nan": (ODOM_LINE.replace("0.5", "nan", 1), "x"),
    "odom_truncated": ("ODOM 1 2 3 4", "rv"),
    "param_offset": ("PARAM robot_frontlaser_offset abc nohost 0", "robot_frontlaser_offset"),
    "robotlaser_bad_remissions": (robotlaser_line(m=3).replace(" 3 0.5", " 4 0.5"), "n_beams"),
    "robotlaser_nan_robot": (robotlaser_line(robot="1.0 nan 0.5"), "robot_y"),
    "robotlaser_max_range": (robotlaser_line().replace(" 30.0 ", " -1.0 "), "max_range"),
}


@pytest.mark.parametrize("suffix", ["", ".gz", ".bz2"])
@pytest.mark.parametrize("case", sorted(MALFORMED))
def test_malformed_line_names_file_line_field(tmp_path: Path, case: str, suffix: str) -> None:
    bad, field = MALFORMED[case]
    text = "".join(s + "\n" for s in ["# header", ODOM_LINE, bad, flaser_line()]).encode()
    p = tmp_path / f"bad.log{suffix}"
    p.write_bytes(gzip.compress(text) if suffix == ".gz" else bz2.compress(text) if suffix == ".bz2" else text)
    with pytest.raises(DataFormatError) as info:
        list(read_carmen(p))
    err = info.value
    msg = str(err)
    assert str(p) in msg and "line 3" in msg and f"field {field}" in msg, msg
    assert err.line == 3 and err.field is not None and err.field.startswith(field)


def test_skip_mode_counts(tmp_path: Path) -> None:
    lines = [ODOM_LINE, MALFORMED["fewer_beams"][0], flaser_line(), MALFORMED["nan_odom_theta"][0]]
    lines += [MALFORMED["odom_nan"][0]] * 6
    p = write_text(tmp_path / "s.log", lines)
    reader = CarmenReader(p, on_error="skip")
    recs = list(reader)
    assert len(recs) == 2
    s = reader.stats
    assert s.skipped_malformed == 8 and s.records == {"ODOM": 1, "FLASER": 1}
    assert [ln for ln, _ in s.malformed_examples] == [2, 4, 5, 6, 7]
    assert "n_beams" in s.malformed_examples[0][1]


@pytest.mark.parametrize("content", ["", "# only a comment\n\n", "NEFF 3\nFOO 1 2\n"])
def test_no_records_is_an_error(tmp_path: Path, content: str) -> None:
    p = tmp_path / "empty.log"
    p.write_text(content)
    with pytest.raises(DataFormatError, match="no records") as info:
        list(read_carmen(p))
    assert str(p) in str(info.value)


def test_all_malformed_in_skip_mode_is_an_error(tmp_path: Path) -> None:
    p = write_text(tmp_path / "bad.log", [MALFORMED["odom_nan"][0]])
    with pytest.raises(DataFormatError, match="no records.*1 malformed"):
        list(read_carmen(p, on_error="skip"))


def test_missing_file_and_bad_options(tmp_path: Path) -> None:
    with pytest.raises(FileNotFoundError):
        CarmenReader(tmp_path / "nope.log")
    p = write_text(tmp_path / "a.log", [ODOM_LINE])
    with pytest.raises(ValueError):
        CarmenReader(p, on_error="ignore")  # type: ignore[arg-type]


def test_truncated_gzip_stream(tmp_path: Path) -> None:
    data = gzip.compress(("\n".join([ODOM_LINE] * 2000) + "\n").encode())
    p = tmp_path / "cut.log.gz"
    p.write_bytes(data[: len(data) // 2])
    with pytest.raises(DataFormatError, match="compressed") as info:
        list(read_carmen(p))
    assert str(p) in str(info.value)


def test_compression_is_sniffed(tmp_path: Path) -> None:
    text = (ODOM_LINE + "\n" + flaser_line() + "\n").encode()
    (tmp_path / "misnamed.log").write_bytes(gzip.compress(text))
    (tmp_path / "plain.gz").write_bytes(text)
    for name in ("misnamed.log", "plain.gz"):
        assert [type(r) for r in read_carmen(tmp_path / name)] == [OdometryReading, LaserScan]


def test_reader_streams(tmp_path: Path) -> None:
    p = write_text(tmp_path / "big.log", [ODOM_LINE, flaser_line()] * 5000)
    reader = CarmenReader(p)
    it = iter(reader)
    assert isinstance(it, Iterator)
    first = next(it)
    assert isinstance(first, OdometryReading) and reader.lines_read == 1
    next(it)
    assert reader.lines_read == 2
    it.close()  # type: ignore[attr-defined]


# ----------------------------------------------------------------------------- fuzz

TOKENS = st.one_of(
    st.sampled_from(
        [
            "FLASER",
            "RLASER",
            "ODOM",
            "ROBOTLASER1",
            "RAWLASER2",
            "PARAM",
            "robot_frontlaser_offset",
            "robot_rearlaser_offset",
            "NEFF",
            "#",
            "nohost",
            "nan",
            "-inf",
            "1e999",
            "0",
            "1",
            "2",
            "3",
            "180",
            "-1",
            "9" * 30,
            "",
            "1_0",
            "٣",
            "0x10",
        ]
    ),
    st.integers(-5, 400).map(str),
    st.floats(allow_nan=True, allow_infinity=True).map(repr),
    st.text(max_size=8),
)
LINES = st.lists(TOKENS, max_size=30).map(" ".join)


def _consume(path: Path, on_error: str) -> None:
    try:
        for _ in read_carmen(path, on_error=on_error, include_raw=True):  # type: ignore[arg-type]
            pass
    except DataFormatError:
        pass


@settings(max_examples=300, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(lines=st.lists(st.one_of(LINES, st.text(max_size=60)), max_size=12), on_error=st.sampled_from(["raise", "skip"]))
def test_fuzz_only_dataformaterror(lines: list[str], on_error: str) -> None:
    with tempfile.TemporaryDirectory() as d:
        p = Path(d) / "fuzz.log"
        p.write_text("\n".join(lines), encoding="utf-8")
        _consume(p, on_error)


@settings(max_examples=200, deadline=None)
@given(
    data=st.data(),
    base=st.sampled_from([flaser_line(), ODOM_LINE, robotlaser_line(), "RAWLASER1 0 -1.5 3.0 0.5 20.0 0.01 0 2 1 2 0 5 h 0"]),
)
def test_fuzz_mutated_valid_lines(data: st.DataObject, base: str) -> None:
    tokens = base.split()
    for _ in range(data.draw(st.integers(1, 4))):
        i = data.draw(st.integers(0, len(tokens)))
        op = data.draw(st.sampled_from(["delete", "replace", "insert"]))
        if op == "delete" and i < len(tokens):
            del tokens[i]
        elif op == "replace" and i < len(tokens):
            tokens[i] = data.draw(TOKENS)
        else:
            tokens.insert(i, data.draw(TOKENS))
    with tempfile.TemporaryDirectory() as d:
        p = Path(d) / "fuzz.log"
        p.write_text(" ".join(tokens) + "\n", encoding="utf-8")
        _consume(p, data.draw(st.sampled_from(["raise", "skip"])))


# ----------------------------------------------------------------------------- writer

COORD = st.floats(-1e4, 1e4, allow_nan=False)
ANGLE = st.floats(-math.pi, math.pi)
STAMP = st.floats(0.0, 2e9)
HOST = st.text(string.ascii_letters + string.digits + "_-", min_size=1, max_size=12)


@st.composite
def scans(draw: st.DrawFn) -> LaserScan:
    n = draw(st.integers(1, 400))
    if draw(st.booleans()):
        amin, inc = flaser_geometry(n)
        max_range = 81.0
        offset = vec(draw(st.floats(-1.0, 1.0)), 0.0, 0.0)
        same_odom = False
    else:
        amin, inc = draw(ANGLE), draw(st.floats(1e-4, 0.05))
        max_range = draw(st.floats(1.0, 100.0))
        offset = vec(draw(st.floats(-1.0, 1.0)), draw(st.floats(-1.0, 1.0)), draw(ANGLE))
        same_odom = True
    ranges = draw(arrays(np.float64, n, elements=st.floats(0.01, max_range)))
    pose = vec(draw(COORD), draw(COORD), draw(ANGLE))
    odom = pose if same_odom else vec(draw(COORD), draw(COORD), draw(ANGLE))
    return LaserScan(
        ranges=ranges,
        angle_min=amin,
        angle_increment=inc,
        max_range=max_range,
        pose=pose,
        odom=odom,
        laser_offset=offset,
        timestamp=draw(STAMP),
        host=draw(HOST),
        logger_timestamp=draw(STAMP),
    )


@st.composite
def odoms(draw: st.DrawFn) -> OdometryReading:
    speed = st.floats(-10.0, 10.0)
    return OdometryReading(
        pose=vec(draw(COORD), draw(COORD), draw(ANGLE)),
        tv=draw(speed),
        rv=draw(speed),
        accel=draw(speed),
        timestamp=draw(STAMP),
        host=draw(HOST),
        logger_timestamp=draw(STAMP),
    )


def angle_diff(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    return np.abs(wrap_angle(np.asarray(a) - np.asarray(b)))


def assert_same_record(a: LaserScan | OdometryReading, b: LaserScan | OdometryReading) -> None:
    assert type(a) is type(b)
    np.testing.assert_allclose(a.pose[:2], b.pose[:2], atol=5.1e-5)
    assert angle_diff(a.pose[2], b.pose[2]) <= 5.1e-7
    assert abs(a.timestamp - b.timestamp) <= 1e-6 and a.host == b.host
    assert abs(a.logger_timestamp - b.logger_timestamp) <= 1e-6
    if isinstance(a, OdometryReading):
        assert isinstance(b, OdometryReading)
        assert abs(a.tv - b.tv) <= 5.1e-5 and abs(a.accel - b.accel) <= 5.1e-5
        assert abs(a.rv - b.rv) <= 5.1e-7
        return
    assert isinstance(b, LaserScan)
    np.testing.assert_allclose(a.odom[:2], b.odom[:2], atol=5.1e-5)
    assert angle_diff(a.odom[2], b.odom[2]) <= 5.1e-7
    assert a.n_beams == b.n_beams
    np.testing.assert_allclose(a.ranges, b.ranges, atol=5.1e-5)
    np.testing.assert_allclose(a.angles, b.angles, atol=1e-6)
    assert abs(a.max_range - b.max_range) <= 5.1e-5
    np.testing.assert_allclose(a.laser_offset[:2], b.laser_offset[:2], atol=3e-4)
    assert angle_diff(a.laser_offset[2], b.laser_offset[2]) <= 2e-6


@settings(max_examples=60, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(
    records=st.lists(st.one_of(scans(), odoms()), min_size=1, max_size=6), suffix=st.sampled_from([".log", ".log.gz", ".clf.bz2"])
)
def test_write_read_round_trip(records: list[LaserScan | OdometryReading], suffix: str) -> None:
    with tempfile.TemporaryDirectory() as d:
        p1, p2 = Path(d) / f"a{suffix}", Path(d) / f"b{suffix}"
        assert write_carmen(p1, records, header="round trip\ntest") == len(records)
        write_carmen(p2, records, header="round trip\ntest")
        assert p1.read_bytes() == p2.read_bytes()
        back = list(read_carmen(p1))
    assert len(back) == len(records)
    for a, b in zip(records, back):
        assert_same_record(a, b)


def test_lidar_270_uses_robotlaser1(tmp_path: Path) -> None:
    n = 1079
    inc = math.radians(270.0) / (n - 1)
    scan = LaserScan(
        ranges=np.linspace(0.1, 30.0, n),
        angle_min=-math.radians(135.0),
        angle_increment=inc,
        max_range=30.0,
        pose=vec(1, 2, 0.3),
        odom=vec(1, 2, 0.3),
        laser_offset=vec(0.1, 0.0, 0.0),
        timestamp=12.5,
    )
    p = tmp_path / "sim.log"
    write_carmen(p, [scan])
    assert p.read_text().startswith("ROBOTLASER1 ")
    (back,) = read_scans(p)
    assert back.kind == "ROBOTLASER1" and back.max_range == 30.0 and back.n_beams == n
    assert np.max(np.abs(back.angles - scan.angles)) < 1e-6
    assert back.angles[-1] == pytest.approx(math.radians(135.0), abs=1e-6)


def test_flaser_offset_becomes_param(tmp_path: Path) -> None:
    amin, inc = flaser_geometry(180)
    mk = [
        LaserScan(
            ranges=np.full(180, 2.0),
            angle_min=amin,
            angle_increment=inc,
            max_range=81.0,
            pose=vec(0, 0, 0),
            odom=vec(0, 0, 0),
            laser_offset=vec(off, 0, 0),
        )
        for off in (0.0, 0.25, 0.25, 0.0)
    ]
    p = tmp_path / "o.log"
    write_carmen(p, mk)
    kinds = [line.split()[0] for line in p.read_text().splitlines()]
    assert kinds == ["FLASER", "PARAM", "FLASER", "FLASER", "PARAM", "FLASER"]
    offsets = [s.laser_offset[0] for s in read_scans(p)]
    assert offsets == [0.0, 0.25, 0.25, 0.0]


def test_writer_robotlaser_odometry_policy(tmp_path: Path) -> None:
    scan = LaserScan(
        ranges=np.ones(10),
        angle_min=-1.0,
        angle_increment=0.1,
        max_range=20.0,
        pose=vec(1.0, 0.0, 0.0),
        odom=vec(2.0, 0.0, 0.0),
        laser_offset=vec(0.3, 0.0, 0.0),
    )
    with pytest.raises(DataFormatError, match="odom") as info:
        write_carmen(tmp_path / "x.log", [scan])
    assert info.value.field == "odom" and str(tmp_path / "x.log") in str(info.value)
    write_carmen(tmp_path / "y.log", [scan], robotlaser_pose="odom")
    (back,) = read_scans(tmp_path / "y.log")
    np.testing.assert_allclose(back.pose, [2.0, 0.0, 0.0])
    np.testing.assert_allclose(compose(back.pose, back.laser_offset), [2.3, 0.0, 0.0], atol=1e-9)


def test_writer_normalises_no_returns_and_rejects_bad_records(tmp_path: Path) -> None:
    amin, inc = flaser_geometry(4)
    scan = LaserScan(
        ranges=vec(1.0, np.nan, -2.0, np.inf),
        angle_min=amin,
        angle_increment=inc,
        max_range=81.0,
        pose=vec(0, 0, 0),
        odom=vec(0, 0, 0),
    )
    write_carmen(tmp_path / "n.log", [scan])
    (back,) = read_scans(tmp_path / "n.log")
    np.testing.assert_array_equal(back.ranges, [1.0, 81.0, 81.0, 81.0])
    bad_pose = LaserScan(ranges=vec(1.0), angle_min=0, angle_increment=0, max_range=5, pose=vec(np.nan, 0, 0), odom=vec(0, 0, 0))
    bad_host = OdometryReading(pose=vec(0, 0, 0), host="two words")
    for rec, field in ((bad_pose, "pose"), (bad_host, "host")):
        with pytest.raises(DataFormatError) as info:
            write_carmen(tmp_path / "bad.log", [rec])
        assert info.value.field == field
    with CarmenWriter(tmp_path / "p.log") as w:
        w.write_param("robot_frontlaser_offset", 0.5)
        w.write_odom(OdometryReading(pose=vec(0, 0, 0)))
        with pytest.raises(DataFormatError):
            w.write_param("has space", 1)
    reader = CarmenReader(tmp_path / "p.log")
    list(reader)
    assert reader.stats.params == {"robot_frontlaser_offset": "0.5000"}


def test_load_log(tmp_path: Path) -> None:
    p = write_text(tmp_path / "l.log", [ODOM_LINE, flaser_line(), ODOM_LINE, flaser_line()])
    log = load_log(p)
    assert len(log.scans) == 2 and len(log.odometry) == 2 and log.stats.n_records == 4
    np.testing.assert_array_equal(log.scan_timestamps, [100.5, 100.5])
    assert log.odometry_poses.shape == (2, 3)


# ----------------------------------------------------------------------------- datasets


def test_data_root_env(monkeypatch: pytest.MonkeyPatch, tmp_path: Path) -> None:
    monkeypatch.setenv("CRLAM_DATA", str(tmp_path))
    assert data_root() == tmp_path
    with pytest.raises(DatasetNotFoundError, match="intel"):
        dataset_path("intel")
    monkeypatch.setenv("CRLAM_DATA", str(tmp_path / "missing"))
    assert data_root() is None
    with pytest.raises(DatasetNotFoundError, match="CRLAM_DATA"):
        dataset_path("intel")


def test_an_empty_crlam_data_means_no_data_folder(monkeypatch: pytest.MonkeyPatch, tmp_path: Path) -> None:
    """``CRLAM_DATA=`` switches the lookup off, ``../shared/data`` beside the checkout included."""
    import crlam.io.datasets as datasets

    (tmp_path / "repo").mkdir()
    (tmp_path / "shared" / "data").mkdir(parents=True)
    monkeypatch.setattr(datasets, "_repo_root", lambda: tmp_path / "repo")
    monkeypatch.delenv("CRLAM_DATA", raising=False)
    assert data_root() == tmp_path / "shared" / "data"  # unset: the folder beside the checkout
    monkeypatch.setenv("CRLAM_DATA", "")
    assert data_root() is None
    with pytest.raises(DatasetNotFoundError, match="CRLAM_DATA=''"):
        dataset_path("cave-map")


@pytest.mark.realdata
def test_registry_files_exist() -> None:
    real("intel")
    for name, ds in DATASETS.items():
        assert dataset_path(name) == dataset_path(ds.relative_path)
        assert dataset_path(name).is_file()


# ----------------------------------------------------------------------------- real data


@pytest.fixture(scope="module")
def intel() -> tuple[list[LaserScan], CarmenReader]:
    reader = CarmenReader(real(DATASETS["intel"].relative_path))
    scans = [r for r in reader if isinstance(r, LaserScan)]
    return scans, reader


@pytest.mark.realdata
def test_intel_counts_and_order(intel: tuple[list[LaserScan], CarmenReader]) -> None:
    scans, reader = intel
    assert reader.stats.records == {"FLASER": 13631, "ODOM": 26915}
    assert reader.stats.skipped_malformed == 0 and reader.stats.unknown_kinds == {}
    assert {s.n_beams for s in scans} == {180}
    assert all(s.angle_increment == scans[0].angle_increment for s in scans)
    stamps = np.array([s.timestamp for s in scans])
    assert int(np.sum(np.diff(stamps) < 0)) == 631
    assert np.all(np.diff([s.line for s in scans]) > 0)


@pytest.mark.realdata
def test_intel_streams_first_scan_quickly() -> None:
    """The first scan comes after the first few lines of the 27 MB log (counted, not timed)."""
    path = real(DATASETS["intel"].relative_path)
    reader = CarmenReader(path)
    gen = iter(reader)
    first = next(r for r in gen if isinstance(r, LaserScan))
    assert reader.lines_read < 50 and first.n_beams == 180
    gen.close()  # type: ignore[attr-defined]


@pytest.mark.realdata
def test_aces_counts() -> None:
    reader = CarmenReader(real(DATASETS["aces"].relative_path), flaser_max_range=50.0)
    for _ in reader:
        pass
    assert reader.stats.records == {"FLASER": 7374, "ODOM": 7375}
    assert reader.stats.n_no_return_ranges == 11139


@pytest.mark.realdata
def test_robotlaser1_sample() -> None:
    reader = CarmenReader(real(DATASETS["robotlaser1-sample"].relative_path))
    scans = list(reader)
    assert reader.stats.records == {"ROBOTLASER1": 50}
    assert all(isinstance(s, LaserScan) for s in scans)
    laser = [s for s in scans if isinstance(s, LaserScan)]
    assert {s.n_beams for s in laser} == {180, 181}
    assert {round(s.angle_min, 6) for s in laser} >= {-1.570796, -1.566433}
    assert all(s.max_range == 81.9 and s.angle_increment == 0.017453 for s in laser)
    np.testing.assert_allclose([s.laser_offset[0] for s in laser], 0.22, atol=2e-3)


@pytest.mark.realdata
@pytest.mark.parametrize(
    ("name", "n_flaser", "n_beams", "offset"),
    [
        ("intel-corrected", 910, 180, 0.0),
        ("aces-corrected", 440, 180, 0.0),
        ("freiburg-101-corrected", 292, 360, -0.04),
        ("edmonton-corrected", 340, 180, 0.0),
    ],
)
def test_corrected_logs(name: str, n_flaser: int, n_beams: int, offset: float) -> None:
    ds = DATASETS[name]
    log = load_log(real(ds.relative_path), flaser_max_range=ds.flaser_max_range or 81.0)
    assert len(log.scans) == n_flaser and log.stats.ignored["NEFF"] == n_flaser
    assert {s.n_beams for s in log.scans} == {n_beams}
    assert {s.laser_offset[0] for s in log.scans} == {offset}
    assert log.stats.skipped_malformed == 0 and len(log.odometry) > 0
