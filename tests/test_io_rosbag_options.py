"""Bag reader options beyond detection: the laser mount published on /tf, the echo of a
multi-echo scan, reading without odometry, and ``crlam slam --config`` repeating a run's
``[input]`` options (bags written with the helpers of ``test_io_rosbag``)."""

from __future__ import annotations

import math
import sys
from pathlib import Path

import numpy as np
import pytest

from crlam.cli import main
from crlam.errors import ConfigError
from crlam.io import RosbagReader, open_log
from crlam.pose import compose
from test_io_rosbag import MULTI, BagSpec, odom_pose, scans_of, write_bag

if sys.version_info >= (3, 11):
    import tomllib
else:  # pragma: no cover
    import tomli as tomllib


@pytest.mark.parametrize("kind", ["sqlite3", "ros1"])
def test_a_fixed_mount_on_tf_is_used(tmp_path: Path, kind: str) -> None:
    # base_link -> laser only on /tf (with the odometry there too), none on /tf_static.
    mount = ("base_link", "laser", (0.25, -0.1, 0.3), (0.0, 0.0, 0.4))
    bag = write_bag(tmp_path / "bag", BagSpec(odom_topic=None, odom_in_tf=True, tf_fixed=[mount], n_scans=4), kind)
    scans, reader = scans_of(bag)
    st = reader.stats
    assert st.mount_source == "tf" and st.base_frame == "base_link"
    np.testing.assert_allclose(st.laser_offset, (0.25, -0.1, 0.4), atol=1e-9)
    for s in scans:
        np.testing.assert_allclose(s.odom, odom_pose(s.timestamp), atol=2e-3)
        np.testing.assert_allclose(s.pose, compose(s.odom, np.array([0.25, -0.1, 0.4])), atol=1e-9)
    # /tf_static wins where it has the mount.
    static = [("base_link", "laser", (0.1, 0.0, 0.0), (0.0, 0.0, 0.0))]
    bag = write_bag(tmp_path / "both", BagSpec(static=static, tf_fixed=[mount], n_scans=2), kind)
    _, reader = scans_of(bag)
    assert reader.stats.mount_source == "tf_static"
    np.testing.assert_allclose(reader.stats.laser_offset, (0.1, 0.0, 0.0), atol=1e-9)


def test_a_moving_tf_transform_is_not_a_mount(tmp_path: Path) -> None:
    spec = BagSpec(tf_fixed=[("base_link", "laser", (0.25, 0.0, 0.0), (0.0, 0.0, 0.0))], tf_fixed_drift=True, n_scans=2)
    _, reader = scans_of(write_bag(tmp_path / "bag", spec))
    assert reader.stats.mount_source.startswith("none")
    # a chain: base_link -> plate fixed on /tf_static, plate -> laser fixed on /tf
    spec = BagSpec(
        static=[("base_link", "plate", (0.1, 0.0, 0.2), (0.0, 0.0, 0.0))],
        tf_fixed=[("plate", "laser", (0.05, 0.02, 0.0), (math.pi, 0.0, 0.0))],
        n_scans=2,
    )
    _, reader = scans_of(write_bag(tmp_path / "chain", spec))
    st = reader.stats
    assert st.mount_source == "tf" and st.upside_down
    np.testing.assert_allclose(st.laser_offset[:2], (0.15, 0.02), atol=1e-9)


@pytest.mark.parametrize(
    ("echo", "intensities", "offset"),
    [("first", (0.0, 0.0), 0.0), ("last", (0.0, 0.0), 1.0), ("strongest", (3.0, 1.0), 0.0), ("strongest", (0.5, 2.0), 1.0)],
)
def test_echo_choice(tmp_path: Path, echo: str, intensities: tuple, offset: float) -> None:
    # Each beam has the echoes (r, r + 1).
    bag = write_bag(tmp_path / "bag", BagSpec(scan_type=MULTI, n_scans=2, echo_intensities=intensities), "mcap")
    scans, reader = scans_of(bag, echo=echo)
    np.testing.assert_allclose(scans[0].ranges, np.linspace(1.0, 3.0, 9) + offset, rtol=1e-6)
    assert reader.stats.describe()["echo"] == echo


def test_echo_choice_is_checked(tmp_path: Path) -> None:
    with pytest.raises(ConfigError, match="echo"):
        RosbagReader(write_bag(tmp_path / "bag", BagSpec(n_scans=1)), echo="loudest")


def test_reading_without_odometry(tmp_path: Path) -> None:
    bag = write_bag(tmp_path / "bag", BagSpec(static=[("base_footprint", "laser", (0.2, 0.0, 0.1), (0.0, 0.0, 0.0))]))
    reader = open_log(bag, odometry=False)
    records = list(reader)
    assert len(records) == 10 and all(np.all(np.isnan(r.odom)) for r in records)
    st = reader.stats
    assert st.odom_topic == "" and st.base_frame == "base_footprint" and st.mount_source == "tf_static"
    assert isinstance(reader, RosbagReader) and reader.has_odometry()
    assert not RosbagReader(write_bag(tmp_path / "none", BagSpec(odom_topic=None))).has_odometry()
    assert RosbagReader(write_bag(tmp_path / "tf", BagSpec(odom_topic=None, odom_in_tf=True))).has_odometry()


def test_slam_config_repeats_the_input_options(tmp_path: Path) -> None:
    # Two laser topics (detection alone fails), multi-echo scans, the mount given by the user.
    spec = BagSpec(scan_topics=("/front", "/rear"), scan_type=MULTI, echo_intensities=(0.0, 1.0))
    bag = write_bag(tmp_path / "bag", spec, "mcap")
    first = tmp_path / "first"
    argv = ["slam", str(bag), "--out", str(first), "--particles", "3", "--quiet", "--scan-topic", "/rear"]
    argv += ["--echo", "strongest", "--laser-mount", "0.1", "0.0", "0.2", "--upside-down", "--odom-frame", "odom"]
    assert main(argv) == 0
    assert main(["slam", str(bag), "--out", str(tmp_path / "plain"), "--particles", "3", "--quiet"]) == 2  # several laser topics
    again = tmp_path / "again"
    assert main(["slam", str(bag), "--out", str(again), "--config", str(first / "config.toml"), "--quiet"]) == 0
    a = tomllib.loads((first / "config.toml").read_text())
    b = tomllib.loads((again / "config.toml").read_text())
    assert a["input"] == b["input"]
    assert b["input"]["scan_topic"] == "/rear" and b["input"]["echo"] == "strongest"
    assert b["input"]["mount_source"] == "user" and b["input"]["upside_down"] is True
    assert (first / "trajectory.tum").read_text() == (again / "trajectory.tum").read_text()
    # A flag given beside --config overrides the file's.
    other = tmp_path / "other"
    assert (
        main(["slam", str(bag), "--out", str(other), "--config", str(first / "config.toml"), "--scan-topic", "/front", "--quiet"])
        == 0
    )
    c = tomllib.loads((other / "config.toml").read_text())["input"]
    assert c["scan_topic"] == "/front" and c["echo"] == "strongest" and c["mount_source"] == "user"
