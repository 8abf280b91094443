"""``crlam ros play`` into ``crlam ros slam`` over DDS, on the loopback interface only.

Every participant here uses :data:`crlam.ros.dds.LOOPBACK_CONFIG` (interface ``lo``, unicast
peers on 127.0.0.1, no multicast) on a domain of this process's own. The player runs in
lock-step with the node (it waits for the node's progress on /diagnostics before each scan and
the node waits for the odometry after each scan without a wall-clock limit), so the node sees
every scan with the offline reader's odometry whatever the machine's speed: its trajectory must
equal ``crlam slam``'s on the same bag to 1e-9 (same seed, same scans, same order).
"""

from __future__ import annotations

import os
import threading
from pathlib import Path
from typing import Any

import numpy as np
import pytest

pytest.importorskip("cyclonedds", reason="crlam[ros] (cyclonedds) is not installed")

from corridor_bag import corridor_bag as _synthetic_bag  # noqa: E402
from crlam.io.run_folder import is_complete  # noqa: E402
from crlam.io.tum import read_tum  # noqa: E402
from crlam.ros import messages as m  # noqa: E402
from crlam.ros import qos  # noqa: E402
from crlam.ros.dds import LOOPBACK_CONFIG, DdsNode  # noqa: E402
from crlam.ros.params import NodeParameters, load_params_file, split_parameters  # noqa: E402
from crlam.ros.play import play_bag  # noqa: E402
from crlam.ros.slam_node import SlamNode  # noqa: E402

#: One domain per test process (pid-based), so parallel runs on one machine do not meet.
DOMAIN = 100 + os.getpid() % 100
SLAM = {"particles": 8, "seed": 3}


class Collector:
    """A test subscriber: every sample of the topics it reads, and an event per topic."""

    def __init__(self, node: DdsNode) -> None:
        self.samples: dict[str, list[Any]] = {}
        self.events: dict[str, threading.Event] = {}
        self.node = node

    def read(self, topic: str, cls: type, profile: Any) -> None:
        self.samples[topic] = []
        self.events[topic] = threading.Event()

        def got(sample: Any) -> None:
            self.samples[topic].append(sample)
            self.events[topic].set()

        self.node.reader(topic, cls, profile, got)


def test_participants_are_loopback_only() -> None:
    assert '<NetworkInterface name="lo"/>' in LOOPBACK_CONFIG
    assert "<AllowMulticast>false</AllowMulticast>" in LOOPBACK_CONFIG
    assert '<Peer address="127.0.0.1"/>' in LOOPBACK_CONFIG
    node = DdsNode("crlam_test_config", domain=DOMAIN)
    try:
        assert os.environ["CYCLONEDDS_URI"] == LOOPBACK_CONFIG
    finally:
        node.close()


def test_params_file(tmp_path: Path) -> None:
    f = tmp_path / "p.yaml"
    f.write_text("crlam_slam:\n  ros__parameters:\n    max_laser_range: 6.0\n    particles: 12\n    map_frame: world\n")
    node, slam = split_parameters(load_params_file(f, "crlam_slam"), str(f))
    assert node.map_frame == "world" and slam == {"max_range": 6.0, "particles": 12}
    f.write_text("crlam_slam:\n  ros__parameters:\n    no_such_thing: 1\n")
    from crlam.errors import ConfigError

    with pytest.raises(ConfigError, match="no_such_thing"):
        split_parameters(load_params_file(f, "crlam_slam"), str(f))


def _run_live(bag: Path, out: Path, **node_changes: Any) -> tuple[SlamNode, Collector]:
    settings: dict[str, Any] = {"max_scan_wait": float("inf"), "odom_extrapolation": 0.0, "map_update_interval": 2.0}
    params = NodeParameters(**(settings | {"process_every_scan": True} | node_changes))
    node = SlamNode(params, dict(SLAM), domain=DOMAIN)
    node.start()
    test = DdsNode("crlam_test_subscriber", domain=DOMAIN)
    col = Collector(test)
    col.read("/map", m.OccupancyGrid, qos.latched())
    col.read("/tf", m.TFMessage, qos.reliable(100))
    col.read("/pose", m.PoseWithCovarianceStamped, qos.reliable())
    try:
        play_bag(bag, rate=float("inf"), lockstep=True, domain=DOMAIN, timeout=120)
        node.request_save(str(out))
        node.wait_idle()
    finally:
        node.stop(save=False)
    assert col.events["/map"].wait(30) and col.events["/tf"].wait(30)
    test.close()
    return node, col


def _run_offline(bag: Path, out: Path, **options: Any) -> Any:
    """``crlam slam``'s run of ``bag`` with the node's settings. The live node runs without the
    checks that read the whole log ahead (time offset, body mask, laser mount, the map's range
    from the readings, the odometry noise's fit), so the offline run does too."""
    from crlam.experiments.slam_run import run_slam_log
    from crlam.slam.presets import resolve

    without_look_ahead = {"time_offset": "off", "body_mask": "off", "map_range": "fixed", "motion_noise": "model"}
    config = resolve("robust", {**SLAM, **without_look_ahead})
    return run_slam_log(bag, out, config, progress=False, figures=False, laser_mount="data", **options)


@pytest.mark.realdata
def test_turtlebot4_live_equals_offline(data_dir: Path, tmp_path: Path) -> None:

    bag = data_dir / "bags" / "turtlebot4-mac-floor"
    if not bag.exists():
        pytest.skip(f"{bag} not found")
    node, col = _run_live(bag, tmp_path / "live")
    assert is_complete(tmp_path / "live")
    assert node.counters["scans_dropped"] == 0
    offline = _run_offline(bag, tmp_path / "offline")
    live_t = read_tum(tmp_path / "live" / "trajectory.tum")
    off_t = read_tum(tmp_path / "offline" / "trajectory.tum")
    assert offline.metrics["n_scans"] == len(live_t.timestamps)
    np.testing.assert_allclose(live_t.timestamps, off_t.timestamps, atol=1e-9)
    np.testing.assert_allclose(live_t.poses, off_t.poses, atol=1e-9)
    assert (tmp_path / "live" / "map.pgm").is_file() and (tmp_path / "live" / "map.yaml").is_file()
    grid = col.samples["/map"][-1]
    assert grid.header.frame_id == "map" and len(grid.data) == grid.info.width * grid.info.height > 0
    assert any(tr.header.frame_id == "map" and tr.child_frame_id == "odom" for s in col.samples["/tf"] for tr in s.transforms)
    assert len(col.samples["/pose"]) > 0


def test_synthetic_bag_live_equals_offline(tmp_path: Path) -> None:

    bag = _synthetic_bag(tmp_path / "corridor.mcap")
    node, col = _run_live(bag, tmp_path / "live")
    assert is_complete(tmp_path / "live")
    offline = _run_offline(bag, tmp_path / "offline")
    live_t = read_tum(tmp_path / "live" / "trajectory.tum")
    off_t = read_tum(tmp_path / "offline" / "trajectory.tum")
    assert len(live_t.timestamps) == offline.metrics["n_scans"] == 40
    np.testing.assert_allclose(live_t.poses, off_t.poses, atol=1e-9)
    assert node.counters["scans_processed"] >= 1


def test_extrapolated_odometry_stays_near_the_offline_run(tmp_path: Path) -> None:
    """With ``odom_extrapolation`` (the live default) each scan goes with the odometry moved on
    from the readings before it instead of waiting for the one after it: the trajectory is no
    longer the offline one to the bit, but stays within a few millimetres of it on a straight run.
    The bag's messages go to the node's handlers in bag order, one at a time, so that every scan
    arrives before the odometry reading after it (over DDS two topics' samples may overtake)."""
    from rosbags.highlevel import AnyReader
    from rosbags.typesys import Stores, get_typestore

    bag = _synthetic_bag(tmp_path / "corridor.mcap")
    params = NodeParameters(max_scan_wait=float("inf"), process_every_scan=True, laser_mount="0.1 0 0")
    assert params.odom_extrapolation > 0  # the default
    node = SlamNode(params, dict(SLAM), domain=DOMAIN)
    node.start()
    try:
        with AnyReader([bag], default_typestore=get_typestore(Stores.ROS2_HUMBLE)) as reader:
            for conn, _, raw in reader.messages([c for c in reader.connections if c.topic in ("/odom", "/scan")]):
                msg = reader.deserialize(raw, conn.msgtype)
                (node._on_odom if conn.topic == "/odom" else node._on_scan)(msg)
        node.request_save(str(tmp_path / "live"))
        node.wait_idle()
    finally:
        node.stop(save=False)
    assert node.counters["scans_extrapolated"] == 40  # each scan 0.01 s after the newest reading
    _run_offline(bag, tmp_path / "offline")
    live_t = read_tum(tmp_path / "live" / "trajectory.tum")
    off_t = read_tum(tmp_path / "offline" / "trajectory.tum")
    assert len(live_t.timestamps) == len(off_t.timestamps) == 40
    gap = np.hypot(*(live_t.poses[:, :2] - off_t.poses[:, :2]).T)
    assert float(np.max(gap)) < 0.01  # a straight run at constant speed: the extrapolation is near exact


def _start_node_process(tmp_path: Path, out: Path) -> Any:
    """``crlam ros slam`` as a child process on this test's domain; returns once it reports ready."""
    import subprocess
    import sys

    params = tmp_path / "params.yaml"
    params.write_text(
        "crlam_slam:\n  ros__parameters:\n    particles: 8\n    seed: 3\n    max_scan_wait: .inf\n"
        "    odom_extrapolation: 0.0\n    process_every_scan: true\n"
    )
    env = dict(os.environ, PYTHONPATH=os.pathsep.join(sys.path))
    proc = subprocess.Popen(
        [sys.executable, "-m", "crlam", "ros", "slam", "--params-file", str(params), "-o", str(out), "--domain", str(DOMAIN)],
        stdout=subprocess.PIPE,
        stderr=subprocess.STDOUT,
        text=True,
        env=env,
    )
    assert proc.stdout is not None
    line = proc.stdout.readline()  # "running on DDS domain ..." once its readers exist
    assert "running on DDS domain" in line, line
    return proc


def test_node_process_saves_whole_on_sigterm_and_nothing_when_killed(tmp_path: Path) -> None:
    import signal

    bag = _synthetic_bag(tmp_path / "corridor.mcap")
    # SIGTERM: the node saves its run folder whole, then exits.
    out = tmp_path / "run"
    proc = _start_node_process(tmp_path, out)
    try:
        play_bag(bag, rate=float("inf"), lockstep=True, domain=DOMAIN, timeout=120)
        proc.send_signal(signal.SIGTERM)
        assert proc.wait(120) == 0
    finally:
        proc.kill()
    assert is_complete(out)
    assert len(read_tum(out / "trajectory.tum").timestamps) == 40
    # SIGKILL mid-run: no run folder, or a whole one; never a partial one.
    out2 = tmp_path / "killed"
    proc = _start_node_process(tmp_path, out2)
    try:
        play_bag(bag, rate=float("inf"), lockstep=True, domain=DOMAIN, timeout=120)
        save = DdsNode("crlam_test_save", domain=DOMAIN)
        w = save.writer("/crlam/save_map", m.String, qos.reliable())
        from crlam.ros.play import _wait_matched

        _wait_matched({"/crlam/save_map": w}, ["/crlam/save_map"], 60)
        w.write(m.String(data=""))
        proc.kill()
        proc.wait(60)
        save.close()
    finally:
        proc.kill()
    assert not out2.exists() or is_complete(out2)
    from crlam.io.run_folder import INCOMPLETE, staging_path

    stage = staging_path(out2)
    assert not stage.exists() or (stage / INCOMPLETE).is_file()  # a staging folder says it is incomplete


@pytest.mark.realdata
@pytest.mark.slow
def test_turtlebot4_localize_live_equals_offline_and_converges(data_dir: Path, tmp_path: Path) -> None:
    """``crlam ros localize`` on the bag's floor map, started by an /initialpose as RViz sends
    it: the same trajectory as ``crlam localize`` with that initial pose, and it converges."""
    from crlam.cli import main
    from crlam.ros.localize_node import LocalizeNode

    bag = data_dir / "bags" / "turtlebot4-mac-floor"
    if not bag.exists():
        pytest.skip(f"{bag} not found")
    floor = bag / "mac_1st_floor_final.yaml"
    pose, cov = (6.54, -8.86, 1.705), (0.25, 0.25, 0.03)
    args = ["localize", str(bag), "--map", str(floor), "--out", str(tmp_path / "offline"), "--quiet"]
    args += ["--initial-pose", *map(str, pose), "--initial-cov", *map(str, cov)]
    args += ["--nav2-free-thresh", "0.196", "--skip-no-returns", "--max-beams", "90", "--time-offset", "off"]
    assert main(args) == 0

    params = NodeParameters(max_scan_wait=float("inf"), odom_extrapolation=0.0, process_every_scan=True)
    node = LocalizeNode(
        params, {"skip_no_returns": True, "max_beams": 90}, str(floor), map_options={"nav2_free_thresh": 0.196}, domain=DOMAIN
    )
    node.start()
    rviz = DdsNode("crlam_test_rviz", domain=DOMAIN)
    col = Collector(rviz)
    col.read("/map", m.OccupancyGrid, qos.latched())
    try:
        w = rviz.writer("/initialpose", m.PoseWithCovarianceStamped, qos.reliable())
        from crlam.ros.play import _wait_matched
        from crlam.ros.slam_node import pose_msg

        _wait_matched({"/initialpose": w}, ["/initialpose"], 60)
        c = [0.0] * 36
        c[0], c[7], c[35] = cov
        w.write(
            m.PoseWithCovarianceStamped(
                header=m.Header(frame_id="map"), pose=m.PoseWithCovariance(pose=pose_msg(np.array(pose)), covariance=c)
            )
        )
        with node.wake:
            while node.counters.get("initial_poses", 0) < 1:
                node.wake.wait()
        play_bag(bag, rate=float("inf"), lockstep=True, domain=DOMAIN, timeout=120)
        node.request_save(str(tmp_path / "live"))
        node.wait_idle()
    finally:
        node.stop(save=False)
    assert col.events["/map"].wait(30)
    rviz.close()
    assert is_complete(tmp_path / "live")
    live = read_tum(tmp_path / "live" / "trajectory.tum")
    offline = read_tum(tmp_path / "offline" / "trajectory.tum")
    np.testing.assert_allclose(live.timestamps, offline.timestamps, atol=1e-9)
    np.testing.assert_allclose(live.poses, offline.poses, atol=1e-9)
    assert node.localizer.convergence is not None


@pytest.mark.parametrize("function", ["crmi", "ucrmi"])
def test_explore_node_publishes_a_reachable_goal_and_scored_candidates(tmp_path: Path, function: str) -> None:
    """On the synthetic corridor, ``crlam ros explore`` publishes a goal inside the mapped free
    space, ahead in the corridor's unexplored part, and one marker per candidate (plus DELETEALL)."""
    from crlam.ros.explore_node import ExploreNode

    bag = _synthetic_bag(tmp_path / "corridor.mcap")
    params = NodeParameters(max_scan_wait=float("inf"), odom_extrapolation=0.0, process_every_scan=True, map_update_interval=1.0)
    settings = {"function": function, "sensor_range": 8.0, "n_candidates": 40, "robot_radius": 0.2, "particles": 8}
    node = ExploreNode(params, dict(SLAM), settings, domain=DOMAIN)
    node.start()
    test = DdsNode("crlam_test_nav2", domain=DOMAIN)
    col = Collector(test)
    col.read("/goal_pose", m.PoseStamped, qos.reliable())
    col.read("/explore/candidates", m.MarkerArray, qos.reliable())
    try:
        from crlam.ros.play import _wait_matched

        _wait_matched(
            {"/goal_pose": node.w_goal, "/explore/candidates": node.w_candidates}, ["/goal_pose", "/explore/candidates"], 60
        )
        play_bag(bag, rate=float("inf"), lockstep=True, domain=DOMAIN, timeout=120)
        node.wait_idle()
    finally:
        node.stop(save=False)
    assert col.events["/goal_pose"].wait(30) and col.events["/explore/candidates"].wait(30)
    test.close()
    d = node.decisions[-1]
    assert d.best >= 0 and len(d.candidates) > 1
    goal = col.samples["/goal_pose"][-1]
    assert goal.header.frame_id == "map"
    gx, gy = goal.pose.position.x, goal.pose.position.y
    assert abs(gy) < 1.5 and -0.5 < gx < 4.0  # inside the corridor's walls
    assert (gx, gy) == pytest.approx(tuple(d.candidates[d.best]))
    markers = col.samples["/explore/candidates"][-1].markers
    assert markers[0].action == 3 and len(markers) == len(d.candidates) + 1


def _synthetic_tf_multi_echo_bag(path: Path) -> Path:
    """The corridor of :func:`_synthetic_bag` with odometry on /tf (odom -> base_link) and the
    laser as a MultiEchoLaserScan (two echoes per beam, the first the wall)."""
    from crlam.io.rosbag_writer import TF_MESSAGE, McapBagWriter

    echo_type = "sensor_msgs/msg/MultiEchoLaserScan"
    angles = np.linspace(-np.pi / 2, np.pi / 2, 181)
    with McapBagWriter(path) as w:
        T = w.types
        w.write("/tf_static", TF_MESSAGE, 0, w.tf([w.transform(0.0, "base_link", "laser", (0.1, 0.0, 0.0))]), latched=True)
        for k in range(80):
            t = 1.0 + 0.05 * k
            x = 0.0125 * k
            w.write("/tf", TF_MESSAGE, int(t * 1e9), w.tf([w.transform(t, "odom", "base_link", (x, 0.0, 0.0))]))
            if k % 2 == 1:
                ts = t + 0.01
                with np.errstate(divide="ignore"):
                    side = np.where(np.abs(np.sin(angles)) > 1e-9, 1.5 / np.abs(np.sin(angles)), np.inf)
                    front = np.where(np.cos(angles) > 1e-9, (4.0 - x - 0.1) / np.cos(angles), np.inf)
                ranges = np.minimum(np.minimum(side, front), 7.5).astype(np.float32)
                echo = T["sensor_msgs/msg/LaserEcho"]
                msg = T[echo_type](
                    header=w.header(ts, "laser"),
                    angle_min=float(angles[0]),
                    angle_max=float(angles[-1]),
                    angle_increment=float(angles[1] - angles[0]),
                    time_increment=0.0,
                    scan_time=0.1,
                    range_min=0.05,
                    range_max=8.0,
                    ranges=[echo(echoes=np.array([r, r + 0.5], dtype=np.float32)) for r in ranges],
                    intensities=[echo(echoes=np.array([1.0, 2.0], dtype=np.float32)) for _ in ranges],
                )
                w.write("/scan", echo_type, int(ts * 1e9), msg)
    return path


def test_tf_odometry_and_multi_echo_scans_live_equal_offline(tmp_path: Path) -> None:

    bag = _synthetic_tf_multi_echo_bag(tmp_path / "corridor-tf.mcap")
    node, _ = _run_live(bag, tmp_path / "live", odom_topic="/tf", scan_type="MultiEchoLaserScan")
    assert is_complete(tmp_path / "live")
    offline = _run_offline(bag, tmp_path / "offline", bag_options={"odom_topic": "/tf"})
    live_t = read_tum(tmp_path / "live" / "trajectory.tum")
    off_t = read_tum(tmp_path / "offline" / "trajectory.tum")
    assert len(live_t.timestamps) == offline.metrics["n_scans"] == 40
    np.testing.assert_allclose(live_t.poses, off_t.poses, atol=1e-9)


def test_save_map_service_over_dds_request_reply(tmp_path: Path) -> None:
    """``/crlam_slam/save_map`` (slam_toolbox/srv/SaveMap as rmw_cyclonedds carries it): before
    any scan the reply says no map yet and nothing is written; after the bag, the reply says
    success and the folder is a whole run folder with the Nav2 map. Each reply carries its
    request's client id and sequence number."""
    from crlam.ros.services import (
        RESULT_NO_MAP_RECEIVED,
        RESULT_SUCCESS,
        SaveMapRequest,
        SaveMapResponse,
        service_topics,
    )

    bag = _synthetic_bag(tmp_path / "corridor.mcap")
    params = NodeParameters(max_scan_wait=float("inf"), odom_extrapolation=0.0, process_every_scan=True)
    node = SlamNode(params, dict(SLAM), domain=DOMAIN)
    node.start()
    client = DdsNode("crlam_test_service_client", domain=DOMAIN)
    replies: list[Any] = []
    got = threading.Condition()

    def on_reply(sample: Any) -> None:
        with got:
            replies.append(sample)
            got.notify_all()

    request_topic, reply_topic = service_topics("/crlam_slam/save_map")
    assert (request_topic, reply_topic) == ("rq/crlam_slam/save_mapRequest", "rr/crlam_slam/save_mapReply")
    client.reader(reply_topic, SaveMapResponse, qos.reliable(), on_reply, raw=True)
    w = client.writer(request_topic, SaveMapRequest, qos.reliable(), raw=True)

    def call(seq: int, folder: str) -> Any:
        w.write(SaveMapRequest(client_guid=0xC0FFEE, sequence_number=seq, name=m.String(data=folder)))
        with got:
            assert got.wait_for(lambda: any(r.sequence_number == seq for r in replies), 60)
        return next(r for r in replies if r.sequence_number == seq)

    try:
        from crlam.ros.play import _wait_matched

        _wait_matched({request_topic: w}, [request_topic], 60)
        early = call(1, str(tmp_path / "early"))
        assert early.result == RESULT_NO_MAP_RECEIVED and early.client_guid == 0xC0FFEE
        assert not (tmp_path / "early").exists()
        play_bag(bag, rate=float("inf"), lockstep=True, domain=DOMAIN, timeout=120)
        done = call(2, str(tmp_path / "saved"))
        assert done.result == RESULT_SUCCESS and done.client_guid == 0xC0FFEE
    finally:
        node.stop(save=False)
        client.close()
    out = tmp_path / "saved"
    assert is_complete(out) and (out / "map.yaml").is_file() and (out / "map.pgm").is_file()
    assert len(read_tum(out / "trajectory.tum").timestamps) == 40


def test_play_clock_and_use_sim_time(tmp_path: Path) -> None:
    """``crlam ros play --clock`` publishes /clock (the bag's times); a node with use_sim_time
    (``--use-sim-time`` or ``use_sim_time: true`` in the params file) stamps its map -> odom with
    it: every stamp is a time the bag's /clock carried (0 before the first /clock arrives, as in
    ROS 2), none the wall clock."""
    from rosbags.highlevel import AnyReader

    f = tmp_path / "p.yaml"
    f.write_text("crlam_slam:\n  ros__parameters:\n    use_sim_time: true\n")
    assert split_parameters(load_params_file(f, "crlam_slam"), str(f))[0].use_sim_time is True
    from crlam.cli import build_parser

    args = build_parser().parse_args(["ros", "slam", "--use-sim-time"])
    assert args.use_sim_time is True

    bag = _synthetic_bag(tmp_path / "corridor.mcap")
    with AnyReader([bag]) as reader:
        bag_times = {t for _, t, _ in reader.messages()}
    params = NodeParameters(max_scan_wait=float("inf"), odom_extrapolation=0.0, process_every_scan=True, use_sim_time=True)
    node = SlamNode(params, dict(SLAM), domain=DOMAIN)
    node.start()
    test = DdsNode("crlam_test_clock", domain=DOMAIN)
    col = Collector(test)
    col.read("/clock", m.Clock, qos.reliable(1))
    col.read("/tf", m.TFMessage, qos.reliable(100))
    try:
        stats = play_bag(bag, rate=float("inf"), lockstep=True, clock=True, domain=DOMAIN, timeout=120)
        node.wait_idle()
    finally:
        node.stop(save=False)
    assert col.events["/clock"].wait(30) and col.events["/tf"].wait(30)
    test.close()
    assert stats.clock_messages == sum(stats.published.values())
    ns = lambda t: t.sec * 1_000_000_000 + t.nanosec  # noqa: E731
    clocks = [ns(c.clock) for c in col.samples["/clock"]]
    assert set(clocks) <= bag_times and clocks == sorted(clocks)
    stamps = [ns(tr.header.stamp) for s in col.samples["/tf"] for tr in s.transforms if tr.child_frame_id == "odom"]
    assert stamps and set(stamps) <= bag_times | {0}
    assert any(s > 0 for s in stamps)
