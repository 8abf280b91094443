"""Nothing a robot's files hold crashes crlam (issue 49): the damaged-bag corpus of
``tests/damaged_bags`` through the reader and the commands, inputs that are not regular files,
bags that point outside their folder, the message rules of :mod:`crlam.io.message_checks`,
deeply nested YAML and TOML, ``--continue`` on unfinished runs, a Dask sweep that cannot start,
and localize's trajectory order."""

from __future__ import annotations

import json
import math
import os
import shutil
import socket
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from bag_messages import write_mutated
from crlam.cli import main
from crlam.errors import ConfigError, CrlamError, DataFormatError
from crlam.io import LaserScan, OdometryReading, RosbagReader, open_log
from crlam.io.message_checks import QUATERNION_TOLERANCE
from test_io_rosbag import BagSpec, odom_pose, write_bag

CORPUS = Path(__file__).parent / "damaged_bags"
EXPECTED: dict[str, dict[str, str]] = json.loads((CORPUS / "corpus.json").read_text())


def _run(argv: list[str], capsys: pytest.CaptureFixture[str]) -> tuple[int, str]:
    try:
        status = main(argv)
    except SystemExit as e:
        status = int(e.code or 0)
    return status, capsys.readouterr().err


def _one_error_line(err: str, command: str) -> str:
    assert "Traceback" not in err, err
    lines = [line for line in err.splitlines() if line.startswith(f"crlam {command}: error: ")]
    assert len(lines) == 1, err
    return lines[0]


# -- the corpus -------------------------------------------------------------------------------


def test_the_corpus_is_small_and_listed() -> None:
    files = [p for p in CORPUS.rglob("*") if p.is_file()]
    assert sum(p.stat().st_size for p in files) < 500_000
    on_disk = {p.name for p in CORPUS.iterdir()} - {"make_corpus.py", "corpus.json", "__pycache__"}
    assert on_disk == set(EXPECTED)


@pytest.mark.parametrize("name", sorted(EXPECTED))
def test_every_damaged_bag_gives_a_named_error_or_a_counted_skip(name: str, tmp_path: Path) -> None:
    # A copy: the escape cases must find nothing of /etc through the copy either.
    src = CORPUS / name
    bag = tmp_path / name
    shutil.copytree(src, bag) if src.is_dir() else shutil.copy(src, bag)
    want = EXPECTED[name]
    reader = RosbagReader(bag) if want["expect"] == "skip" else None
    if want["expect"] == "error":
        with pytest.raises(CrlamError) as info:
            list(open_log(bag))
        text = str(info.value)
        assert name in text  # the message names the bag
        assert want["match"] in text
        assert "\n" not in text
    else:
        assert reader is not None
        records = list(reader)
        assert any(isinstance(r, LaserScan) for r in records)
        assert sum(getattr(reader.stats, c) for c in want["match"].split(",")) > 0
        stamps = [r.timestamp for r in records if isinstance(r, LaserScan)]
        assert stamps == sorted(stamps) and len(set(stamps)) == len(stamps)


@pytest.mark.parametrize("command", ["map", "slam", "convert", "localize"])
@pytest.mark.parametrize(
    "name",
    [
        "truncated.mcap",
        "garbage.bag",
        "zstd-corrupt",
        "compression-lie",
        "metadata-nested",
        "metadata-escape",
        "metadata-ros1-serialisation",
        "scan-range-max-nan.mcap",
        "odom-quaternion-doubled.mcap",
    ],
)
def test_commands_give_one_error_line_and_status_2(
    name: str, command: str, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    bag = str(CORPUS / name)
    out = str(tmp_path / "out")
    argv = {
        "map": ["map", bag, "--out", out, "--quiet"],
        "slam": ["slam", bag, "--out", out, "--quiet"],
        "convert": ["convert", bag, str(tmp_path / "out.clf")],
        "localize": ["localize", bag, "--map", str(_room_map(tmp_path)), "--out", out, "--quiet"],
    }[command]
    status, err = _run(argv, capsys)
    assert status == 2
    line = _one_error_line(err, command)
    assert name in line
    assert not Path(out).exists()


def _room_map(tmp_path: Path) -> Path:
    """A small Nav2 map (a 4 m room) for localize."""
    from crlam.io.nav2 import write_nav2_map

    grid = np.zeros((40, 40), dtype=np.uint8)
    grid[[0, -1], :] = grid[:, [0, -1]] = 1
    probs = np.where(grid == 1, 1.0, 0.0)
    return write_nav2_map(tmp_path / "room.pgm", probs, resolution=0.1, origin=(-2.0, -2.0, 0.0))


# -- what is not a regular file -----------------------------------------------------------------


def test_a_fifo_is_refused_at_once(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    fifo = tmp_path / "x.bag"
    os.mkfifo(fifo)
    with pytest.raises(DataFormatError, match="FIFO"):
        RosbagReader(fifo)  # os.stat does not open it: no writer needed, no hang
    status, err = _run(["slam", str(fifo), "--out", str(tmp_path / "o"), "--quiet"], capsys)
    assert status == 2 and "FIFO" in _one_error_line(err, "slam")


def test_a_device_and_a_socket_are_refused(tmp_path: Path) -> None:
    if Path("/dev/zero").exists():
        (tmp_path / "zero.bag").symlink_to("/dev/zero")
        with pytest.raises(DataFormatError, match="device"):
            list(open_log(tmp_path / "zero.bag"))
    sock_path = tmp_path / "s.mcap"
    with socket.socket(socket.AF_UNIX) as s:
        s.bind(str(sock_path))
        with pytest.raises(DataFormatError, match="socket"):
            RosbagReader(sock_path)


def test_a_bag_file_that_links_out_of_its_folder_is_refused(tmp_path: Path) -> None:
    bag = write_bag(tmp_path / "bag", BagSpec(n_scans=3), "mcap")
    (data,) = bag.glob("*.mcap")
    outside = tmp_path / "elsewhere.mcap"
    shutil.move(str(data), outside)
    data.symlink_to(outside)
    with pytest.raises(DataFormatError, match="outside the bag's folder"):
        list(open_log(bag))
    data.unlink()
    data.symlink_to(bag / "metadata.yaml")  # a link inside the folder is fine (but not a bag file)
    with pytest.raises(DataFormatError, match=str(bag)):
        list(open_log(bag))


# -- message rules ------------------------------------------------------------------------------


def _odometry(path: Path) -> list[OdometryReading]:
    return [r for r in open_log(path) if isinstance(r, OdometryReading)]


def _scale_odom_quaternions(scale: float) -> Any:
    def edit(topic: str, msg: Any) -> Any:
        if topic == "/odom":
            q = msg.pose.pose.orientation
            q.x, q.y, q.z, q.w = q.x * scale, q.y * scale, q.z * scale, q.w * scale
        return msg

    return edit


def test_headings_do_not_depend_on_the_quaternions_length_within_the_tolerance(tmp_path: Path) -> None:
    spec = BagSpec(n_scans=5)
    unit = _odometry(write_mutated(tmp_path / "unit.mcap", spec))
    for scale in (1 - 0.9 * QUATERNION_TOLERANCE, 1 + 0.9 * QUATERNION_TOLERANCE, 1.0 + 1e-7):
        scaled = _odometry(write_mutated(tmp_path / f"s{scale}.mcap", spec, _scale_odom_quaternions(scale)))
        np.testing.assert_allclose([r.pose for r in scaled], [r.pose for r in unit], atol=1e-12)
    np.testing.assert_allclose([r.pose[2] for r in unit], [odom_pose(r.timestamp)[2] for r in unit], atol=1e-9)
    for scale in (0.5, 2.0, 0.0, math.nan):
        with pytest.raises(DataFormatError, match=r"/odom message 1: .*quaternion"):
            _odometry(write_mutated(tmp_path / f"bad{scale}.mcap", spec, _scale_odom_quaternions(scale)))


def test_a_nan_mount_is_refused(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    bag = write_mutated(tmp_path / "b.mcap", BagSpec(n_scans=3), until=100.8)
    with pytest.raises(ConfigError, match="finite"):
        RosbagReader(bag, laser_mount=(0.1, math.nan, 0.0))
    status, err = _run(["map", str(bag), "--laser-mount", "0", "nan", "0", "--out", str(tmp_path / "o"), "--quiet"], capsys)
    assert status == 2 and "finite" in _one_error_line(err, "map")


def test_a_zero_quaternion_in_tf_static_is_refused(tmp_path: Path) -> None:
    spec = BagSpec(n_scans=3, static=[("base_link", "laser", (0.1, 0.0, 0.0), (0.0, 0.0, 0.5))])

    def zero(topic: str, msg: Any) -> Any:
        if topic == "/tf_static":
            r = msg.transforms[0].transform.rotation
            r.x = r.y = r.z = r.w = 0.0
        return msg

    with pytest.raises(DataFormatError, match=r"\(field transform to laser: rotation\): /tf_static message 1: quaternion"):
        list(open_log(write_mutated(tmp_path / "z.mcap", spec, zero)))


@pytest.mark.parametrize(
    ("field", "value"),
    [
        ("range_max", math.nan),
        ("range_max", -1.0),
        ("range_max", math.inf),
        ("range_min", math.nan),
        ("range_min", 20.0),
        ("angle_min", math.inf),
        ("angle_max", math.nan),
        ("angle_increment", math.nan),
        ("angle_increment", 0.0),
        ("angle_increment", 3.0),
        ("time_increment", math.nan),
        ("scan_time", -math.inf),
    ],
)
def test_scan_header_geometry_is_checked(field: str, value: float, tmp_path: Path) -> None:
    def edit(topic: str, msg: Any) -> Any:
        if topic == "/scan" and msg.header.stamp.nanosec == 510_000_000:  # the third scan
            setattr(msg, field, value)
        return msg

    bag = write_mutated(tmp_path / "b.mcap", BagSpec(n_scans=5), edit)
    with pytest.raises(DataFormatError, match=rf"\(field {field}\): /scan message 3: "):
        list(open_log(bag))
    # The same rule for a bag read without odometry.
    with pytest.raises(DataFormatError, match=rf"\(field {field}\): /scan message 3: "):
        list(open_log(bag, odometry=False))


@pytest.fixture
def default_limits() -> Any:
    """The default limits before and after the test (``--max-readings`` sets them for the process)."""
    from dataclasses import fields

    from crlam.limits import DEFAULTS, Limits, set_limits

    set_limits(**{f.name: getattr(DEFAULTS, f.name) for f in fields(Limits)})
    yield
    set_limits(**{f.name: getattr(DEFAULTS, f.name) for f in fields(Limits)})


def test_beam_counts_are_checked_before_allocating(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], default_limits: None
) -> None:
    bag = write_mutated(tmp_path / "wide.mcap", BagSpec(n_scans=2, n_beams=5000, angle_increment=1e-4), until=100.5)
    status, err = _run(["map", str(bag), "--out", str(tmp_path / "o"), "--quiet", "--max-readings", "4000"], capsys)
    assert status == 2
    line = _one_error_line(err, "map")
    assert "5,000 beams" in line and "--max-readings" in line
    # 100,000 beams: more than any 2D laser has (localize weighed every beam for every particle).
    from dataclasses import fields

    from crlam.limits import DEFAULTS, Limits, set_limits

    set_limits(**{f.name: getattr(DEFAULTS, f.name) for f in fields(Limits)})
    wide = write_mutated(tmp_path / "w.mcap", BagSpec(n_scans=1, n_beams=100_000, angle_increment=6e-5), until=100.2)
    for command in ("localize", "map"):
        argv = [command, str(wide), "--out", str(tmp_path / f"o-{command}"), "--quiet"]
        if command == "localize":
            argv += ["--map", str(_room_map(tmp_path))]
        status, err = _run(argv, capsys)
        assert status == 2
        assert "100,000 beams, more than any laser has" in _one_error_line(err, command)


def test_scans_stamped_backwards_or_repeated_are_skipped_and_counted(tmp_path: Path) -> None:
    stamps = {0.31: 0.31, 0.51: 0.21, 0.71: 0.31, 0.91: 0.91}  # the third goes back, the fourth repeats the second

    def edit(topic: str, msg: Any) -> Any:
        if topic == "/scan":
            frac = round(msg.header.stamp.sec - 100 + msg.header.stamp.nanosec * 1e-9 - 0.0, 2)
            new = stamps.get(round(frac - 0.0, 2))
            if new is not None:
                msg.header.stamp.nanosec = int(round(new * 1e9))
        return msg

    for odometry in (True, False):
        reader = open_log(write_mutated(tmp_path / f"b{odometry}.mcap", BagSpec(n_scans=6), edit), odometry=odometry)
        scans = [r for r in reader if isinstance(r, LaserScan)]
        assert isinstance(reader, RosbagReader)
        assert (reader.stats.skipped_stamp_backwards, reader.stats.skipped_stamp_repeated) == (1, 1)
        assert [round(s.timestamp, 2) for s in scans] == [100.11, 100.31, 100.91, 101.11]


def test_repeated_odometry_stamps_are_skipped_and_counted(tmp_path: Path) -> None:
    def edit(topic: str, msg: Any) -> Any:
        if topic == "/odom" and msg.header.stamp.nanosec == 100_000_000:  # 100.10 and 101.10 repeat 100.05, 101.05
            msg.header.stamp.nanosec = 50_000_000
        return msg

    reader = open_log(write_mutated(tmp_path / "o.mcap", BagSpec(n_scans=3), edit))
    odom = [r.timestamp for r in reader if isinstance(r, OdometryReading)]
    assert isinstance(reader, RosbagReader) and reader.stats.skipped_odom_repeated == 2
    assert len(odom) == 39 and len(set(odom)) == 39


# -- YAML and TOML nesting ----------------------------------------------------------------------


def test_deeply_nested_yaml_and_toml_give_a_clean_error(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    log = tmp_path / "a.log"
    ranges = " ".join(["3.0"] * 180)
    log.write_text("".join(f"FLASER 180 {ranges} {0.1 * i} 0 0 {0.1 * i} 0 0 {i}.0 host {i}.0\n" for i in range(3)))
    nested_yaml = tmp_path / "map.yaml"
    nested_yaml.write_text("image: m.pgm\nresolution: " + "[" * 20000 + "]" * 20000 + "\n")
    ladder = tmp_path / "ladder.yaml"
    ladder.write_text("".join(" " * i + f"k{i}:\n" for i in range(3000)))
    nested_toml = tmp_path / "c.toml"
    nested_toml.write_text("x = " + "[" * 20000 + "]" * 20000 + "\n")
    deep_toml = tmp_path / "d.toml"
    deep_toml.write_text("x = " + "[" * 100 + "]" * 100 + "\n")  # parses, but deeper than any crlam file
    cases = [
        (["localize", str(log), "--map", str(nested_yaml), "--out", str(tmp_path / "o1"), "--quiet"], "map.yaml"),
        (["localize", str(log), "--map", str(ladder), "--out", str(tmp_path / "o2"), "--quiet"], "ladder.yaml"),
        (["slam", str(log), "--config", str(nested_toml), "--out", str(tmp_path / "o3"), "--quiet"], "c.toml"),
        (["slam", str(log), "--config", str(deep_toml), "--out", str(tmp_path / "o4"), "--quiet"], "d.toml"),
    ]
    for argv, name in cases:
        status, err = _run(argv, capsys)
        assert status == 2, err
        line = _one_error_line(err, argv[0])
        assert name in line and "nested" in line


# -- --continue, Dask, localize's trajectory ---------------------------------------------------


def test_continue_takes_only_a_complete_run_folder(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    log = tmp_path / "a.log"
    ranges = " ".join(["3.0"] * 180)
    log.write_text("".join(f"FLASER 180 {ranges} {0.05 * i} 0 0 {0.05 * i} 0 0 {i}.0 host {i}.0\n" for i in range(4)))
    run = tmp_path / "run"
    status, err = _run(["slam", str(log), "--out", str(run), "--quiet", "--particles", "5"], capsys)
    assert status == 0, err
    for broken in ("incomplete", "unmarked"):
        copy = tmp_path / broken
        shutil.copytree(run, copy)
        (copy / "COMPLETE").unlink()
        if broken == "incomplete":
            (copy / "INCOMPLETE").write_text("{}")
        argv = ["slam", str(log), "--continue", str(copy), "--out", str(tmp_path / f"c-{broken}"), "--quiet"]
        status, err = _run(argv, capsys)
        assert status == 2
        assert ("INCOMPLETE" if broken == "incomplete" else "COMPLETE") in _one_error_line(err, "slam")
        if broken == "incomplete":  # nor its belief.npz named alone
            argv[3] = str(copy / "belief.npz")
            status, err = _run(argv, capsys)
            assert status == 2 and "INCOMPLETE" in _one_error_line(err, "slam")
    argv = ["slam", str(log), "--continue", str(run), "--out", str(tmp_path / "c-ok"), "--quiet", "--particles", "5"]
    status, err = _run(argv, capsys)
    assert status == 0, err


def test_a_dask_sweep_that_cannot_start_leaves_nothing(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    pytest.importorskip("distributed", reason="Dask is optional (pip install 'crlam[cluster]')")
    from crlam.errors import ConfigError
    from crlam.experiments.dask_executor import DaskExecutor

    out = tmp_path / "sweep"
    argv = ["experiment", "table1", "--executor", "dask", "--scheduler", "no address", "--out", str(out), "--quiet"]
    status, err = _run(argv, capsys)
    assert status == 2
    assert "not a Dask address" in _one_error_line(err, "experiment")
    assert not out.exists()
    # No scheduler at a well-formed address: refused after the connection attempt (the command
    # makes this check before it makes its folder; here with a short timeout).
    with pytest.raises(ConfigError, match="cannot reach the Dask scheduler"):
        DaskExecutor("tcp://127.0.0.1:1").check_scheduler(timeout=1.0)


def test_localize_writes_its_trajectory_sorted(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    from crlam.io.tum import read_tum

    room = _room_map(tmp_path)
    # A CARMEN log whose scans are not in time order (file order 0, 2, 1, 3, ...).
    ranges = " ".join(["1.5"] * 180)
    order = [0, 2, 1, 3, 5, 4, 6, 7]
    log = tmp_path / "a.log"
    log.write_text("".join(f"FLASER 180 {ranges} 0 0 0 0 0 0 {i}.0 host {i}.0\n" for i in order))
    out = tmp_path / "loc"
    argv = ["localize", str(log), "--map", str(room), "--initial-pose", "0", "0", "0", "--out", str(out), "--quiet"]
    status, err = _run(argv + ["--kld-max-particles", "200"], capsys)
    assert status == 0, err
    stamps = read_tum(out / "trajectory.tum").timestamps
    assert list(stamps) == sorted(stamps) and len(stamps) == len(order)
