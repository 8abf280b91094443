"""ROS bag reader (streaming): ROS 1 ``.bag``, ROS 2 bag folders (sqlite3 or MCAP storage) and
plain ``.mcap`` files, read with the pure-Python ``rosbags`` package.

It yields the records the CARMEN reader yields (:class:`~crlam.io.carmen_types.LaserScan` and
:class:`~crlam.io.carmen_types.OdometryReading`), so ``crlam map``, ``crlam slam`` and the
experiments take a bag wherever they take a CARMEN log.

What is read
------------
Scans
    ``sensor_msgs/msg/LaserScan`` (or ``MultiEchoLaserScan``: the first echo of every beam) of the
    scan topic: the only laser topic of the bag unless ``scan_topic`` names one. The stamp is the
    message header's (the bag's receive time when the header stamp is zero). Beam ``i`` has the
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
    odometry reading takes that reading; scans further out are skipped and counted.
Laser mount
    ``laser_offset`` (the laser pose in the base frame, x, y, yaw) comes from ``/tf_static``: the
    chain of static transforms from the base frame (``base_frame``, by default the odometry's
    ``child_frame_id``) to the scan's ``frame_id``, composed in 3D and projected to the plane. A
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
different clocks gives no scan: the error says so, with both stamp spans. ``/tf_static`` is read first in a
separate pass (a few messages).
"""

from __future__ import annotations

import math
import os
from bisect import bisect_left
from collections import deque
from collections.abc import Iterator, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from crlam.errors import ConfigError, CrlamError, DataFormatError
from crlam.io.carmen_types import CarmenRecord, CarmenStats, LaserScan, OdometryReading
from crlam.pose import compose

__all__ = [
    "LASER_TYPES",
    "ODOMETRY_TYPE",
    "TF_TYPE",
    "BagStats",
    "RosbagReader",
    "is_bag",
    "read_bag",
]

LASER_TYPES = ("sensor_msgs/msg/LaserScan", "sensor_msgs/msg/MultiEchoLaserScan")
ODOMETRY_TYPE = "nav_msgs/msg/Odometry"
TF_TYPE = "tf2_msgs/msg/TFMessage"

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


@dataclass
class BagStats(CarmenStats):
    """What a :class:`RosbagReader` saw (the CARMEN counters plus the bag's own).

    Attributes
    ----------
    scan_topic, odom_topic : str
        The topics read (``odom_topic`` is ``"/tf"`` when odometry came from TF).
    odom_frame, base_frame, laser_frame : str
        Frames: odometry's parent frame, the robot's base frame, the scan's ``frame_id``.
    laser_offset : tuple of float
        The laser mount used (x, y, yaw in the base frame).
    upside_down : bool
        True when the beam bearings were mirrored.
    mount_source : str
        ``"tf_static"``, ``"user"`` or ``"none (laser at the base frame's origin)"``.
    n_inf_ranges, n_nan_ranges, n_above_max_ranges, n_below_min_ranges : int
        Readings made no-returns, per cause (``n_nonpositive_ranges`` counts 0 and negative ones).
    skipped_before_odometry, skipped_after_odometry : int
        Scans skipped because no odometry reading was close enough before/after them.
    """

    scan_topic: str = ""
    odom_topic: str = ""
    odom_frame: str = ""
    base_frame: str = ""
    laser_frame: str = ""
    laser_offset: tuple[float, float, float] = (0.0, 0.0, 0.0)
    upside_down: bool = False
    mount_source: str = ""
    n_inf_ranges: int = 0
    n_nan_ranges: int = 0
    n_above_max_ranges: int = 0
    n_below_min_ranges: int = 0
    skipped_before_odometry: int = 0
    skipped_after_odometry: int = 0

    def describe(self) -> dict[str, Any]:
        """The topics, frames and mount used, for a run's ``config.toml``."""
        return {
            "scan_topic": self.scan_topic,
            "odom_topic": self.odom_topic,
            "odom_frame": self.odom_frame,
            "base_frame": self.base_frame,
            "laser_frame": self.laser_frame,
            "laser_mount": [float(v) for v in self.laser_offset],
            "upside_down": self.upside_down,
            "mount_source": self.mount_source,
        }


def _stamp(header: Any) -> float:
    # Integer nanoseconds divided exactly (Python's int / int is correctly rounded): the float
    # nearest the stamp, so a stamp written from a float with up to 9 decimals reads back equal.
    return (int(header.stamp.sec) * 1_000_000_000 + int(header.stamp.nanosec)) / 1_000_000_000


def _quat_matrix(q: Any) -> NDArray[np.float64]:
    x, y, z, w = float(q.x), float(q.y), float(q.z), float(q.w)
    n = math.sqrt(x * x + y * y + z * z + w * w) or 1.0
    x, y, z, w = x / n, y / n, z / n, w / n
    return np.array(
        [
            [1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
            [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
            [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)],
        ]
    )


def _transform(t: Any) -> NDArray[np.float64]:
    """A ``geometry_msgs/Transform`` or ``Pose`` as a 4x4 matrix."""
    m = np.eye(4)
    rot = getattr(t, "rotation", None) or t.orientation
    tr = getattr(t, "translation", None) or t.position
    m[:3, :3] = _quat_matrix(rot)
    m[:3, 3] = [float(tr.x), float(tr.y), float(tr.z)]
    return m


def _planar(m: NDArray[np.float64]) -> tuple[NDArray[np.float64], bool]:
    """``(x, y, yaw)`` of a 3D transform and whether its z axis points down (upside down)."""
    yaw = math.atan2(m[1, 0], m[0, 0])
    return np.array([m[0, 3], m[1, 3], yaw]), bool(m[2, 2] < 0.0)


def _yaw_of(q: Any) -> float:
    x, y, z, w = float(q.x), float(q.y), float(q.z), float(q.w)
    return math.atan2(2.0 * (w * z + x * y), 1.0 - 2.0 * (y * y + z * z))


def _wrap(a: float) -> float:
    return (a + math.pi) % (2.0 * math.pi) - math.pi


class _StaticTree:
    """The static transforms as a forest of parent links; resolves the transform between two frames."""

    def __init__(self) -> None:
        self.parent: dict[str, tuple[str, NDArray[np.float64]]] = {}

    def add(self, parent: str, child: str, m: NDArray[np.float64]) -> None:
        self.parent[child.lstrip("/")] = (parent.lstrip("/"), m)

    def _to_root(self, frame: str) -> tuple[list[str], dict[str, NDArray[np.float64]]]:
        chain = [frame]
        poses = {frame: np.eye(4)}  # frame's pose in each ancestor, filled below
        acc = np.eye(4)
        seen = {frame}
        f = frame
        while f in self.parent:
            p, m = self.parent[f]
            if p in seen:
                break
            acc = m @ acc
            poses[p] = acc.copy()
            chain.append(p)
            seen.add(p)
            f = p
        return chain, poses

    def lookup(self, base: str, child: str) -> NDArray[np.float64] | None:
        """The pose of ``child`` in ``base`` (4x4), or None when no static chain links them."""
        base, child = base.lstrip("/"), child.lstrip("/")
        if base == child:
            return np.eye(4)
        chain_b, poses_b = self._to_root(base)
        chain_c, poses_c = self._to_root(child)
        common = next((f for f in chain_c if f in poses_b), None)
        if common is None:
            return None
        # T_common_base^-1 @ T_common_child
        return np.asarray(np.linalg.inv(poses_b[common]) @ poses_c[common])

    def reaches(self, base: str, child: str) -> bool:
        return self.lookup(base, child) is not None


def _topics_text(connections: Sequence[Any]) -> str:
    seen: dict[str, str] = {}
    for c in connections:
        seen.setdefault(c.topic, c.msgtype)
    return ", ".join(f"{t} ({ty})" for t, ty in sorted(seen.items())) or "(none)"


def _library_errors() -> tuple[type[BaseException], ...]:
    """What reading a damaged bag raises in the bag library (and the standard library under it)."""
    import struct

    # MemoryError: a damaged length field makes the library ask for an absurd buffer at once.
    errors: list[type[BaseException]] = [KeyError, IndexError, ValueError, EOFError, OSError, struct.error, AssertionError]
    # TypeError: the MCAP parser on a truncated record; AttributeError: a ROS 1 bag whose damaged
    # message definition gives a known type name other fields.
    errors += [MemoryError, TypeError, ArithmeticError, AttributeError]
    try:
        from rosbags.highlevel import AnyReaderError
        from rosbags.rosbag1 import ReaderError as Ros1Error
        from rosbags.rosbag2 import ReaderError as Ros2Error

        errors += [AnyReaderError, Ros1Error, Ros2Error]
    except ImportError:  # pragma: no cover - rosbags is a dependency
        pass
    return tuple(errors)


class RosbagReader:
    """Streaming ROS bag reader; iterate it to get :data:`~crlam.io.carmen_types.CarmenRecord` s.

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
    ) -> None:
        self.path = Path(path)
        if not self.path.exists():
            raise FileNotFoundError(f"ROS bag not found: {self.path}")
        if laser_mount is not None and len(laser_mount) != 3:
            raise ConfigError(f"laser_mount needs 3 values (x, y, yaw), got {list(laser_mount)}")
        if not (math.isfinite(odom_tolerance) and odom_tolerance >= 0):
            raise ConfigError(f"odom_tolerance must be >= 0, got {odom_tolerance}")
        self.scan_topic = scan_topic
        self.odom_topic = odom_topic
        self.base_frame = base_frame
        self.odom_frame = odom_frame
        self.laser_mount = None if laser_mount is None else tuple(float(v) for v in laser_mount)
        self.upside_down = bool(upside_down)
        self.odom_tolerance = float(odom_tolerance)
        self.stats = BagStats()
        self._scan_span = (math.nan, math.nan)
        self._odom_span: tuple[float, float] | None = None

    # -- opening and detection ---------------------------------------------------------------

    def _open(self) -> Any:
        try:
            from rosbags.highlevel import AnyReader
            from rosbags.typesys import Stores, get_typestore
        except ImportError as exc:  # pragma: no cover - rosbags is a dependency
            raise ConfigError("reading ROS bags needs the 'rosbags' package (pip install rosbags)") from exc
        return AnyReader([self.path], default_typestore=get_typestore(Stores.ROS2_HUMBLE))

    def _error(self, message: str, connections: Sequence[Any]) -> DataFormatError:
        return DataFormatError(f"{message}; the bag's topics: {_topics_text(connections)}", path=str(self.path))

    def _pick_scan(self, conns: Sequence[Any]) -> list[Any]:
        if self.scan_topic is not None:
            sel = [c for c in conns if c.topic == self.scan_topic]
            if not sel:
                raise self._error(f"scan topic {self.scan_topic!r} not in the bag", conns)
            if sel[0].msgtype not in LASER_TYPES:
                raise self._error(f"scan topic {self.scan_topic!r} is a {sel[0].msgtype}, not a LaserScan", conns)
            return sel
        topics = sorted({c.topic for c in conns if c.msgtype in LASER_TYPES})
        if not topics:
            raise self._error("no sensor_msgs/msg/LaserScan topic in the bag", conns)
        if len(topics) > 1:
            raise self._error(f"several laser topics ({', '.join(topics)}): choose one with --scan-topic", conns)
        return [c for c in conns if c.topic == topics[0]]

    def _pick_odom(self, conns: Sequence[Any]) -> tuple[list[Any], bool]:
        """The odometry connections and whether they are TF (True) or Odometry messages."""
        tf = [c for c in conns if c.topic in ("/tf", "tf") and c.msgtype == TF_TYPE]
        if self.odom_topic is not None:
            sel = [c for c in conns if c.topic == self.odom_topic]
            if not sel:
                raise self._error(f"odometry topic {self.odom_topic!r} not in the bag", conns)
            if sel[0].msgtype == TF_TYPE:
                return sel, True
            if sel[0].msgtype != ODOMETRY_TYPE:
                raise self._error(f"odometry topic {self.odom_topic!r} is a {sel[0].msgtype}, not nav_msgs/msg/Odometry", conns)
            return sel, False
        topics = sorted({c.topic for c in conns if c.msgtype == ODOMETRY_TYPE})
        if len(topics) > 1:
            preferred = [t for t in topics if t in ("/odom", "odom")]
            if not preferred:
                raise self._error(f"several odometry topics ({', '.join(topics)}): choose one with --odom-topic", conns)
            topics = preferred[:1]
        if topics:
            return [c for c in conns if c.topic == topics[0]], False
        if tf:
            return tf, True
        raise self._error("no odometry: neither a nav_msgs/msg/Odometry topic nor /tf (give --odom-topic)", conns)

    def _static_tree(self, reader: Any) -> _StaticTree:
        tree = _StaticTree()
        conns = [c for c in reader.connections if c.topic in ("/tf_static", "tf_static") and c.msgtype == TF_TYPE]
        if conns:  # an empty list would read every message
            for conn, _, raw in reader.messages(connections=conns):
                for tr in reader.deserialize(raw, conn.msgtype).transforms:
                    tree.add(tr.header.frame_id, tr.child_frame_id, _transform(tr.transform))
        return tree

    def _first(self, reader: Any, conns: Sequence[Any], limit: int = 1) -> list[Any]:
        out = []
        for conn, _, raw in reader.messages(connections=conns):
            out.append(reader.deserialize(raw, conn.msgtype))
            if len(out) >= limit:
                break
        return out

    def _tf_base_frame(self, reader: Any, tf_conns: Sequence[Any], tree: _StaticTree, laser_frame: str) -> str:
        """The base frame when odometry comes from /tf: a child of the odometry frame, preferring
        one from which a static chain reaches the laser frame."""
        children: list[str] = []
        for msg in self._first(reader, tf_conns, limit=200):
            for tr in msg.transforms:
                child = tr.child_frame_id.lstrip("/")
                if tr.header.frame_id.lstrip("/") == self.odom_frame and child not in children:
                    children.append(child)
        if not children:
            raise self._error(
                f"no {self.odom_frame} -> base transform in /tf (give --base-frame and --odom-topic)", reader.connections
            )
        linked = [c for c in children if tree.reaches(c, laser_frame)]
        return (linked or children)[0]

    # -- iteration ---------------------------------------------------------------------------

    def __iter__(self) -> Iterator[CarmenRecord]:
        return self._records()

    def _records(self) -> Iterator[CarmenRecord]:
        """The records; what the bag library cannot read (a damaged, truncated or foreign file)
        is a :class:`DataFormatError` naming the bag."""
        try:
            yield from self._read_records()
        except CrlamError:
            raise
        except _library_errors() as exc:
            reason = " ".join(str(exc).split())[:300]
            raise DataFormatError(f"damaged or unreadable ROS bag ({type(exc).__name__}: {reason})", path=str(self.path)) from exc

    def _read_records(self) -> Iterator[CarmenRecord]:
        self.stats = stats = BagStats()
        self._scan_span, self._odom_span = (math.nan, math.nan), None
        with self._open() as reader:
            conns = reader.connections
            scan_conns = self._pick_scan(conns)
            odom_conns, from_tf = self._pick_odom(conns)
            stats.scan_topic = scan_conns[0].topic
            stats.odom_topic = odom_conns[0].topic
            tree = self._static_tree(reader)
            first_scan = self._first(reader, scan_conns)
            if not first_scan:
                raise self._error(f"scan topic {stats.scan_topic} holds no messages", conns)
            laser_frame = first_scan[0].header.frame_id.lstrip("/")
            given = None if self.base_frame is None else self.base_frame.lstrip("/")
            if from_tf:
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
            yield from self._stream(reader, scan_conns, odom_conns, from_tf, base, offset, mirrored)
        if stats.n_scans == 0:
            odom = self._odom_span
            span = "no odometry readings" if odom is None else f"odometry stamped {odom[0]:.3f}..{odom[1]:.3f} s"
            raise DataFormatError(
                f"no laser scans with odometry found ({stats.skipped_before_odometry} scans before and "
                f"{stats.skipped_after_odometry} after the odometry; scans stamped {self._scan_span[0]:.3f}.."
                f"{self._scan_span[1]:.3f} s, {span}): are the scans and the odometry stamped on the same clock?",
                path=str(self.path),
            )

    def _mount(self, tree: _StaticTree, base: str, laser_frame: str) -> tuple[NDArray[np.float64], bool]:
        if self.laser_mount is not None:
            self.stats.mount_source = "user"
            return np.array(self.laser_mount), self.upside_down
        m = tree.lookup(base, laser_frame)
        if m is None:
            self.stats.mount_source = "none (laser at the base frame's origin)"
            return np.zeros(3), self.upside_down
        self.stats.mount_source = "tf_static" if base != laser_frame else "same frame"
        offset, down = _planar(m)
        return offset, down or self.upside_down

    def _scan_ranges(self, msg: Any) -> NDArray[np.float64]:
        raw = msg.ranges
        if hasattr(raw, "__len__") and len(raw) and hasattr(raw[0], "echoes"):  # MultiEchoLaserScan
            r = np.array([e.echoes[0] if len(e.echoes) else np.nan for e in raw], dtype=np.float64)
        else:
            r = np.asarray(raw, dtype=np.float64).copy()
        st = self.stats
        rmax, rmin = float(msg.range_max), float(msg.range_min)
        nan = np.isnan(r)
        inf = np.isposinf(r)
        nonpos = ~nan & (r <= 0.0)  # includes -inf
        below = ~nan & ~nonpos & (r < rmin)
        above = ~inf & (r > rmax)
        st.n_nan_ranges += int(nan.sum())
        st.n_inf_ranges += int(inf.sum())
        st.n_nonpositive_ranges += int(nonpos.sum())
        st.n_below_min_ranges += int(below.sum())
        st.n_above_max_ranges += int(above.sum())
        st.n_nonfinite_ranges += int((nan | ~np.isfinite(r)).sum())
        r[nan | inf | nonpos | below | above] = rmax
        st.n_no_return_ranges += int(np.count_nonzero(r >= rmax))
        return r

    def _stream(
        self,
        reader: Any,
        scan_conns: Sequence[Any],
        odom_conns: Sequence[Any],
        from_tf: bool,
        base: str,
        offset: NDArray[np.float64],
        mirrored: bool,
    ) -> Iterator[CarmenRecord]:
        st = self.stats
        scan_ids = {c.id for c in scan_conns}
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

        def add_odom(t: float, pose: NDArray[np.float64], tv: float, rv: float, recv: float) -> OdometryReading:
            if hist_t and t < hist_t[-1]:
                # Out-of-order odometry: insert in place (rare; keeps the history sorted).
                ts = list(hist_t)
                k = bisect_left(ts, t)
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

        for conn, bag_t, raw in reader.messages(connections=[*scan_conns, *odom_conns]):
            recv = bag_t * 1e-9
            msg = reader.deserialize(raw, conn.msgtype)
            if conn.id in scan_ids:
                n_scan_msgs += 1
                t = _stamp(msg.header) or recv
                lo, hi = self._scan_span
                self._scan_span = (t, t) if n_scan_msgs == 1 else (min(lo, t), max(hi, t))
                ranges = self._scan_ranges(msg)
                amin, inc = float(msg.angle_min), float(msg.angle_increment)
                if mirrored:
                    amin, inc = -amin, -inc
                if inc < 0:
                    amin, inc = amin + inc * (len(ranges) - 1), -inc
                    ranges = ranges[::-1].copy()
                kind = conn.msgtype.rsplit("/", 1)[-1]
                pending.append(
                    LaserScan(
                        ranges=ranges,
                        angle_min=_wrap(amin),
                        angle_increment=inc,
                        max_range=float(msg.range_max),
                        pose=np.full(3, np.nan),
                        odom=np.full(3, np.nan),
                        laser_offset=offset.copy(),
                        timestamp=t,
                        host=st.scan_topic,
                        logger_timestamp=recv,
                        line=n_scan_msgs,
                        kind=kind,
                    )
                )
                yield from flush(final=False, now=recv)
                continue
            if from_tf:
                for tr in msg.transforms:
                    if tr.header.frame_id.lstrip("/") != self.odom_frame or tr.child_frame_id.lstrip("/") != base:
                        continue
                    m = _transform(tr.transform)
                    pose, _ = _planar(m)
                    yield add_odom(_stamp(tr.header) or recv, pose, 0.0, 0.0, recv)
            else:
                p = msg.pose.pose
                pose = np.array([float(p.position.x), float(p.position.y), _yaw_of(p.orientation)])
                tw = msg.twist.twist
                yield add_odom(_stamp(msg.header) or recv, pose, float(tw.linear.x), float(tw.angular.z), recv)
                if not st.odom_frame or st.odom_frame == self.odom_frame:
                    st.odom_frame = msg.header.frame_id.lstrip("/") or self.odom_frame
            yield from flush(final=False, now=recv)
        yield from flush(final=True)


def read_bag(path: str | os.PathLike[str], **options: Any) -> Iterator[CarmenRecord]:
    """Stream the records of a ROS bag (see :class:`RosbagReader` for the options)."""
    return iter(RosbagReader(path, **options))
