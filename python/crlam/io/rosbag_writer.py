"""ROS 2 bag output (MCAP storage) with standard message types, written with ``rosbags``' writer.

Used by ``crlam convert`` (a CARMEN log to a bag, :mod:`crlam.io.convert`) and by ``crlam slam
--mcap`` (a run as ``run.mcap``). :class:`McapBagWriter` writes a ROS 2 bag folder
(``metadata.yaml`` + one ``.mcap`` file), or a single ``.mcap`` file when the path ends in
``.mcap`` (Foxglove opens either; ``ros2 bag play`` takes the folder, and a ``.mcap`` file on
ROS 2 Iron and later).

Message fields are float32 where the ROS message says so: ``sensor_msgs/msg/LaserScan`` stores
its angles, ``range_max`` and ranges as float32, ``nav_msgs/msg/OccupancyGrid`` its resolution.
Poses, transforms and stamps are float64 and integer nanoseconds.
"""

from __future__ import annotations

import math
import os
import shutil
import tempfile
from fractions import Fraction
from pathlib import Path
from types import TracebackType
from typing import TYPE_CHECKING, Any

import numpy as np
from numpy.typing import ArrayLike

from crlam.errors import ConfigError

if TYPE_CHECKING:
    from typing_extensions import Self

__all__ = [
    "LASER_SCAN",
    "OCCUPANCY_GRID",
    "ODOMETRY",
    "PATH",
    "POSE_ARRAY",
    "TF_MESSAGE",
    "McapBagWriter",
    "RosMessageBuilder",
    "yaw_quaternion",
]

LASER_SCAN = "sensor_msgs/msg/LaserScan"
ODOMETRY = "nav_msgs/msg/Odometry"
TF_MESSAGE = "tf2_msgs/msg/TFMessage"
OCCUPANCY_GRID = "nav_msgs/msg/OccupancyGrid"
PATH = "nav_msgs/msg/Path"
POSE_ARRAY = "geometry_msgs/msg/PoseArray"


def _reader_yaw(z: float, w: float) -> float:
    # The formula of crlam.io.rosbag._yaw_of for a quaternion (0, 0, z, w).
    return math.atan2(2.0 * (w * z), 1.0 - 2.0 * (z * z))


def yaw_quaternion(yaw: float) -> tuple[float, float, float, float]:
    """The quaternion ``(x, y, z, w)`` of a rotation by ``yaw`` about z.

    ``(0, 0, sin(yaw/2), cos(yaw/2))``, with z and w moved by a few units in the last place when
    that makes the yaw read back by :mod:`crlam.io.rosbag` equal ``yaw`` bit for bit (a bag read
    back then gives the odometry that was written; for a small share of angles no such
    neighbour exists and the yaw read back is within an ulp or two).
    """
    z, w = math.sin(0.5 * yaw), math.cos(0.5 * yaw)
    if _reader_yaw(z, w) == yaw:
        return (0.0, 0.0, z, w)
    zs = [z]
    ws = [w]
    for direction in (math.inf, -math.inf):
        a, b = z, w
        for _ in range(6):
            a, b = math.nextafter(a, direction), math.nextafter(b, direction)
            zs.append(a)
            ws.append(b)
    for zz in zs:
        for ww in ws:
            if _reader_yaw(zz, ww) == yaw:
                return (0.0, 0.0, zz, ww)
    return (0.0, 0.0, z, w)


class RosMessageBuilder:
    """Builds ROS 2 messages (rosbags' classes of ``types``) from crlam's poses and scans:
    what :class:`McapBagWriter` writes and :mod:`crlam.live_view` serves."""

    def __init__(self, types: dict[str, Any]) -> None:
        self.types = types

    def header(self, t: float, frame: str) -> Any:
        sec, nsec = ros_time(t)
        return self.types["std_msgs/msg/Header"](
            stamp=self.types["builtin_interfaces/msg/Time"](sec=sec, nanosec=nsec), frame_id=frame
        )

    def pose(self, p: ArrayLike) -> Any:
        x, y, th = (float(v) for v in np.asarray(p, dtype=np.float64))
        T = self.types
        q = yaw_quaternion(th)
        return T["geometry_msgs/msg/Pose"](
            position=T["geometry_msgs/msg/Point"](x=x, y=y, z=0.0),
            orientation=T["geometry_msgs/msg/Quaternion"](x=q[0], y=q[1], z=q[2], w=q[3]),
        )

    def transform(self, t: float, parent: str, child: str, p: ArrayLike) -> Any:
        x, y, th = (float(v) for v in np.asarray(p, dtype=np.float64))
        T = self.types
        q = yaw_quaternion(th)
        return T["geometry_msgs/msg/TransformStamped"](
            header=self.header(t, parent),
            child_frame_id=child,
            transform=T["geometry_msgs/msg/Transform"](
                translation=T["geometry_msgs/msg/Vector3"](x=x, y=y, z=0.0),
                rotation=T["geometry_msgs/msg/Quaternion"](x=q[0], y=q[1], z=q[2], w=q[3]),
            ),
        )

    def tf(self, transforms: list[Any]) -> Any:
        return self.types[TF_MESSAGE](transforms=transforms)

    def occupancy_grid(
        self, t: float, frame: str, shape: tuple[int, int], origin: ArrayLike, resolution: float, data: ArrayLike
    ) -> Any:
        """An OccupancyGrid of ``data`` (int8, row-major ``shape`` = (rows, columns)) whose cell
        (0, 0) has its corner at ``origin`` (x, y; m), ``resolution`` m per cell."""
        T = self.types
        sec, nsec = ros_time(max(t, 0.0))
        ny, nx = shape
        ox, oy = (float(v) for v in np.asarray(origin, dtype=np.float64)[:2])
        info = T["nav_msgs/msg/MapMetaData"](
            map_load_time=T["builtin_interfaces/msg/Time"](sec=sec, nanosec=nsec),
            resolution=float(resolution),
            width=nx,
            height=ny,
            origin=self.pose((ox, oy, 0.0)),
        )
        return T[OCCUPANCY_GRID](header=self.header(t, frame), info=info, data=np.asarray(data, dtype=np.int8))

    def laser_scan(
        self, t: float, frame: str, ranges: ArrayLike, angle_min: float, angle_increment: float, max_range: float
    ) -> Any:
        """A LaserScan; readings at or beyond ``max_range`` (and non-finite ones) become ``+inf``,
        the no-return of REP 117."""
        r = np.asarray(ranges, dtype=np.float64)
        r32 = np.where(np.isfinite(r) & (r > 0.0) & (r < max_range), r, np.inf).astype(np.float32)
        n = len(r32)
        return self.types[LASER_SCAN](
            header=self.header(t, frame),
            angle_min=float(angle_min),
            angle_max=float(angle_min + angle_increment * max(n - 1, 0)),
            angle_increment=float(angle_increment),
            time_increment=0.0,
            scan_time=0.0,
            range_min=0.0,
            range_max=float(max_range),
            ranges=r32,
            intensities=np.zeros(0, dtype=np.float32),
        )

    def odometry(self, t: float, frame: str, child: str, pose: ArrayLike, tv: float = 0.0, rv: float = 0.0) -> Any:
        T = self.types
        vec = T["geometry_msgs/msg/Vector3"]
        return T[ODOMETRY](
            header=self.header(t, frame),
            child_frame_id=child,
            pose=T["geometry_msgs/msg/PoseWithCovariance"](pose=self.pose(pose), covariance=np.zeros(36)),
            twist=T["geometry_msgs/msg/TwistWithCovariance"](
                twist=T["geometry_msgs/msg/Twist"](linear=vec(x=float(tv), y=0.0, z=0.0), angular=vec(x=0.0, y=0.0, z=float(rv))),
                covariance=np.zeros(36),
            ),
        )


class McapBagWriter(RosMessageBuilder):
    """A ROS 2 bag with MCAP storage; connections are added on a topic's first message.

    Parameters
    ----------
    path : str or PathLike
        A folder to create (it must not exist), or a file ending in ``.mcap`` (overwritten).

    Use it as a context manager. :meth:`write` takes the topic, the message type, the receive
    time in integer nanoseconds and the message built from :attr:`types`.
    """

    def __init__(self, path: str | os.PathLike[str]) -> None:
        try:
            from rosbags.rosbag2 import StoragePlugin, Writer
            from rosbags.typesys import Stores, get_typestore
        except ImportError as exc:  # pragma: no cover - rosbags is a dependency
            raise ConfigError("writing ROS bags needs the 'rosbags' package (pip install rosbags)") from exc
        self.path = Path(path)
        self.typestore = get_typestore(Stores.ROS2_HUMBLE)
        super().__init__(self.typestore.types)
        self._single_file = self.path.suffix.lower() == ".mcap"
        self._tmp: Path | None = None
        if self._single_file:
            self.path.parent.mkdir(parents=True, exist_ok=True)
            self._tmp = Path(tempfile.mkdtemp(prefix=".crlam-mcap-", dir=self.path.parent))
            folder = self._tmp / self.path.stem
        else:
            if self.path.exists():
                raise ConfigError(f"{self.path} exists already: a bag is written to a new folder")
            folder = self.path
        writer = Writer(folder, version=9, storage_plugin=StoragePlugin.MCAP)
        writer.open()
        self._writer: Any = writer
        self._folder = folder
        self._conns: dict[str, Any] = {}
        self.counts: dict[str, int] = {}

    def __enter__(self) -> Self:
        return self

    def __exit__(
        self,
        exc_type: type[BaseException] | None,
        exc: BaseException | None,
        tb: TracebackType | None,
    ) -> None:
        self.close(keep=exc_type is None)

    def close(self, keep: bool = True) -> None:
        """Finish the bag (with ``keep=False``, after an error, a single-file output is dropped)."""
        if self._writer is None:
            return
        self._writer.close()
        self._writer = None
        if self._tmp is not None:
            if keep:
                files = sorted(self._folder.glob("*.mcap"))
                if len(files) != 1:  # pragma: no cover - rosbags writes one file without splitting
                    raise ConfigError(f"expected one .mcap file in {self._folder}, found {len(files)}")
                os.replace(files[0], self.path)
            shutil.rmtree(self._tmp, ignore_errors=True)

    def write(self, topic: str, msgtype: str, t_ns: int, msg: Any, *, latched: bool = False) -> None:
        """Write ``msg`` on ``topic``; ``latched`` topics are offered as transient-local (like
        ``/tf_static`` and ``/map``), so a late subscriber of ``ros2 bag play`` still gets them."""
        if self._writer is None:
            raise ConfigError(f"bag writer for {self.path} is closed")
        conn = self._conns.get(topic)
        if conn is None:
            qos = [_latched_qos()] if latched else []
            conn = self._writer.add_connection(topic, msgtype, typestore=self.typestore, offered_qos_profiles=qos)
            self._conns[topic] = conn
        self._writer.write(conn, int(t_ns), self.typestore.serialize_cdr(msg, msgtype))
        self.counts[topic] = self.counts.get(topic, 0) + 1


def ros_time(t: float) -> tuple[int, int]:
    """``(sec, nanosec)`` of a time in seconds, rounded to the nanosecond (must be >= 0).

    The bag reader divides the nanoseconds back exactly, so a time with up to 9 decimals (a
    CARMEN stamp has 6) reads back as the same float."""
    if not (math.isfinite(t) and t >= 0.0):
        raise ConfigError(f"a ROS time must be finite and >= 0, got {t}")
    ns = round(Fraction(t) * 1_000_000_000)  # exact: t * 1e9 in floating point is off by up to 128 ns at epoch times
    sec = int(math.floor(t))
    nsec = ns - sec * 1_000_000_000
    if nsec < 0:
        sec, nsec = sec - 1, nsec + 1_000_000_000
    elif nsec >= 1_000_000_000:
        sec, nsec = sec + 1, nsec - 1_000_000_000
    return sec, int(nsec)


def _latched_qos() -> Any:
    from rosbags.interfaces import Qos, QosDurability, QosHistory, QosLiveliness, QosReliability, QosTime

    zero = QosTime(sec=0, nsec=0)
    return Qos(
        history=QosHistory.KEEP_LAST,
        depth=1,
        reliability=QosReliability.RELIABLE,
        durability=QosDurability.TRANSIENT_LOCAL,
        deadline=zero,
        lifespan=zero,
        liveliness=QosLiveliness.AUTOMATIC,
        liveliness_lease_duration=zero,
        avoid_ros_namespace_conventions=False,
    )
