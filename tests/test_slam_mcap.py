"""``crlam slam --mcap``: run.mcap read back with rosbags (topics, types, counts, the map against map.yaml)."""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any

import numpy as np
import pytest
import yaml
from rosbags.highlevel import AnyReader
from rosbags.typesys import Stores, get_typestore

from crlam.cli import main
from crlam.io import LaserScan, open_log
from crlam.io.nav2 import read_pgm
from crlam.io.tum import read_tum
from crlam.pose import compose


@pytest.fixture(scope="module")
def sim_log(tmp_path_factory: pytest.TempPathFactory) -> Path:
    out = tmp_path_factory.mktemp("sim")
    assert main(["simulate", "--scans", "30", "--world", "office", "--out", str(out), "--quiet"]) == 0
    return out / "log.clf"


def _messages(path: Path) -> tuple[dict[str, str], dict[str, list[tuple[int, Any]]]]:
    types: dict[str, str] = {}
    msgs: dict[str, list[tuple[int, Any]]] = {}
    with AnyReader([path], default_typestore=get_typestore(Stores.ROS2_HUMBLE)) as reader:
        for c in reader.connections:
            types[c.topic] = c.msgtype
        for conn, t, raw in reader.messages():
            msgs.setdefault(conn.topic, []).append((t, reader.deserialize(raw, conn.msgtype)))
    return types, msgs


def _pose(p: Any) -> np.ndarray:
    q = p.orientation
    yaw = math.atan2(2.0 * (q.w * q.z + q.x * q.y), 1.0 - 2.0 * (q.y * q.y + q.z * q.z))
    return np.array([p.position.x, p.position.y, yaw])


def _stamp(h: Any) -> float:
    return h.stamp.sec + h.stamp.nanosec * 1e-9


def _check_grid(grid: Any, run: Path) -> None:
    meta = yaml.safe_load((run / "map.yaml").read_text())
    image = read_pgm(run / "map.pgm")
    assert grid.header.frame_id == "map"
    assert (grid.info.height, grid.info.width) == image.shape
    assert grid.info.resolution == pytest.approx(meta["resolution"], rel=1e-6)  # float32 in the message
    origin = _pose(grid.info.origin)
    np.testing.assert_allclose(origin, meta["origin"], atol=1e-12)
    data = np.asarray(grid.data).reshape(grid.info.height, grid.info.width)
    assert data.min() >= -1 and data.max() <= 100
    # The PGM (trinary) is the same map thresholded: its first row is the largest y; unknown
    # cells are unknown (205) there, occupied (0) and free (254) pixels above / below the thresholds.
    pixels = image[::-1]
    assert np.all(pixels[data == -1] == 205)
    assert (data == -1).sum() > 0 and (data >= 0).sum() > 0


def _check_occupancy(grid: Any, run: Path) -> None:
    data = np.asarray(grid.data).reshape(grid.info.height, grid.info.width)
    pixels = read_pgm(run / "map.pgm")[::-1]
    assert np.all(data[pixels == 0] >= 65) and np.all((data[pixels == 254] >= 0) & (data[pixels == 254] <= 20))
    assert (pixels == 0).sum() > 0 and (pixels == 254).sum() > 0


@pytest.mark.parametrize("method", ["clam", "ogm"])
def test_slam_mcap_reads_back(sim_log: Path, tmp_path: Path, method: str) -> None:
    run = tmp_path / "run"
    argv = ["slam", str(sim_log), "--out", str(run), "--particles", "3", "--max-scans", "30", "--quiet", "--mcap"]
    assert main([*argv, "--method", method]) == 0
    path = run / "run.mcap"
    assert path.is_file()
    assert [p.name for p in run.iterdir() if p.name.startswith(".")] == []  # no temporary folder left
    types, msgs = _messages(path)
    expected = {
        "/scan": "sensor_msgs/msg/LaserScan",
        "/tf": "tf2_msgs/msg/TFMessage",
        "/tf_static": "tf2_msgs/msg/TFMessage",
        "/particles": "geometry_msgs/msg/PoseArray",
        "/path": "nav_msgs/msg/Path",
        "/map": "nav_msgs/msg/OccupancyGrid",
    }
    if method == "clam":
        expected["/map_confidence"] = "nav_msgs/msg/OccupancyGrid"
    assert types == expected
    steps = np.loadtxt(run / "steps.csv", delimiter=",", skiprows=1, ndmin=2)
    n_processed = len(steps)
    counts = {t: len(m) for t, m in msgs.items()}
    assert counts == {t: 1 for t in expected} | {"/scan": 30, "/tf": 30, "/particles": n_processed}
    times = [t for m in msgs.values() for t, _ in m]
    assert max(times) == msgs["/map"][0][0]  # the map comes at the last scan

    scans = [r for r in open_log(sim_log) if isinstance(r, LaserScan)]
    for rec, (_, msg) in zip(scans, msgs["/scan"]):
        assert _stamp(msg.header) == pytest.approx(rec.timestamp, abs=1e-9)
        assert len(msg.ranges) == rec.n_beams and msg.header.frame_id == "laser"

    # /path is trajectory.tum; map -> odom -> base_link is the estimate at every processed scan.
    tum = read_tum(run / "trajectory.tum")
    path_msg = msgs["/path"][0][1]
    assert path_msg.header.frame_id == "map" and len(path_msg.poses) == 30
    got = np.array([_pose(p.pose) for p in path_msg.poses])
    np.testing.assert_allclose(got, tum.poses, atol=1e-6)
    estimates = steps[:, 5:8]
    k = 0
    for _, tf in msgs["/tf"]:
        frames = {(t.header.frame_id, t.child_frame_id): t.transform for t in tf.transforms}
        assert ("odom", "base_link") in frames
        if ("map", "odom") in frames:

            def planar(tr: Any) -> np.ndarray:
                q = tr.rotation
                return np.array([tr.translation.x, tr.translation.y, 2.0 * math.atan2(q.z, q.w)])

            est = compose(planar(frames[("map", "odom")]), planar(frames[("odom", "base_link")]))
            np.testing.assert_allclose(est[:2], estimates[k, :2], atol=2e-6)
            assert math.remainder(est[2] - estimates[k, 2], 2 * math.pi) == pytest.approx(0.0, abs=2e-6)
            k += 1
    assert k == n_processed
    for _, pa in msgs["/particles"]:
        assert pa.header.frame_id == "map" and len(pa.poses) == 3
    static = msgs["/tf_static"][0][1].transforms[0]
    assert (static.header.frame_id, static.child_frame_id) == ("base_link", "laser")

    _check_grid(msgs["/map"][0][1], run)
    _check_occupancy(msgs["/map"][0][1], run)
    if method == "clam":
        conf = msgs["/map_confidence"][0][1]
        _check_grid(conf, run)
        m = np.asarray(msgs["/map"][0][1].data)
        assert np.array_equal(np.asarray(conf.data) == -1, m == -1)


def test_slam_without_mcap_writes_none(sim_log: Path, tmp_path: Path) -> None:
    run = tmp_path / "run"
    assert main(["slam", str(sim_log), "--out", str(run), "--particles", "3", "--max-scans", "5", "--quiet"]) == 0
    assert not (run / "run.mcap").exists()


def test_slam_mcap_reads_back_with_the_mcap_packages(sim_log: Path, tmp_path: Path) -> None:
    """The reader Foxglove's own Python tools use (``mcap`` + ``mcap-ros2-support``) decodes
    every message, with the same content as rosbags reads."""
    mcap_reader = pytest.importorskip("mcap.reader")
    mcap_ros2_reader = pytest.importorskip("mcap_ros2.reader")
    run = tmp_path / "run"
    argv = ["slam", str(sim_log), "--out", str(run), "--particles", "3", "--max-scans", "30", "--quiet", "--mcap"]
    assert main(argv) == 0
    path = run / "run.mcap"
    with open(path, "rb") as fh:
        reader = mcap_reader.make_reader(fh)
        assert reader.get_header().profile == "ros2"
        summary = reader.get_summary()
        assert summary is not None and summary.statistics is not None
        n_total = summary.statistics.message_count
    decoded: dict[str, list[Any]] = {}
    for m in mcap_ros2_reader.read_ros2_messages(str(path)):
        assert m.channel.message_encoding == "cdr" and m.schema.encoding == "ros2msg"
        decoded.setdefault(m.channel.topic, []).append((m.schema.name, m.ros_msg))
    assert sum(len(v) for v in decoded.values()) == n_total
    types, msgs = _messages(path)
    assert {t: v[0][0] for t, v in decoded.items()} == types
    assert {t: len(v) for t, v in decoded.items()} == {t: len(v) for t, v in msgs.items()}
    grid, ref = decoded["/map"][0][1], msgs["/map"][0][1]
    assert (grid.info.width, grid.info.height) == (ref.info.width, ref.info.height)
    np.testing.assert_array_equal(np.asarray(grid.data), np.asarray(ref.data))
    path_msg = decoded["/path"][0][1]
    np.testing.assert_allclose(
        [_pose(p.pose) for p in path_msg.poses], [_pose(p.pose) for p in msgs["/path"][0][1].poses], atol=1e-12
    )
    scans = decoded["/scan"]
    assert len(scans) == 30
    np.testing.assert_array_equal(np.asarray(scans[0][1].ranges), np.asarray(msgs["/scan"][0][1].ranges))
