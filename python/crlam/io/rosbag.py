"""ROS bag reader (streaming): ROS 1 ``.bag``, ROS 2 bag folders (sqlite3 or MCAP storage) and
plain ``.mcap`` files, read with the pure-Python ``rosbags`` package.

It yields the records the CARMEN reader yields (:class:`~crlam.io.carmen_types.LaserScan` and
:class:`~crlam.io.carmen_types.OdometryReading`), so ``crlam map``, ``crlam slam`` and the
experiments take a bag wherever they take a CARMEN log.

What is read
------------
Scans
    ``sensor_msgs/msg/LaserScan`` (or ``MultiEchoLaserScan``: the first echo of every beam, or
    the last or the strongest with ``echo``) of the scan topic: the only laser topic of the bag
    unless ``scan_topic`` names one. The stamp is the message header's (the bag's receive time
    when the header stamp is zero). Beam ``i`` has the
    bearing ``angle_min + i * angle_increment``; any layout works (0..360 deg, -180..180 deg, a
    negative increment: such a scan is reversed so that its increment is positive).
Invalid readings
    A range is a "no return" when it is ``>= max_range`` (``max_range`` = the message's
    ``range_max``), as in CARMEN scans; every consumer (mapping, SLAM) treats such readings as
    no-returns. ``+inf`` and readings above ``range_max`` become ``range_max``. NaN, ``-inf``,
    ``0``, negative readings and readings below ``range_min`` cannot be dropped from a scan record
    (its bearings are implicit, one per range), so they also become ``range_max``: the same rule
    the CARMEN reader applies to NaN and non-positive ranges. Each case is counted in
    :class:`BagStats`.
Odometry
    ``nav_msgs/msg/Odometry`` of the odometry topic (the only one, or ``/odom`` among several,
    unless ``odom_topic`` names one); without an odometry topic, the ``/tf`` transforms from the
    odometry frame (``odom``) to the base frame. Every odometry message is yielded as an
    :class:`OdometryReading` (pose projected to the plane: x, y, yaw), and each scan's ``odom``
    field is the odometry interpolated to the scan's stamp (linear in x and y, shortest arc in
    yaw). A scan stamped up to ``odom_tolerance`` seconds before the first or after the last
    odometry reading takes that reading; scans further out are skipped and counted. With
    ``odometry=False`` none is read: every scan is yielded as it comes, ``odom`` and ``pose`` NaN
    (for scan-matching odometry, :mod:`crlam.slam.scan_odometry`).
IMU
    With ``imu=True``, the yaw rate of each ``sensor_msgs/msg/Imu`` message of the IMU topic (the
    only one unless ``imu_topic`` names one) as an :class:`~crlam.io.carmen_types.ImuReading`:
    the angular velocity rotated into the base frame by the IMU's mount, z component.
Laser mount
    ``laser_offset`` (the laser pose in the base frame, x, y, yaw) comes from ``/tf_static``: the
    chain of static transforms from the base frame (``base_frame``, by default the odometry's
    ``child_frame_id``) to the scan's ``frame_id``, composed in 3D and projected to the plane.
    When ``/tf_static`` links neither ``base_link`` nor ``base_footprint`` to the laser, the
    transforms of the first 500 ``/tf`` messages that never change (the odometry's and the map's
    left out: :class:`~crlam.io.rosbag_tf.FixedTransforms`) join the chain: some bags publish
    the mount on ``/tf`` (``mount_source = "tf"``). A
    laser whose z axis points down (a roll or pitch of pi: mounted upside down) sees the world
    mirrored: its beam bearings are negated. ``laser_mount=(x, y, yaw)`` replaces the mount
    found in ``/tf_static`` and ``upside_down=True`` mirrors the bearings (once: a mount that
    ``/tf_static`` already shows upside down is not mirrored twice). Without either and
    without a ``/tf_static`` path, the laser is taken to sit at the base frame's origin
    (``BagStats.mount_source`` says which rule was used).

``LaserScan.pose`` is the laser pose from odometry (``odom`` composed with the mount), like the
pose field of a CARMEN FLASER line; ``kind`` is the message type (``"LaserScan"``), ``host`` the
topic and ``line`` the 1-based index of the scan message in its topic.

Streaming: the bag is read message by message in time order; only the scans waiting for the
next odometry reading (at most 5 s of bag time each, then they are skipped as after the
odometry) and a short odometry history are held. A bag whose scans and odometry are stamped on
different clocks gives no scan: the error says so, with both stamp spans. ``/tf_static`` (and,
when it lacks the mount, the first ``/tf`` messages) is read first in a separate pass.
"""

from __future__ import annotations

import math
import os
from bisect import bisect_left
from collections import deque
from collections.abc import Iterator, Sequence
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from crlam.errors import ConfigError, DataFormatError
from crlam.io.bag_open import bag_errors, check_bag_input, library_errors, open_any_reader
from crlam.io.carmen_types import ImuReading, LaserScan, LogRecord, OdometryReading
from crlam.io.message_checks import MessagePlace, check_scan_header, check_translation
from crlam.io.rosbag_scans import ECHOES, BagStats, scan_ranges
from crlam.io.rosbag_tf import FixedTransforms, TransformTree, planar, transform_matrix, wrap, yaw_of
from crlam.io.rosbag_topics import IMU_TYPE, LASER_TYPES, ODOMETRY_TYPE, TF_TYPE, pick_imu, pick_odom, pick_scan, topics_text
from crlam.pose import compose

# Kept under their former private names (the writer's tests compare against the reader's yaw).
_yaw_of = yaw_of
_wrap = wrap

__all__ = [
    "ECHOES",
    "IMU_TYPE",
    "LASER_TYPES",
    "ODOMETRY_TYPE",
    "TF_TYPE",
    "BagStats",
    "RosbagReader",
    "is_bag",
    "read_bag",
]

#: /tf messages read to find a fixed base -> laser transform there when /tf_static has none.
_TF_MOUNT_PROBE = 500

#: Odometry readings kept to interpolate scans that arrive late.
_ODOM_HISTORY = 4096
#: Bag time (s) a scan waits for the odometry reading after its stamp before it is given up.
_MAX_WAIT = 5.0


def is_bag(path: str | os.PathLike[str]) -> bool:
    """True for a ROS bag: a folder holding ``metadata.yaml``, a ``.bag`` or a ``.mcap`` file."""
    p = Path(path)
    if p.is_dir():
        return (p / "metadata.yaml").is_file()
    return p.suffix.lower() in (".bag", ".mcap")


def _stamp(header: Any) -> float:
    # Integer nanoseconds divided exactly (Python's int / int is correctly rounded): the float
    # nearest the stamp, so a stamp written from a float with up to 9 decimals reads back equal.
    return (int(header.stamp.sec) * 1_000_000_000 + int(header.stamp.nanosec)) / 1_000_000_000


def _library_errors() -> tuple[type[BaseException], ...]:
    """What reading a damaged bag raises in the bag library (see :mod:`crlam.io.bag_open`)."""
    return library_errors()


class RosbagReader:
    """Streaming ROS bag reader; iterate it to get :data:`~crlam.io.carmen_types.LogRecord` s.

    Parameters
    ----------
    path : str or PathLike
        A ROS 2 bag folder (``metadata.yaml`` + ``.db3`` / ``.mcap``), a ROS 1 ``.bag`` or a ``.mcap``.
    scan_topic, odom_topic : str, optional
        Topics to read (default: detected, see the module docstring). ``odom_topic="/tf"`` takes
        odometry from TF even when the bag has an odometry topic.
    base_frame : str, optional
        The robot's base frame, whose pose the odometry gives: with odometry from ``/tf`` the
        child of ``odom_frame`` to follow (default: one from which ``/tf_static`` reaches the
        laser); with an Odometry topic it must be the messages' ``child_frame_id`` (the default).
    odom_frame : str
        The odometry frame, the parent of the base frame in ``/tf`` (used without an odometry topic).
    laser_mount : (x, y, yaw), optional
        The laser pose in the base frame (m, m, rad); replaces the one from ``/tf_static``.
    upside_down : bool
        Mirror the beam bearings (a laser mounted upside down).
    odom_tolerance : float
        How far (s) before the first / after the last odometry reading a scan may be stamped and
        still take that reading's pose.
    echo : str
        The return of a ``MultiEchoLaserScan`` beam used as its range: ``"first"`` (default),
        ``"last"`` or ``"strongest"`` (the echo of highest intensity).
    odometry : bool
        Read the odometry (default). ``False`` reads none, whatever the bag holds: every scan is
        yielded at once with ``odom`` and ``pose`` NaN (for scan-matching odometry,
        :mod:`crlam.slam.scan_odometry`); the base frame is then ``base_frame``, else ``base_link`` or
        ``base_footprint`` when a fixed chain reaches the laser from it, else the top of the
        laser frame's chain.
    imu : bool
        Also yield the yaw rate of every ``sensor_msgs/msg/Imu`` message of the IMU topic as an
        :class:`~crlam.io.carmen_types.ImuReading` (rotated into the base frame by the IMU's
        mount when the fixed transforms give it). A bag without an IMU topic yields none.
    imu_topic : str, optional
        The IMU topic (default: the only one).

    Raises
    ------
    DataFormatError
        When a topic is missing or ambiguous (the message lists the bag's topics and types).
    """

    def __init__(
        self,
        path: str | os.PathLike[str],
        *,
        scan_topic: str | None = None,
        odom_topic: str | None = None,
        base_frame: str | None = None,
        odom_frame: str = "odom",
        laser_mount: Sequence[float] | None = None,
        upside_down: bool = False,
        odom_tolerance: float = 0.25,
        echo: str = "first",
        odometry: bool = True,
        imu: bool = False,
        imu_topic: str | None = None,
    ) -> None:
        # A FIFO, a device or a socket, and a folder whose metadata.yaml names files outside it,
        # are refused before the bag library opens anything (crlam.io.bag_open).
        self.path = check_bag_input(path)
        if laser_mount is not None and (len(laser_mount) != 3 or not all(math.isfinite(float(v)) for v in laser_mount)):
            raise ConfigError(f"laser_mount needs 3 finite values (x, y, yaw), got {list(laser_mount)}")
        if not (math.isfinite(odom_tolerance) and odom_tolerance >= 0):
            raise ConfigError(f"odom_tolerance must be >= 0, got {odom_tolerance}")
        if echo not in ECHOES:
            raise ConfigError(f"echo must be one of {', '.join(ECHOES)}, got {echo!r}")
        self.scan_topic = scan_topic
        self.odom_topic = odom_topic
        self.base_frame = base_frame
        self.odom_frame = odom_frame
        self.laser_mount = None if laser_mount is None else tuple(float(v) for v in laser_mount)
        self.upside_down = bool(upside_down)
        self.odom_tolerance = float(odom_tolerance)
        self.echo = echo
        self.odometry = bool(odometry)
        self.imu = bool(imu)
        self.imu_topic = imu_topic
        self.stats = BagStats()
        self._scan_span = (math.nan, math.nan)
        self._odom_span: tuple[float, float] | None = None
        self._static: TransformTree | None = None
        # The stamp of the last scan yielded: later scans at or before it are skipped.
        self._last_scan_t: float | None = None

    # -- opening and detection ---------------------------------------------------------------

    def _open(self) -> Any:
        return open_any_reader(self.path)

    def _decode(self, reader: Any, conn: Any, raw: bytes, index: int) -> Any:
        """A message deserialized; a damaged one is a DataFormatError naming its topic and index."""
        with bag_errors(self.path, f"{conn.topic} message {index}"):
            return reader.deserialize(raw, conn.msgtype)

    def _place(self, conn: Any, index: int) -> MessagePlace:
        return MessagePlace(str(self.path), conn.topic, index)

    def _error(self, message: str, connections: Sequence[Any]) -> DataFormatError:
        return DataFormatError(f"{message}; the bag's topics: {topics_text(connections)}", path=str(self.path))

    # The topics read: crlam.io.rosbag_topics.
    def _pick_scan(self, conns: Sequence[Any]) -> list[Any]:
        return pick_scan(conns, self.scan_topic, self._error)

    def _pick_odom(self, conns: Sequence[Any]) -> tuple[list[Any], bool]:
        """The odometry connections and whether they are TF (True) or Odometry messages."""
        return pick_odom(conns, self.odom_topic, self._error)

    def _pick_imu(self, conns: Sequence[Any]) -> list[Any]:
        return pick_imu(conns, self.imu_topic, self._error)

    def scan_count(self) -> int:
        """The scan messages the bag's index lists on the scan topic this reader would pick (read
        from the index, no message is decoded): a progress bar's total, an upper bound of the
        scans a run yields. A damaged bag raises :class:`~crlam.errors.DataFormatError`."""
        with bag_errors(self.path), self._open() as reader:
            return sum(int(c.msgcount) for c in self._pick_scan(reader.connections))

    def has_odometry(self) -> bool:
        """Whether the bag has odometry to read: a ``nav_msgs/msg/Odometry`` topic, or
        ``odom_frame -> base`` transforms in the first ``/tf`` messages (a given ``odom_topic``
        counts as odometry; it is checked when the bag is read)."""
        if self.odom_topic is not None:
            return True
        with bag_errors(self.path), self._open() as reader:
            conns = reader.connections
            if any(c.msgtype == ODOMETRY_TYPE for c in conns):
                return True
            tf = [c for c in conns if c.topic in ("/tf", "tf") and c.msgtype == TF_TYPE]
            return bool(tf) and bool(self._tf_children(reader, tf))

    def _fixed_tf_tree(self, reader: Any) -> TransformTree:
        """The transforms of the first ``/tf`` messages that never change, the odometry's and
        the map's left out (a fixed mount published on /tf rather than /tf_static)."""
        fixed = FixedTransforms(skip_parents=(self.odom_frame, "odom", "map", "world"))
        conns = [c for c in reader.connections if c.topic in ("/tf", "tf") and c.msgtype == TF_TYPE]
        for i, msg in enumerate(self._first(reader, conns, limit=_TF_MOUNT_PROBE) if conns else [], 1):
            for tr in msg.transforms:
                m = transform_matrix(tr.transform, self._place(conns[0], i), tr.child_frame_id)
                fixed.add(tr.header.frame_id, tr.child_frame_id, m)
        return fixed.tree()

    def _static_tree(self, reader: Any) -> TransformTree:
        tree = TransformTree()
        conns = [c for c in reader.connections if c.topic in ("/tf_static", "tf_static") and c.msgtype == TF_TYPE]
        if conns:  # an empty list would read every message
            for i, (conn, _, raw) in enumerate(reader.messages(connections=conns), 1):
                for tr in self._decode(reader, conn, raw, i).transforms:
                    m = transform_matrix(tr.transform, self._place(conn, i), tr.child_frame_id)
                    tree.add(tr.header.frame_id, tr.child_frame_id, m)
        return tree

    def _first(self, reader: Any, conns: Sequence[Any], limit: int = 1) -> list[Any]:
        out: list[Any] = []
        for conn, _, raw in reader.messages(connections=conns):
            out.append(self._decode(reader, conn, raw, len(out) + 1))
            if len(out) >= limit:
                break
        return out

    def _tf_children(self, reader: Any, tf_conns: Sequence[Any]) -> list[str]:
        """The children of the odometry frame in the first 200 /tf messages, in order seen."""
        children: list[str] = []
        for msg in self._first(reader, tf_conns, limit=200):
            for tr in msg.transforms:
                child = tr.child_frame_id.lstrip("/")
                if tr.header.frame_id.lstrip("/") == self.odom_frame and child not in children:
                    children.append(child)
        return children

    def _tf_base_frame(self, reader: Any, tf_conns: Sequence[Any], tree: TransformTree, laser_frame: str) -> str:
        """The base frame when odometry comes from /tf: a child of the odometry frame, preferring
        one from which a fixed chain reaches the laser frame."""
        children = self._tf_children(reader, tf_conns)
        if not children:
            raise self._error(
                f"no {self.odom_frame} -> base transform in /tf (give --base-frame and --odom-topic)", reader.connections
            )
        linked = [c for c in children if tree.reaches(c, laser_frame)]
        return (linked or children)[0]

    # -- iteration ---------------------------------------------------------------------------

    def __iter__(self) -> Iterator[LogRecord]:
        return self._records()

    def _records(self) -> Iterator[LogRecord]:
        """The records; what the bag library cannot read (a damaged, truncated or foreign file)
        is a :class:`DataFormatError` naming the bag."""
        with bag_errors(self.path):
            yield from self._read_records()

    def _read_records(self) -> Iterator[LogRecord]:
        self.stats = stats = BagStats()
        self._scan_span, self._odom_span = (math.nan, math.nan), None
        self._last_scan_t = None
        with self._open() as reader:
            conns = reader.connections
            scan_conns = self._pick_scan(conns)
            odom_conns, from_tf = self._pick_odom(conns) if self.odometry else ([], False)
            imu_conns = self._pick_imu(conns) if self.imu else []
            stats.scan_topic = scan_conns[0].topic
            stats.odom_topic = odom_conns[0].topic if odom_conns else ""
            stats.imu_topic = imu_conns[0].topic if imu_conns else ""
            stats.echo = self.echo
            tree = self._static = self._static_tree(reader)
            first_scan = self._first(reader, scan_conns)
            if not first_scan:
                raise self._error(f"scan topic {stats.scan_topic} holds no messages", conns)
            laser_frame = first_scan[0].header.frame_id.lstrip("/")
            if self.laser_mount is None and not any(tree.reaches(b, laser_frame) for b in ("base_link", "base_footprint")):
                # No base of the usual names reaches the laser through /tf_static: add the
                # fixed transforms of /tf (some bags publish the mount there).
                tree = tree.merged(self._fixed_tf_tree(reader))
            given = None if self.base_frame is None else self.base_frame.lstrip("/")
            if not self.odometry:
                linked = [b for b in ("base_link", "base_footprint") if tree.reaches(b, laser_frame)]
                base = given or (linked[0] if linked else tree.root(laser_frame))
            elif from_tf:
                base = given or self._tf_base_frame(reader, odom_conns, tree, laser_frame)
            else:
                # The odometry gives the pose of its child frame: that is the base frame.
                first_odom = self._first(reader, odom_conns)
                child = first_odom[0].child_frame_id.lstrip("/") if first_odom else ""
                if given is not None and child and given != child:
                    raise ConfigError(
                        f"--base-frame {given} differs from the child frame of {stats.odom_topic}, {child}, whose pose "
                        "the odometry gives: leave --base-frame out, or take odometry from /tf with --odom-topic /tf"
                    )
                base = given or child or "base_link"
            stats.base_frame, stats.laser_frame = base, laser_frame
            stats.odom_frame = self.odom_frame
            offset, mirrored = self._mount(tree, base, laser_frame)
            stats.laser_offset = (float(offset[0]), float(offset[1]), float(offset[2]))
            stats.upside_down = mirrored
            imu_rotation = self._imu_rotation(reader, imu_conns, tree, base)
            if not self.odometry:
                yield from self._stream_without_odometry(reader, scan_conns, imu_conns, imu_rotation, offset, mirrored)
                return
            yield from self._stream(reader, scan_conns, odom_conns, from_tf, base, offset, mirrored, imu_conns, imu_rotation)
        if stats.n_scans == 0:
            odom = self._odom_span
            span = "no odometry readings" if odom is None else f"odometry stamped {odom[0]:.3f}..{odom[1]:.3f} s"
            raise DataFormatError(
                f"no laser scans with odometry found ({stats.skipped_before_odometry} scans before and "
                f"{stats.skipped_after_odometry} after the odometry; scans stamped {self._scan_span[0]:.3f}.."
                f"{self._scan_span[1]:.3f} s, {span}): are the scans and the odometry stamped on the same clock?",
                path=str(self.path),
            )

    def _mount(self, tree: TransformTree, base: str, laser_frame: str) -> tuple[NDArray[np.float64], bool]:
        if self.laser_mount is not None:
            self.stats.mount_source = "user"
            return np.array(self.laser_mount), self.upside_down
        m = tree.lookup(base, laser_frame)
        if m is None:
            self.stats.mount_source = "none (laser at the base frame's origin)"
            return np.zeros(3), self.upside_down
        self.stats.mount_source = "tf_static" if base != laser_frame else "same frame"
        if base != laser_frame and self._static is not None and self._static.lookup(base, laser_frame) is None:
            self.stats.mount_source = "tf"
        offset, down = planar(m)
        return offset, down or self.upside_down

    def _scan_ranges(self, msg: Any) -> NDArray[np.float64]:
        """The message's ranges, invalid readings made no-returns and counted
        (:func:`crlam.io.rosbag_scans.scan_ranges`)."""
        return scan_ranges(msg, self.echo, self.stats, str(self.path))

    def _imu_rotation(self, reader: Any, imu_conns: Sequence[Any], tree: TransformTree, base: str) -> NDArray[np.float64]:
        """The rotation from the IMU's frame to the base frame (identity when the fixed
        transforms do not link them)."""
        first = self._first(reader, imu_conns) if imu_conns else []
        if not first:
            return np.eye(3)
        m = tree.lookup(base, first[0].header.frame_id.lstrip("/") or base)
        return np.eye(3) if m is None else np.asarray(m[:3, :3])

    def _imu_reading(self, msg: Any, rotation: NDArray[np.float64], recv: float) -> ImuReading:
        w = msg.angular_velocity
        yaw_rate = float((rotation @ np.array([float(w.x), float(w.y), float(w.z)]))[2])
        self.stats.records["IMU"] = self.stats.records.get("IMU", 0) + 1
        return ImuReading(
            yaw_rate=yaw_rate, timestamp=_stamp(msg.header) or recv, host=self.stats.imu_topic, logger_timestamp=recv
        )

    def _scan_record(
        self, conn: Any, msg: Any, recv: float, line: int, offset: NDArray[np.float64], mirrored: bool
    ) -> LaserScan | None:
        """A scan message as a LaserScan record without odometry (``odom``, ``pose`` NaN); None
        for a scan stamped at or before the previous one (skipped and counted). A header that
        breaks the rules of :mod:`crlam.io.message_checks` is refused."""
        check_scan_header(msg, len(msg.ranges), self._place(conn, line))
        t = _stamp(msg.header) or recv
        last = self._last_scan_t
        if last is not None and t <= last:
            if t == last:
                self.stats.skipped_stamp_repeated += 1
            else:
                self.stats.skipped_stamp_backwards += 1
            return None
        self._last_scan_t = t
        lo, hi = self._scan_span
        self._scan_span = (t, t) if line == 1 else (min(lo, t), max(hi, t))
        ranges = self._scan_ranges(msg)
        amin, inc = float(msg.angle_min), float(msg.angle_increment)
        if mirrored:
            amin, inc = -amin, -inc
        if inc < 0:
            amin, inc = amin + inc * (len(ranges) - 1), -inc
            ranges = ranges[::-1].copy()
        return LaserScan(
            ranges=ranges,
            angle_min=_wrap(amin),
            angle_increment=inc,
            max_range=float(msg.range_max),
            pose=np.full(3, np.nan),
            odom=np.full(3, np.nan),
            laser_offset=offset.copy(),
            timestamp=t,
            host=self.stats.scan_topic,
            logger_timestamp=recv,
            line=line,
            kind=conn.msgtype.rsplit("/", 1)[-1],
        )

    def _stream_without_odometry(
        self,
        reader: Any,
        scan_conns: Sequence[Any],
        imu_conns: Sequence[Any],
        imu_rotation: NDArray[np.float64],
        offset: NDArray[np.float64],
        mirrored: bool,
    ) -> Iterator[LogRecord]:
        """Every scan at once, with no odometry (``odometry=False``), and the IMU readings."""
        st = self.stats
        scan_ids = {c.id for c in scan_conns}
        n_scan_msgs = n_other = 0
        for conn, bag_t, raw in reader.messages(connections=[*scan_conns, *imu_conns]):
            recv = bag_t * 1e-9
            if conn.id in scan_ids:
                n_scan_msgs += 1
                msg = self._decode(reader, conn, raw, n_scan_msgs)
                scan = self._scan_record(conn, msg, recv, n_scan_msgs, offset, mirrored)
                if scan is not None:
                    st.records[scan.kind] = st.records.get(scan.kind, 0) + 1
                    yield scan
            else:
                n_other += 1
                msg = self._decode(reader, conn, raw, n_other)
                yield self._imu_reading(msg, imu_rotation, recv)
        if st.n_scans == 0:
            raise self._error(f"scan topic {st.scan_topic} holds no messages", reader.connections)

    def _stream(
        self,
        reader: Any,
        scan_conns: Sequence[Any],
        odom_conns: Sequence[Any],
        from_tf: bool,
        base: str,
        offset: NDArray[np.float64],
        mirrored: bool,
        imu_conns: Sequence[Any] = (),
        imu_rotation: NDArray[np.float64] | None = None,
    ) -> Iterator[LogRecord]:
        st = self.stats
        scan_ids = {c.id for c in scan_conns}
        imu_ids = {c.id for c in imu_conns}
        hist_t: deque[float] = deque(maxlen=_ODOM_HISTORY)
        hist_p: deque[NDArray[np.float64]] = deque(maxlen=_ODOM_HISTORY)
        pending: deque[LaserScan] = deque()
        n_scan_msgs = 0
        tol = self.odom_tolerance

        def resolve(scan: LaserScan) -> bool:
            """Fill the scan's odometry from the history; False when it must be skipped."""
            t = scan.timestamp
            ts = list(hist_t)
            k = bisect_left(ts, t)
            if k < len(ts) and ts[k] == t:
                pose = hist_p[k]
            elif k == 0:
                if ts[0] - t > tol:
                    st.skipped_before_odometry += 1
                    return False
                pose = hist_p[0]
            elif k == len(ts):
                pose = hist_p[-1]
            else:
                t0, t1 = ts[k - 1], ts[k]
                p0, p1 = hist_p[k - 1], hist_p[k]
                a = (t - t0) / (t1 - t0) if t1 > t0 else 0.0
                pose = np.array(
                    [p0[0] + a * (p1[0] - p0[0]), p0[1] + a * (p1[1] - p0[1]), _wrap(p0[2] + a * _wrap(p1[2] - p0[2]))]
                )
            scan.odom = np.array(pose, dtype=np.float64)
            scan.pose = np.asarray(compose(scan.odom, offset), dtype=np.float64)
            return True

        def flush(final: bool, now: float = math.inf) -> Iterator[LaserScan]:
            """Yield the pending scans that can be resolved. Without ``final``, a scan waits for
            the odometry after it for at most ``_MAX_WAIT`` s of bag time (``now``), so that a bag
            whose odometry stops (or runs on another clock) holds few scans in memory."""
            while pending:
                scan = pending[0]
                waited = now - scan.logger_timestamp > _MAX_WAIT
                if not hist_t:
                    if not (final or waited):
                        return
                    st.skipped_before_odometry += 1
                    pending.popleft()
                    continue
                if scan.timestamp > hist_t[-1]:
                    if not (final or waited):
                        return
                    if scan.timestamp - hist_t[-1] > tol:
                        st.skipped_after_odometry += 1
                        pending.popleft()
                        continue
                pending.popleft()
                if resolve(scan):
                    st.records[scan.kind] = st.records.get(scan.kind, 0) + 1
                    yield scan

        def add_odom(t: float, pose: NDArray[np.float64], tv: float, rv: float, recv: float) -> OdometryReading | None:
            if hist_t and t <= hist_t[-1]:
                # Out-of-order odometry: insert in place (rare; keeps the history sorted). A
                # reading that repeats a held stamp is skipped and counted.
                ts = list(hist_t)
                k = bisect_left(ts, t)
                if k < len(ts) and ts[k] == t:
                    st.skipped_odom_repeated += 1
                    return None
                if len(hist_t) == hist_t.maxlen:  # a full bounded deque refuses insert()
                    hist_t.popleft()
                    hist_p.popleft()
                    k = max(k - 1, 0)
                hist_t.insert(k, t)
                hist_p.insert(k, pose)
            else:
                hist_t.append(t)
                hist_p.append(pose)
            st.records["ODOM"] = st.records.get("ODOM", 0) + 1
            span = self._odom_span
            self._odom_span = (t, t) if span is None else (min(span[0], t), max(span[1], t))
            return OdometryReading(pose=pose, tv=tv, rv=rv, timestamp=t, host=st.odom_topic, logger_timestamp=recv)

        n_other: dict[str, int] = {}
        for conn, bag_t, raw in reader.messages(connections=[*scan_conns, *odom_conns, *imu_conns]):
            recv = bag_t * 1e-9
            if conn.id in scan_ids:
                n_scan_msgs += 1
                msg = self._decode(reader, conn, raw, n_scan_msgs)
                scan = self._scan_record(conn, msg, recv, n_scan_msgs, offset, mirrored)
                if scan is not None:
                    pending.append(scan)
                yield from flush(final=False, now=recv)
                continue
            index = n_other[conn.topic] = n_other.get(conn.topic, 0) + 1
            msg = self._decode(reader, conn, raw, index)
            place = self._place(conn, index)
            if conn.id in imu_ids:
                yield self._imu_reading(msg, np.eye(3) if imu_rotation is None else imu_rotation, recv)
                continue
            if from_tf:
                for tr in msg.transforms:
                    if tr.header.frame_id.lstrip("/") != self.odom_frame or tr.child_frame_id.lstrip("/") != base:
                        continue
                    m = transform_matrix(tr.transform, place, tr.child_frame_id)
                    pose, _ = planar(m)
                    if (reading := add_odom(_stamp(tr.header) or recv, pose, 0.0, 0.0, recv)) is not None:
                        yield reading
            else:
                p = msg.pose.pose
                x, y, _ = check_translation(p.position, place, "pose.pose.position")
                pose = np.array([x, y, _yaw_of(p.orientation, place, "pose.pose.orientation")])
                tw = msg.twist.twist
                tv, rv = float(tw.linear.x), float(tw.angular.z)
                if not (math.isfinite(tv) and math.isfinite(rv)):
                    raise place.error(f"twist ({tv}, {rv}) is not finite", "twist.twist")
                if (reading := add_odom(_stamp(msg.header) or recv, pose, tv, rv, recv)) is not None:
                    yield reading
                if not st.odom_frame or st.odom_frame == self.odom_frame:
                    st.odom_frame = msg.header.frame_id.lstrip("/") or self.odom_frame
            yield from flush(final=False, now=recv)
        yield from flush(final=True)


def read_bag(path: str | os.PathLike[str], **options: Any) -> Iterator[LogRecord]:
    """Stream the records of a ROS bag (see :class:`RosbagReader` for the options)."""
    return iter(RosbagReader(path, **options))
