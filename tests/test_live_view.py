"""``--foxglove``: a Foxglove WebSocket client on 127.0.0.1 receives the map of an offline
``crlam slam`` run and of a live ``crlam ros slam`` node, and the decoded grid is the run's map.

Every wait here is on an event (a line the command prints, a message received, a process that
ends); the timeouts only turn a hang into a failure.
"""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path
from typing import Any

import numpy as np
import pytest

pytest.importorskip("foxglove", reason="crlam[live] (foxglove-sdk) is not installed")
pytest.importorskip("websockets", reason="the websockets package (the test's Foxglove client) is not installed")

from crlam.cli import main  # noqa: E402
from crlam.errors import ConfigError  # noqa: E402
from crlam.io.run_folder import is_complete  # noqa: E402
from foxglove_client import FoxgloveClient  # noqa: E402

TIMEOUT = 120.0


def _read_until(proc: subprocess.Popen[str], prefix: str) -> str:
    """The first line of ``proc``'s output that starts with ``prefix`` (the lines before are skipped)."""
    assert proc.stdout is not None
    for line in proc.stdout:
        if line.startswith(prefix):
            return line
    raise AssertionError(f"the command ended (exit {proc.wait()}) without printing {prefix!r}")


def _port_of(line: str) -> int:
    return int(line.rsplit("(port ", 1)[1].split(")")[0])


def _mcap_map(path: Path) -> Any:
    from rosbags.highlevel import AnyReader
    from rosbags.typesys import Stores, get_typestore

    with AnyReader([path], default_typestore=get_typestore(Stores.ROS2_HUMBLE)) as reader:
        maps = [reader.deserialize(raw, c.msgtype) for c, _, raw in reader.messages() if c.topic == "/map"]
    assert len(maps) == 1
    return maps[0]


def test_view_binds_to_loopback_and_port_zero_picks_a_free_port() -> None:
    from crlam.live_view import LiveView, ros_type_name

    view = LiveView(port=0)
    try:
        assert view.host == "127.0.0.1" and view.port > 0 and view.url == f"ws://127.0.0.1:{view.port}"
        # The port is taken: a second server on it is a clear error.
        with pytest.raises(ConfigError, match="cannot serve"):
            LiveView(port=view.port)
    finally:
        view.close()
    assert ros_type_name("nav_msgs::msg::dds_::OccupancyGrid_") == "nav_msgs/msg/OccupancyGrid"


def test_offline_slam_serves_its_map_on_foxglove(tmp_path: Path) -> None:
    assert main(["simulate", "--scans", "30", "--world", "office", "--out", str(tmp_path / "sim"), "--quiet"]) == 0
    out = tmp_path / "run"
    cmd = [sys.executable, "-m", "crlam", "slam", str(tmp_path / "sim" / "log.clf"), "-o", str(out), "--quiet", "--mcap"]
    cmd += ["--particles", "8", "--seed", "3", "--foxglove", "0", "--foxglove-wait"]
    env = dict(os.environ, PYTHONPATH=os.pathsep.join(sys.path))
    proc = subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True, env=env)
    try:
        port = _port_of(_read_until(proc, "foxglove: serving on ws://127.0.0.1:"))
        client = FoxgloveClient(port, timeout=TIMEOUT)
        topics = ["/map_confidence", "/scan", "/particles", "/pose", "/path", "/tf", "/tf_static", "/map"]
        client.subscribe(topics)
        got: dict[str, list[tuple[int, Any]]] = {t: [] for t in topics}
        final = None
        while final is None:
            topic, log_time, msg = client.receive()
            got[topic].append((log_time, msg))
            # The final map comes once the run folder is in place; earlier maps come while it runs.
            if topic == "/map" and is_complete(out):
                expected = _mcap_map(out / "run.mcap")
                if (msg.header.stamp.sec, msg.header.stamp.nanosec) == (expected.header.stamp.sec, expected.header.stamp.nanosec):
                    final = msg
        client.close()
        assert proc.wait(TIMEOUT) == 0  # --foxglove-wait: it ends once the client has left
    finally:
        proc.kill()
    assert final.info.width == expected.info.width and final.info.height == expected.info.height
    assert final.info.resolution == pytest.approx(expected.info.resolution)
    assert final.info.origin.position.x == pytest.approx(expected.info.origin.position.x)
    np.testing.assert_array_equal(final.data, expected.data)
    assert (final.data >= 0).any() and (final.data == -1).any()  # a map with known and unknown cells
    assert len(got["/scan"]) == 30 and len(got["/tf"]) == 30 and len(got["/tf_static"]) >= 1
    assert len(got["/particles"]) >= 1 and len(got["/particles"][-1][1].poses) == 8
    assert len(got["/pose"]) == len(got["/particles"])
    assert len(got["/map_confidence"]) >= 1 and len(got["/path"][-1][1].poses) == 30


def test_missing_foxglove_sdk_is_a_clear_error(monkeypatch: pytest.MonkeyPatch) -> None:
    from crlam.live_view import need_foxglove

    monkeypatch.setitem(sys.modules, "foxglove", None)  # import foxglove now raises ImportError
    with pytest.raises(ConfigError, match=r"crlam\[live\]"):
        need_foxglove()


def test_live_slam_node_serves_its_map_on_foxglove(tmp_path: Path) -> None:
    """``crlam ros slam --foxglove 0``: the node's outputs on the WebSocket are its DDS outputs
    (the same CDR bytes); the last /map decodes to the map the node published on DDS."""
    pytest.importorskip("cyclonedds", reason="crlam[ros] (cyclonedds) is not installed")
    from corridor_bag import corridor_bag
    from crlam.live_view import LiveView
    from crlam.ros import messages as m
    from crlam.ros import qos
    from crlam.ros.dds import DdsNode
    from crlam.ros.params import NodeParameters
    from crlam.ros.play import play_bag
    from crlam.ros.slam_node import SlamNode

    domain = 100 + (os.getpid() + 50) % 100  # not test_ros_nodes.py's domain
    bag = corridor_bag(tmp_path / "corridor.mcap")
    params = NodeParameters(max_scan_wait=float("inf"), odom_extrapolation=0.0, map_update_interval=1.0, process_every_scan=True)
    node = SlamNode(params, {"particles": 8, "seed": 3}, domain=domain)
    view = LiveView(port=0)
    node.live_view = view
    node.start()
    dds_maps: list[Any] = []
    rviz = DdsNode("crlam_test_rviz", domain=domain)
    rviz.reader("/map", m.OccupancyGrid, qos.latched(), dds_maps.append)
    client = FoxgloveClient(view.port, timeout=TIMEOUT)
    try:
        # Outputs, and the inputs the view mirrors (the scans the filter took, odom -> base_link, the mount).
        topics = ["/map", "/map_confidence", "/particles", "/pose", "/path", "/scan", "/tf", "/tf_static"]
        client.subscribe(topics)
        assert view.wait_for_subscriber(topics[-1], TIMEOUT)  # and so every topic before it
        play_bag(bag, rate=float("inf"), lockstep=True, domain=domain, timeout=TIMEOUT)
        node.request_save(str(tmp_path / "live"))  # the save publishes the final map
        node.wait_idle()
        final_stamp = node.run.stamps[-1]
        got: dict[str, list[Any]] = {t: [] for t in topics}
        while True:
            topic, _, msg = client.receive()
            got[topic].append(msg)
            if topic == "/map" and abs(msg.header.stamp.sec + msg.header.stamp.nanosec * 1e-9 - final_stamp) < 1e-6:
                break
    finally:
        client.close()
        node.stop(save=False)
        view.close()
    assert is_complete(tmp_path / "live")
    final = got["/map"][-1]
    dds = [g for g in dds_maps if abs(g.header.stamp.sec + g.header.stamp.nanosec * 1e-9 - final_stamp) < 1e-6][-1]
    assert (final.info.width, final.info.height) == (dds.info.width, dds.info.height)
    np.testing.assert_array_equal(final.data, np.asarray(dds.data, dtype=np.int8))
    assert (final.data >= 0).any() and final.header.frame_id == "map"
    assert len(got["/scan"]) == 40 and len(got["/particles"]) >= 1 and len(got["/tf_static"]) >= 1
    assert any(tr.header.frame_id == "map" and tr.child_frame_id == "odom" for s in got["/tf"] for tr in s.transforms)
    assert any(tr.header.frame_id == "odom" and tr.child_frame_id == "base_link" for s in got["/tf"] for tr in s.transforms)
    rviz.close()


def test_offline_localize_serves_the_known_map_particles_and_path(tmp_path: Path) -> None:
    from crlam.experiments.slam_mcap import occupancy_grid_values
    from crlam.io.tum import read_tum
    from crlam.localize.map import load_localization_map

    assert main(["simulate", "--scans", "30", "--world", "office", "--out", str(tmp_path / "sim"), "--quiet"]) == 0
    world = tmp_path / "sim" / "world.yaml"
    start = read_tum(tmp_path / "sim" / "groundtruth.tum").poses[0]
    out = tmp_path / "loc"
    cmd = [sys.executable, "-m", "crlam", "localize", str(tmp_path / "sim" / "log.clf"), "--map", str(world), "-o", str(out)]
    cmd += ["--quiet", "--time-offset", "off", "--initial-pose", *map(str, start), "--foxglove", "0", "--foxglove-wait"]
    cmd += ["--kld-min-particles", "20", "--kld-max-particles", "100", "--max-beams", "30"]
    env = dict(os.environ, PYTHONPATH=os.pathsep.join(sys.path))
    proc = subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True, env=env)
    try:
        port = _port_of(_read_until(proc, "foxglove: serving on ws://127.0.0.1:"))
        client = FoxgloveClient(port, timeout=TIMEOUT)
        client.subscribe(["/particles", "/path", "/scan", "/map"])
        got: dict[str, list[Any]] = {"/map": [], "/particles": [], "/path": [], "/scan": []}
        while not got["/path"]:  # /path comes once, when the run folder is in place
            topic, _, msg = client.receive()
            got[topic].append(msg)
        client.close()
        assert proc.wait(TIMEOUT) == 0
    finally:
        proc.kill()
    assert is_complete(out)
    layer = load_localization_map(str(world)).expected_occupancy()
    expected = occupancy_grid_values(layer.values, ~np.isfinite(layer.values))
    assert len(got["/map"]) == 1 and got["/map"][0].info.width == layer.values.shape[1]
    np.testing.assert_array_equal(got["/map"][0].data, expected)
    assert len(got["/scan"]) == 30 and len(got["/particles"]) >= 1
    traj = read_tum(out / "trajectory.tum")
    path = np.array([[p.pose.position.x, p.pose.position.y] for p in got["/path"][0].poses])
    np.testing.assert_allclose(path, traj.poses[:, :2], atol=1e-9)


def test_offline_explore_serves_map_goals_and_candidates(tmp_path: Path) -> None:
    import csv

    out = tmp_path / "explore"
    cmd = [sys.executable, "-m", "crlam", "explore", "--world", "office", "--budget", "6", "--candidates", "20", "--no-gif"]
    cmd += ["-o", str(out), "--quiet", "--foxglove", "0", "--foxglove-wait"]
    env = dict(os.environ, PYTHONPATH=os.pathsep.join(sys.path))
    proc = subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True, env=env)
    topics = ["/goal_pose", "/explore/candidates", "/scan", "/path", "/map"]
    got: dict[str, list[Any]] = {t: [] for t in topics}
    try:
        port = _port_of(_read_until(proc, "foxglove: serving on ws://127.0.0.1:"))
        client = FoxgloveClient(port, timeout=TIMEOUT)
        client.subscribe(topics)
        while True:  # the last decision's map comes once more when the run folder is in place
            topic, _, msg = client.receive()
            got[topic].append(msg)
            if topic == "/map" and is_complete(out):
                break
        client.close()
        assert proc.wait(TIMEOUT) == 0
    finally:
        proc.kill()
    with open(out / "progress.csv") as f:
        rows = list(csv.DictReader(f))
    assert len(got["/goal_pose"]) == len(rows) >= 1
    assert len(got["/explore/candidates"][-1].markers) == int(rows[-1]["candidates"]) + 1
    final = got["/map"][-1]
    # The map's observed cells (not -1) are the decision's explored area.
    explored = float(np.count_nonzero(final.data != -1)) * final.info.resolution**2
    assert explored == pytest.approx(float(rows[-1]["explored_m2"]), abs=1e-3)
    assert len(got["/scan"]) >= len(rows) and len(got["/path"][-1].poses) == len(got["/scan"])


def test_cli_without_foxglove_sdk_names_the_extra(tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: Any) -> None:
    assert main(["simulate", "--scans", "5", "--world", "office", "--out", str(tmp_path / "sim"), "--quiet"]) == 0
    monkeypatch.setitem(sys.modules, "foxglove", None)
    code = main(["slam", str(tmp_path / "sim" / "log.clf"), "-o", str(tmp_path / "run"), "--quiet", "--foxglove", "0"])
    assert code != 0
    assert "crlam[live]" in capsys.readouterr().err
    assert not (tmp_path / "run").exists()  # nothing was run nor written


def test_a_client_that_never_reads_does_not_hold_up_the_publisher() -> None:
    """A subscribed client that reads nothing: 1,000 messages of 100 kB (far beyond its queue
    and the socket's buffers) are all handed over without waiting for it (its oldest are dropped)."""
    from crlam.live_view import BACKLOG, LiveView

    view = LiveView(port=0)
    try:
        view.announce({"/map": "std_msgs/msg/String"})
        client = FoxgloveClient(view.port, timeout=TIMEOUT)
        client.subscribe(["/map"])
        assert view.wait_for_subscriber("/map", TIMEOUT)
        payload = b"\x00\x01\x00\x00" + (100_000).to_bytes(4, "little") + b"x" * 99_999 + b"\x00"
        for _ in range(1000):  # would block here if the publisher waited for the client
            view.publish_cdr("/map", "std_msgs/msg/String", payload)
        assert view.counts["/map"] == 1000 > BACKLOG
        client.close()
    finally:
        view.close()


def test_ros_slam_command_serves_foxglove(tmp_path: Path) -> None:
    """``crlam ros slam --foxglove 0`` as a process: a client gets the map the save publishes."""
    pytest.importorskip("cyclonedds", reason="crlam[ros] (cyclonedds) is not installed")
    import signal

    from corridor_bag import corridor_bag
    from crlam.ros import messages as m
    from crlam.ros import qos
    from crlam.ros.dds import DdsNode
    from crlam.ros.play import _wait_matched, play_bag

    domain = 100 + (os.getpid() + 25) % 100
    bag = corridor_bag(tmp_path / "corridor.mcap")
    params = tmp_path / "params.yaml"
    params.write_text(
        "crlam_slam:\n  ros__parameters:\n    particles: 8\n    max_scan_wait: .inf\n"
        "    odom_extrapolation: 0.0\n    process_every_scan: true\n"
    )
    cmd = [sys.executable, "-m", "crlam", "ros", "slam", "--params-file", str(params), "--domain", str(domain)]
    cmd += ["--foxglove", "0"]
    env = dict(os.environ, PYTHONPATH=os.pathsep.join(sys.path))
    proc = subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True, env=env)
    try:
        port = _port_of(_read_until(proc, "foxglove: serving on ws://127.0.0.1:"))
        client = FoxgloveClient(port, timeout=TIMEOUT)
        client.subscribe(["/map", "/scan"])
        play_bag(bag, rate=float("inf"), lockstep=True, domain=domain, timeout=TIMEOUT)
        save = DdsNode("crlam_test_save", domain=domain)
        w = save.writer("/crlam/save_map", m.String, qos.reliable())
        _wait_matched({"/crlam/save_map": w}, ["/crlam/save_map"], TIMEOUT)
        w.write(m.String(data=str(tmp_path / "saved")))
        while True:  # the save publishes the map at the last scan's stamp (4.96 s)
            topic, _, msg = client.receive()
            if topic == "/map" and abs(msg.header.stamp.sec + msg.header.stamp.nanosec * 1e-9 - 4.96) < 1e-6:
                break
        client.close()
        save.close()
        proc.send_signal(signal.SIGTERM)
        assert proc.wait(TIMEOUT) == 0
    finally:
        proc.kill()
    assert is_complete(tmp_path / "saved")
    assert (msg.data >= 0).any() and msg.info.width > 0
