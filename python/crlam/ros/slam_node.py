"""``crlam ros slam``: RBPF-CLAM as a live ROS 2 node.

**In**: ``/scan`` (sensor_msgs/LaserScan, best effort; MultiEchoLaserScan on ``scan_topic``
too is read by the offline reader only), ``/odom`` (nav_msgs/Odometry), ``/tf_static`` (the laser
mount), ``/clock`` (with ``use_sim_time``), ``/crlam/save_map`` (std_msgs/String: a folder to
write, or empty for ``output_folder``).

**Out**: ``/map`` and ``/map_confidence`` (nav_msgs/OccupancyGrid, reliable transient local:
expected occupancy x 100 and the occupancy's standard deviation x 200, -1 unknown),
``/map_metadata``, ``/tf`` map -> odom every ``transform_publish_period`` s,
``/pose`` (PoseWithCovarianceStamped), ``/particles`` (PoseArray), ``/path`` (Path),
``/diagnostics`` (:data:`DIAGNOSTIC_NAME`: scans received, handled, processed, dropped, latency).

**Threads.** Cyclone's listener thread only hands samples over (:class:`SlamNode` callbacks
take a lock for microseconds); one worker thread runs the filter on the newest matched scan
(a matched scan that another replaces before the worker takes it is *dropped* and counted: the
filter's own update triggers would have skipped most of them anyway), and a timer thread
publishes map -> odom at a steady rate. With a :class:`crlam.live_view.LiveView` as
:attr:`SlamNode.live_view` (``--foxglove``), every output also goes, as the same CDR bytes, to the
Foxglove WebSocket, with the scans the filter took, ``odom -> base_link`` at those scans and
``/tf_static``; a message is serialised for it only while a client subscribes to its topic, and
the server drops a slow client's oldest messages: the view never holds up the filter.
A save (request or shutdown) writes a crlam run folder
(trajectory, maps, belief, config) plus the Nav2 map through :func:`crlam.io.run_folder.staged_folder`:
the folder appears whole or not at all.
"""

from __future__ import annotations

import math
import threading
import time
from collections import deque
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from crlam.errors import CrlamError
from crlam.ros.live_view_mirror import LiveViewMirror
from crlam.ros.message_helpers import pose_msg, ros_messages, ros_stamp, stamp_seconds, yaw_quaternion
from crlam.ros.odometry_buffer import OdometryBuffer, PendingScan
from crlam.ros.params import NodeParameters
from crlam.ros.save_map_service import SaveMapService

__all__ = ["DIAGNOSTIC_NAME", "SLAM_TOPICS", "SlamNode"]

#: (topic, ROS type, in/out, QoS, what) of ``crlam ros slam`` (the documentation's topic table).
SLAM_TOPICS = (
    ("/scan", "sensor_msgs/msg/LaserScan", "in", "sensor data (best effort)", "the laser (scan_topic)"),
    ("/odom", "nav_msgs/msg/Odometry", "in", "reliable", "wheel odometry (odom_topic)"),
    ("/tf_static", "tf2_msgs/msg/TFMessage", "in", "transient local", "the laser mount (base frame -> laser frame)"),
    ("/clock", "rosgraph_msgs/msg/Clock", "in", "reliable", "with use_sim_time"),
    ("/crlam/save_map", "std_msgs/msg/String", "in", "reliable", "save the run folder (data: folder, or empty)"),
    ("/map", "nav_msgs/msg/OccupancyGrid", "out", "transient local", "expected occupancy x 100, -1 unknown"),
    ("/map_confidence", "nav_msgs/msg/OccupancyGrid", "out", "transient local", "the occupancy's standard deviation x 200"),
    ("/map_metadata", "nav_msgs/msg/MapMetaData", "out", "transient local", "the map's size, resolution and origin"),
    ("/tf", "tf2_msgs/msg/TFMessage", "out", "reliable", "map -> odom every transform_publish_period"),
    ("/pose", "geometry_msgs/msg/PoseWithCovarianceStamped", "out", "reliable", "the estimate and the particles' spread"),
    ("/particles", "geometry_msgs/msg/PoseArray", "out", "reliable", "the particles at each processed scan"),
    ("/path", "nav_msgs/msg/Path", "out", "reliable", "the estimate at every processed scan so far, with each map update"),
    ("/diagnostics", "diagnostic_msgs/msg/DiagnosticArray", "out", "reliable", "scans received, processed, dropped; latency"),
)

#: The DiagnosticStatus name of a node's counters (``/diagnostics``) ends with this; the
#: status's hardware_id is ``crlam``.
DIAGNOSTIC_NAME = ": scans"


def scan_ranges(msg: Any) -> NDArray[np.float64]:
    """A LaserScan's ranges with every invalid reading (NaN, inf, <= 0, below range_min, above
    range_max) set to range_max, a no-return: :meth:`crlam.io.rosbag.RosbagReader._scan_ranges`'s rule."""
    r = np.asarray(msg.ranges, dtype=np.float64).copy()
    rmax, rmin = float(np.float32(msg.range_max)), float(np.float32(msg.range_min))
    nan = np.isnan(r)
    inf = np.isposinf(r)
    nonpos = ~nan & (r <= 0.0)
    below = ~nan & ~nonpos & (r < rmin)
    above = ~inf & (r > rmax)
    r[nan | inf | nonpos | below | above] = rmax
    return r


class SlamNode(SaveMapService, LiveViewMirror):
    """The node; :meth:`start` makes its readers, writers and threads, :meth:`stop` ends them.

    Parameters
    ----------
    node : NodeParameters
        Frames, topics, rates, saving.
    slam_overrides : dict
        :class:`crlam.slam.SlamConfig` fields over the preset ``node.preset``.
    domain, dds_config
        See :class:`crlam.ros.dds.DdsNode`.
    """

    def __init__(
        self, node: NodeParameters, slam_overrides: dict[str, Any], *, domain: int | None = None, dds_config: str = "loopback"
    ) -> None:
        self.params = node
        self.config = self._make_config(slam_overrides)
        self.domain, self.dds_config = domain, dds_config
        self.lock = threading.Lock()
        self.write_lock = threading.Lock()
        self.wake = threading.Condition(self.lock)
        self.buffer = OdometryBuffer(node.odom_tolerance, node.max_scan_wait, node.odom_extrapolation)
        self.ready: deque[PendingScan] = deque()
        self.static: dict[tuple[str, str], Any] = {}
        self.base_frame = node.base_frame.lstrip("/")
        self.mount: NDArray[np.float64] | None = None
        self.mirrored = False
        if node.laser_mount:
            self.mount = np.array([float(v) for v in node.laser_mount.split()], dtype=np.float64)
        self.counters = {
            "ready": 1,
            "scans_received": 0,
            "odometry_received": 0,
            "scans_handled": 0,
            "scans_processed": 0,
            "scans_dropped": 0,
            "scans_without_odometry": 0,
            "scans_extrapolated": 0,
        }
        self.latencies: deque[float] = deque(maxlen=1000)
        self.map_to_odom = np.zeros(3)
        self.sim_time: float | None = None
        self.run: Any = None
        self.readings: Any = None
        self.last_map_t = -math.inf
        self.path_poses: list[Any] = []
        self.stop_event = threading.Event()
        #: Save requests: (folder, the service request's (client id, sequence number) to reply to, or None).
        self.save_requests: deque[tuple[str, tuple[int, int] | None]] = deque()
        self.saved: list[Path] = []
        self.busy = False
        self.threads: list[threading.Thread] = []
        self.t_first_wall: float | None = None
        #: A :class:`crlam.live_view.LiveView` to mirror the outputs to (set before :meth:`start`), or None.
        self.live_view: Any = None

    #: The node's name (DDS participant, parameter file section, diagnostics).
    NODE_NAME = "crlam_slam"

    def _make_config(self, overrides: dict[str, Any]) -> Any:
        """The preset's settings with ``overrides``. The odometry-noise fit reads the whole log
        ahead (``motion_noise = "estimate"``): live, the motion model's own parameters are used."""
        from dataclasses import replace

        from crlam.slam.presets import resolve

        config = resolve(self.params.preset, overrides)
        if config.motion_noise == "estimate" and config.motion_params is None:
            config = replace(config, motion_noise="model")
        return config

    # --- DDS ----------------------------------------------------------------------------------

    def start(self) -> None:
        m = ros_messages()
        from crlam.ros import qos
        from crlam.ros.dds import DdsNode

        p = self.params
        self.dds = DdsNode(self.NODE_NAME, domain=self.domain, dds_config=self.dds_config)
        d = self.dds
        view = self.live_view
        if view is not None:
            # Every output is advertised at once (a client can subscribe before its first message),
            # and so are the inputs the view mirrors.
            d.on_new_writer = lambda topic, msgtype: view.announce({topic: msgtype})
            view.announce({"/scan": "sensor_msgs/msg/LaserScan", "/tf_static": "tf2_msgs/msg/TFMessage"})
        self.w_map = d.writer("/map", m.OccupancyGrid, qos.latched())
        self.w_conf = d.writer("/map_confidence", m.OccupancyGrid, qos.latched())
        self.w_meta = d.writer("/map_metadata", m.MapMetaData, qos.latched())
        self.w_tf = d.writer("/tf", m.TFMessage, qos.reliable(100))
        self.w_pose = d.writer("/pose", m.PoseWithCovarianceStamped, qos.reliable())
        self.w_particles = d.writer("/particles", m.PoseArray, qos.reliable())
        self.w_path = d.writer("/path", m.Path, qos.reliable())
        self.w_diag = d.writer("/diagnostics", m.DiagnosticArray, qos.reliable(50))
        d.reader("/tf_static", m.TFMessage, qos.latched(100), self._on_tf_static)
        if p.odom_topic.strip("/") == "tf":
            d.reader(p.odom_topic, m.TFMessage, qos.reliable(100), self._on_tf)
        else:
            d.reader(p.odom_topic, m.Odometry, qos.reliable(100), self._on_odom)
        if p.scan_type == "MultiEchoLaserScan":
            d.reader(p.scan_topic, m.MultiEchoLaserScan, qos.sensor_data(10), self._on_multi_echo)
        else:
            d.reader(p.scan_topic, m.LaserScan, qos.sensor_data(10), self._on_scan)
        d.reader(p.save_map_topic, m.String, qos.reliable(), self._on_save)
        self._serve_save_map()
        if p.use_sim_time:
            d.reader("/clock", m.Clock, qos.reliable(1), self._on_clock)
        for target, name in ((self._work, "crlam-slam-worker"), (self._publish_tf_loop, "crlam-slam-tf")):
            t = threading.Thread(target=target, name=name, daemon=True)
            t.start()
            self.threads.append(t)
        self._publish_diagnostics()

    def _write(self, writer: Any, msg: Any) -> None:
        """Every write goes through one lock: the binding serialises a type into a buffer it
        shares between writers, so two threads must never write at once. The live view gets the
        same bytes (transient-local topics latched)."""
        with self.write_lock:
            writer.write(msg)
            view = self.live_view
            entry = None if view is None else self.dds.writer_topics.get(id(writer))  # None: a service's reply
            if entry is not None:
                topic, msgtype, latched = entry
                if latched or view.has_subscriber(topic, msgtype):
                    view.publish_cdr(topic, msgtype, msg.serialize(), latched=latched)

    def now(self) -> float:
        """The time output is stamped with: /clock with use_sim_time, else the wall clock (s)."""
        if self.params.use_sim_time:
            return self.sim_time or 0.0
        return time.time()

    def _on_clock(self, msg: Any) -> None:
        self.sim_time = stamp_seconds(msg.clock)

    def _on_tf_static(self, msg: Any) -> None:
        with self.lock:
            for tr in msg.transforms:
                self.static[(tr.header.frame_id.lstrip("/"), tr.child_frame_id.lstrip("/"))] = tr.transform
            static = list(self.static.items())
        if self.live_view is not None:
            self._view_static(static)

    def _mount_of(self, laser_frame: str) -> tuple[NDArray[np.float64], bool] | None:
        """The laser's mount in the base frame from /tf_static (None until it is known)."""
        from crlam.io.rosbag_tf import TransformTree, planar, transform_matrix

        if not self.base_frame:
            return None
        tree = TransformTree()
        for (parent, child), tr in self.static.items():
            tree.add(parent, child, transform_matrix(tr))
        if self.base_frame == laser_frame:
            return np.zeros(3), False
        mtx = tree.lookup(self.base_frame, laser_frame)
        if mtx is None:
            return None
        return planar(mtx)

    def _on_odom(self, msg: Any) -> None:
        from crlam.io.rosbag_tf import yaw_of

        p = msg.pose.pose
        pose = np.array([float(p.position.x), float(p.position.y), yaw_of(p.orientation)])
        with self.lock:
            self.counters["odometry_received"] += 1
            if not self.base_frame:
                self.base_frame = msg.child_frame_id.lstrip("/") or "base_link"
            self.buffer.add_odometry(stamp_seconds(msg.header.stamp), pose)
            self._resolve(final=False)

    def _on_tf(self, msg: Any) -> None:
        """Odometry from /tf: the odom_frame -> base_frame transforms (base_frame: the given one,
        else the first child of odom_frame seen)."""
        from crlam.io.rosbag_tf import planar, transform_matrix

        odom = self.params.odom_frame.lstrip("/")
        with self.lock:
            self.counters["odometry_received"] += 1  # messages on the odometry topic, as for /odom
        for tr in msg.transforms:
            child = tr.child_frame_id.lstrip("/")
            if tr.header.frame_id.lstrip("/") != odom:
                continue
            with self.lock:
                if not self.base_frame:
                    self.base_frame = child
                if child != self.base_frame:
                    continue
                pose, _ = planar(transform_matrix(tr.transform))
                self.buffer.add_odometry(stamp_seconds(tr.header.stamp), np.asarray(pose, dtype=np.float64))
                self._resolve(final=False)

    def _on_multi_echo(self, msg: Any) -> None:
        """A MultiEchoLaserScan as a LaserScan with one range per beam (``echo``; NaN, a no-return,
        for a beam without echoes): the offline reader's rule."""
        m = ros_messages()
        out = np.full(len(msg.ranges), np.nan)
        for i, beam in enumerate(msg.ranges):
            echoes = np.asarray(beam.echoes, dtype=np.float64)
            if not len(echoes):
                continue
            if self.params.echo == "last":
                out[i] = echoes[-1]
            elif self.params.echo == "strongest" and i < len(msg.intensities) and len(msg.intensities[i].echoes) == len(echoes):
                out[i] = echoes[int(np.argmax(np.asarray(msg.intensities[i].echoes)))]
            else:
                out[i] = echoes[0]
        scan = m.LaserScan(
            header=msg.header,
            angle_min=msg.angle_min,
            angle_max=msg.angle_max,
            angle_increment=msg.angle_increment,
            time_increment=msg.time_increment,
            scan_time=msg.scan_time,
            range_min=msg.range_min,
            range_max=msg.range_max,
            ranges=out.tolist(),
        )
        self._on_scan(scan)

    def _on_scan(self, msg: Any) -> None:
        with self.lock:
            self.counters["scans_received"] += 1
            self.buffer.add_scan(PendingScan(stamp_seconds(msg.header.stamp), time.monotonic(), msg))
            self._resolve(final=False)

    def _on_save(self, msg: Any) -> None:
        with self.lock:
            self.save_requests.append((msg.data.strip(), None))
            self.wake.notify_all()

    def _resolve(self, final: bool) -> None:
        """Moves matched scans to the worker's slot (lock held); a replaced one is dropped."""
        before = self.buffer.skipped_before + self.buffer.skipped_after
        if self.mount is None and self.buffer.pending:
            got = self._mount_of(self.buffer.pending[0].payload.header.frame_id.lstrip("/"))  # type: ignore[attr-defined]
            if got is None and not final:
                return  # scans wait for /tf_static
            self.mount, self.mirrored = got if got is not None else (np.zeros(3), False)
        for scan in self.buffer.resolved(time.monotonic(), final):
            if self.ready and not self.params.process_every_scan:
                self.counters["scans_dropped"] += len(self.ready)
                self.ready.clear()
            self.ready.append(scan)
            self.wake.notify_all()
        self.counters["scans_without_odometry"] += self.buffer.skipped_before + self.buffer.skipped_after - before
        self.counters["scans_extrapolated"] = self.buffer.extrapolated

    # --- the filter ---------------------------------------------------------------------------

    def _work(self) -> None:
        while True:
            with self.lock:
                while not self.ready and not self.save_requests and not self.stop_event.is_set():
                    self.wake.wait()
                # Scans before a save request: the save comes after every scan that arrived first.
                request = self.save_requests.popleft() if not self.ready and self.save_requests else None
                if not self.ready and request is None:
                    return  # stop
                scan = self.ready.popleft() if self.ready else None
                self.busy = scan is not None or request is not None
            saved: bool | None = None
            try:
                if scan is not None:
                    self._step(scan)
                if request is not None:
                    saved = self._save(request[0])
            except (CrlamError, OSError) as exc:
                print(f"crlam ros slam: error: {exc}", flush=True)
            finally:
                if request is not None and request[1] is not None:
                    self._reply_save(request[1], saved)
                with self.lock:
                    self.busy = False
                    self.wake.notify_all()
            self._publish_diagnostics()

    def _scan_inputs(self, msg: Any) -> tuple[NDArray[np.float64], NDArray[np.float64], float]:
        """(bearings rad, ranges m with no-returns as inf, the sensor's range_max) of a scan
        message, turned as the offline bag reader turns it (mirrored mount, decreasing angles)."""
        from crlam.io.rosbag_tf import wrap

        ranges = scan_ranges(msg)
        amin, inc = float(np.float32(msg.angle_min)), float(np.float32(msg.angle_increment))
        if self.mirrored:
            amin, inc = -amin, -inc
        if inc < 0:
            amin, inc = amin + inc * (len(ranges) - 1), -inc
            ranges = ranges[::-1].copy()
        amin = wrap(amin)
        rmax = float(np.float32(msg.range_max))
        angles = amin + inc * np.arange(len(ranges))
        return np.asarray(angles, dtype=np.float64), np.where(ranges >= rmax, np.inf, ranges), rmax

    def _filter_step(
        self, scan: PendingScan, angles: NDArray[np.float64], ranges: NDArray[np.float64], rmax: float
    ) -> tuple[bool, NDArray[np.float64], NDArray[np.float64] | None, tuple[float, float]]:
        """Feeds one matched scan to the filter: (processed, estimate, particle poses or None,
        (position spread m, heading spread rad))."""
        from crlam.experiments.slam_run import within_sensor_range
        from crlam.io.readings import ReadingFilter
        from crlam.slam import SlamRun

        assert scan.odom is not None and self.mount is not None
        if self.run is None:
            self.run = SlamRun(within_sensor_range(self.config, rmax))
            # The no-return policy, scan by scan as offline; the checks that read the log ahead
            # (body mask, laser mount, time offset, the map's range from the readings) do not run live.
            self.readings = ReadingFilter(self.run.config.no_return, self.run.config.max_range)
        assert self.readings is not None
        angles, ranges = self.readings.apply(angles, ranges, rmax)
        step = self.run.step(scan.odom, angles, ranges, self.mount, scan.stamp)
        particles = None
        spread = (0.0, 0.0)
        if step.processed:
            particles = np.asarray(self.run.filter.particle_poses(), dtype=np.float64)
            rec = self.run.particle_sets[-1]
            spread = (rec.spread_xy, rec.spread_theta)
        return bool(step.processed), np.asarray(step.estimate, dtype=np.float64), particles, spread

    def _step(self, scan: PendingScan) -> None:
        from crlam.pose import compose

        assert scan.odom is not None
        if self.t_first_wall is None:
            self.t_first_wall = time.perf_counter()
        angles, ranges, rmax = self._scan_inputs(scan.payload)
        processed, est, particles, spread = self._filter_step(scan, angles, ranges, rmax)
        if self.live_view is not None:
            self._view_scan(scan)
        # map -> odom = estimate (map) composed with the inverse odometry pose (odom).
        c, s = math.cos(scan.odom[2]), math.sin(scan.odom[2])
        inv = np.array([-(c * scan.odom[0] + s * scan.odom[1]), s * scan.odom[0] - c * scan.odom[1], -scan.odom[2]])
        m2o = np.asarray(compose(est, inv), dtype=np.float64)
        with self.lock:
            self.map_to_odom = m2o
            self.counters["scans_handled"] += 1
            self.counters["scans_processed"] += int(processed)
        self._publish_tf(self.now())
        self.latencies.append(time.monotonic() - scan.arrival)
        self._publish_estimate(scan.stamp, est, particles, spread)
        if processed and scan.stamp - self.last_map_t >= self.params.map_update_interval:
            self.last_map_t = scan.stamp
            self._publish_path(scan.stamp)
            self._publish_map(scan.stamp)

    def _publish_estimate(
        self, t: float, est: NDArray[np.float64], particles: NDArray[np.float64] | None, spread: tuple[float, float]
    ) -> None:
        m = ros_messages()

        p = self.params
        header = m.Header(stamp=ros_stamp(t), frame_id=p.map_frame)
        if particles is not None:  # a processed scan
            self.path_poses.append(m.PoseStamped(header=header, pose=pose_msg(est)))
        cov = [0.0] * 36
        # The particle set's spread: RMS position spread shared by x and y, heading spread.
        cov[0] = cov[7] = spread[0] ** 2 / 2
        cov[35] = spread[1] ** 2
        self._write(
            self.w_pose, m.PoseWithCovarianceStamped(header=header, pose=m.PoseWithCovariance(pose=pose_msg(est), covariance=cov))
        )
        if particles is not None:
            self._write(self.w_particles, m.PoseArray(header=header, poses=[pose_msg(q) for q in particles]))

    def _publish_path(self, t: float) -> None:
        """The estimates of the processed scans so far, with each map update: a path of every scan,
        sent at every scan, would cost the worker time growing with the run (10,000 poses take
        0.1 s to serialise, a scan period of a 7.7 Hz lidar)."""
        m = ros_messages()

        header = m.Header(stamp=ros_stamp(t), frame_id=self.params.map_frame)
        self._write(self.w_path, m.Path(header=header, poses=list(self.path_poses)))

    def _map_layers(self) -> tuple[Any, NDArray[np.bool_], Any]:
        from crlam.experiments.known_poses import unknown_mask
        from crlam.mapping import ConfidenceRichMap, MapLayer

        best = self.run.best_map()
        if isinstance(best, ConfidenceRichMap):
            mean, var, ent = best.layers()
            unknown = unknown_mask(best, ent)
            std = MapLayer(np.sqrt(np.maximum(var.values, 0.0)), var.origin, var.resolution, "standard deviation")
            return mean, unknown, std
        mean = best.probability()
        return mean, best.native.log_odds(best.region()) == 0.0, None

    def _grid(self, t: float, layer: Any, data: NDArray[np.int8]) -> Any:
        m = ros_messages()

        ny, nx = layer.shape
        info = m.MapMetaData(
            map_load_time=ros_stamp(t),
            resolution=float(layer.resolution),
            width=nx,
            height=ny,
            origin=pose_msg(np.array([layer.origin[0], layer.origin[1], 0.0])),
        )
        return m.OccupancyGrid(header=m.Header(stamp=ros_stamp(t), frame_id=self.params.map_frame), info=info, data=data.tolist())

    def _publish_map(self, t: float) -> None:
        from crlam.experiments.slam_mcap import occupancy_grid_values

        mean, unknown, std = self._map_layers()
        grid = self._grid(t, mean, occupancy_grid_values(mean.values, unknown))
        self._write(self.w_map, grid)
        self._write(self.w_meta, grid.info)
        if std is not None:
            self._write(self.w_conf, self._grid(t, std, occupancy_grid_values(std.values, unknown, scale=200.0)))

    def _publish_tf(self, t: float) -> None:
        m = ros_messages()

        with self.lock:
            p = self.map_to_odom.copy()
        tr = m.TransformStamped(
            header=m.Header(stamp=ros_stamp(t), frame_id=self.params.map_frame),
            child_frame_id=self.params.odom_frame,
            transform=m.Transform(
                translation=m.Vector3(x=float(p[0]), y=float(p[1]), z=0.0), rotation=yaw_quaternion(float(p[2]))
            ),
        )
        self._write(self.w_tf, m.TFMessage(transforms=[tr]))

    def _publish_tf_loop(self) -> None:
        period = max(self.params.transform_publish_period, 1e-3)
        while not self.stop_event.wait(period):
            if self.t_first_wall is not None:
                self._publish_tf(self.now())
            self._publish_diagnostics()

    def latency_summary(self) -> dict[str, float]:
        """Median and 99th percentile (ms) of scan arrival -> published map -> odom."""
        lat = np.array(self.latencies, dtype=np.float64) * 1e3
        if not len(lat):
            return {}
        return {"latency_median_ms": float(np.median(lat)), "latency_p99_ms": float(np.percentile(lat, 99))}

    def _publish_diagnostics(self) -> None:
        m = ros_messages()

        with self.lock:
            c = self.counters
            settled = c["scans_handled"] + c["scans_dropped"] + c["scans_without_odometry"]
            values = [m.KeyValue(key=k, value=str(v)) for k, v in (*c.items(), ("scans_settled", settled))]
        values += [m.KeyValue(key=k, value=f"{v:.2f}") for k, v in self.latency_summary().items()]
        values += [m.KeyValue(key=k, value=str(v)) for k, v in self._extra_diagnostics().items()]
        status = m.DiagnosticStatus(
            level=0, name=f"{self.NODE_NAME}: scans", message="running", hardware_id="crlam", values=values
        )
        self._write(self.w_diag, m.DiagnosticArray(header=m.Header(stamp=ros_stamp(self.now())), status=[status]))

    def _extra_diagnostics(self) -> dict[str, object]:
        return {"particles": self.config.particles}

    # --- saving -------------------------------------------------------------------------------

    def _save(self, request: str) -> bool | None:
        """Writes the run folder ``request`` (or ``output_folder``) whole, or not at all: True once
        written, False with nothing to save yet, None without a folder to write."""
        from crlam.io.run_folder import staged_folder

        target = request or self.params.output_folder
        if not target:
            print("crlam ros slam: save request without a folder and no output_folder parameter: ignored", flush=True)
            return None
        with self.lock:
            self._resolve(final=True)
            scans, self.ready = list(self.ready), deque()
        for scan in scans:
            self._step(scan)
        if self.run is None or not self.run.particle_sets:
            print(f"crlam ros slam: nothing to save to {target} yet (no scan processed)", flush=True)
            return False
        from crlam.experiments.slam_run import write_slam_outputs

        p = self.params
        info = {
            "format": "ros2 (live DDS)",
            "scan_topic": p.scan_topic,
            "odom_topic": p.odom_topic,
            "base_frame": self.base_frame,
            "odom_frame": p.odom_frame,
            "laser_offset": [float(v) for v in (self.mount if self.mount is not None else np.zeros(3))],
            "odometry": "wheel",
            "odometry_choice": "the node's odometry topic",
        } | {k: v for k, v in self.counters.items() if k != "ready"}
        wall = time.perf_counter() - (self.t_first_wall or time.perf_counter())
        with staged_folder(target, replace=True, command="crlam ros slam") as stage:
            write_slam_outputs(self.run, wall, stage, source=f"ros2:{p.scan_topic}", input_info=info)
        self._publish_path(self.run.stamps[-1])
        self._publish_map(self.run.stamps[-1])
        self.saved.append(Path(target))
        print(f"crlam ros slam: saved {self.run.n_scans} scans to {target}", flush=True)
        return True

    def request_save(self, folder: str = "") -> None:
        """Queues a save (as a message on the save topic does)."""
        with self.lock:
            self.save_requests.append((folder, None))
            self.wake.notify_all()

    def wait_idle(self) -> None:
        """Returns once every message received so far has been handed over and no scan or save is
        waiting or being handled."""
        self.dds.wait_delivered()
        with self.lock:
            while self.ready or self.save_requests or self.busy:
                self.wake.wait()

    def stop(self, save: bool = True) -> None:
        """Ends the node; with ``save`` and ``output_folder`` set, saves first (Ctrl-C, SIGTERM)."""
        if save and self.params.output_folder:
            self.request_save("")
        self.wait_idle()
        self.stop_event.set()
        with self.lock:
            self.wake.notify_all()
        for t in self.threads:
            t.join()
        self.dds.close()
