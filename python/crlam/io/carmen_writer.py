"""CARMEN log writer.

Every record is written so that :class:`crlam.io.carmen.CarmenReader` reads it back:

* a :class:`LaserScan` whose geometry is the implicit FLASER layout (see
  :func:`flaser_geometry`), whose ``max_range`` is the writer's ``flaser_max_range`` and whose
  ``laser_offset`` is a pure forward offset is written as ``FLASER``; a change of that offset is
  announced first with a ``PARAM robot_frontlaser_offset`` line, which the reader applies to the
  scans that follow. Any other scan (e.g. a simulated 1079-beam 270-deg LIDAR, or a rear laser)
  is written as ``ROBOTLASER1`` so that its start angle, resolution and maximum range survive.
  ``kind`` is therefore not preserved; the format follows the geometry.
* ``ROBOTLASER1`` has a single robot pose and no odometry field: by default
  (``robotlaser_pose="strict"``) the writer refuses a scan whose ``odom`` differs from its
  ``pose`` at the written precision, rather than silently dropping the odometry. Choose
  ``"pose"`` or ``"odom"`` to say which one goes into the robot pose.
* NaN, infinite and non-positive ranges are written as ``max_range`` (a no-return), exactly what
  the reader would turn them into. Non-finite poses or timestamps are refused.

Number formatting is fixed, so the same records always give the same bytes (``.gz`` output has a
zero mtime and no file name in its header; ``.bz2`` is deterministic by construction):

==========================================  ==========  =====================
quantity                                    format      round-trip error
==========================================  ==========  =====================
ranges, x, y, max range, offsets, tv, accel ``%.4f``    <= 5e-5 m
theta, rv                                   ``%.6f``    <= 5e-7 rad
ROBOTLASER1 start angle, fov, resolution    ``%.9f``    <= 5e-10 rad per beam
timestamps (ipc and logger)                 ``%.6f``    <= 5e-7 s
==========================================  ==========  =====================

The ROBOTLASER1 geometry gets more digits than headings because the resolution is multiplied by
the beam index: at ``%.6f`` the last beam of a 1079-beam scan could be off by 5e-4 rad.
"""

from __future__ import annotations

import bz2
import gzip
import math
import os
from collections.abc import Iterable
from pathlib import Path
from types import TracebackType
from typing import TYPE_CHECKING, BinaryIO, Literal

import numpy as np

from crlam.errors import DataFormatError
from crlam.io.carmen_types import (
    DEFAULT_FLASER_MAX_RANGE,
    CarmenRecord,
    LaserScan,
    OdometryReading,
    flaser_geometry,
)
from crlam.pose import compose

if TYPE_CHECKING:  # annotations only: typing.Self needs Python 3.11
    from typing_extensions import Self

__all__ = ["CarmenWriter", "write_carmen"]

RobotlaserPose = Literal["strict", "pose", "odom"]


def _m(v: float) -> str:
    return f"{v:.4f}"


def _rad(v: float) -> str:
    return f"{v:.6f}"


def _t(v: float) -> str:
    return f"{v:.6f}"


def _pose(p: np.ndarray) -> str:
    return f"{p[0]:.4f} {p[1]:.4f} {p[2]:.6f}"


class CarmenWriter:
    """Write CARMEN records to ``path`` (plain, or gzip / bzip2 if it ends in ``.gz`` / ``.bz2``).

    Use it as a context manager, or call :meth:`close`.

    Parameters
    ----------
    path : str or PathLike
        Output file, overwritten.
    header : str, optional
        Free text written first, every line prefixed with ``"# "``.
    flaser_fov : float
        Field of view (rad) that makes a scan eligible for ``FLASER``; must match the reader's.
    flaser_max_range : float
        Maximum range (m) that makes a scan eligible for ``FLASER``; must match the reader's.
    robotlaser_pose : {"strict", "pose", "odom"}
        Which field becomes the ROBOTLASER1 robot pose (see the module docstring).
    """

    def __init__(
        self,
        path: str | os.PathLike[str],
        *,
        header: str | None = None,
        flaser_fov: float = math.pi,
        flaser_max_range: float = DEFAULT_FLASER_MAX_RANGE,
        robotlaser_pose: RobotlaserPose = "strict",
    ) -> None:
        if robotlaser_pose not in ("strict", "pose", "odom"):
            raise ValueError(f"robotlaser_pose must be strict/pose/odom, got {robotlaser_pose!r}")
        self.path = Path(path)
        self.flaser_fov = float(flaser_fov)
        self.flaser_max_range = float(flaser_max_range)
        self.robotlaser_pose: RobotlaserPose = robotlaser_pose
        self.n_written = 0
        # The reader starts every file with a zero front-laser offset.
        self._front = _m(0.0)
        raw = open(self.path, "wb")  # noqa: SIM115 - closed in close()
        self._raw = raw
        self._fh: BinaryIO
        name = self.path.name.lower()
        if name.endswith(".gz"):
            # No name and a zero mtime in the header keep the output byte-for-byte repeatable.
            gz = gzip.GzipFile(filename="", mode="wb", fileobj=raw, mtime=0)
            self._fh = gz  # type: ignore[assignment]
        elif name.endswith(".bz2"):
            self._fh = bz2.BZ2File(raw, "wb")  # type: ignore[assignment]
        else:
            self._fh = raw
        self._closed = False
        if header is not None:
            for text in header.splitlines() or [""]:
                self._emit(f"# {text}".rstrip())

    def __enter__(self) -> Self:
        return self

    def __exit__(
        self,
        exc_type: type[BaseException] | None,
        exc: BaseException | None,
        tb: TracebackType | None,
    ) -> None:
        self.close()

    def close(self) -> None:
        """Flush and close the file (idempotent)."""
        if self._closed:
            return
        self._closed = True
        if self._fh is not self._raw:
            self._fh.close()
        self._raw.close()

    def _emit(self, line: str) -> None:
        if self._closed:
            raise ValueError(f"CarmenWriter for {self.path} is closed")
        self._fh.write(line.encode("utf-8") + b"\n")

    def _error(self, message: str, field: str) -> DataFormatError:
        return DataFormatError(f"cannot write record {self.n_written + 1}: {message}", path=str(self.path), field=field)

    def _check_finite(self, name: str, value: float | np.ndarray) -> None:
        if not np.all(np.isfinite(value)):
            raise self._error(f"non-finite {name} {value}", name)

    def _check_host(self, host: str) -> None:
        if not host or any(c.isspace() for c in host):
            raise self._error(f"host must be a non-empty word, got {host!r}", "host")

    def write(self, record: CarmenRecord) -> None:
        """Write a :class:`LaserScan` or an :class:`OdometryReading`."""
        if isinstance(record, LaserScan):
            self.write_scan(record)
        elif isinstance(record, OdometryReading):
            self.write_odom(record)
        else:
            raise TypeError(f"not a CARMEN record: {type(record).__name__}")

    def write_param(self, name: str, value: str | float) -> None:
        """Write ``PARAM name value nohost 0``; a laser offset also updates the writer's state."""
        text = repr(float(value)) if isinstance(value, float) else str(value)
        for label, word in (("param_name", name), ("param_value", text)):
            if not word or any(c.isspace() for c in word):
                raise self._error(f"{label} must be a non-empty word, got {word!r}", label)
        if name == "robot_frontlaser_offset":
            try:
                d = float(text)
            except ValueError:
                raise self._error(f"laser offset must be a number, got {text!r}", "param_value") from None
            self._check_finite("param_value", d)
            self._front = text = _m(d)
        self._emit(f"PARAM {name} {text} nohost 0")

    def _is_flaser(self, scan: LaserScan) -> bool:
        amin, step = flaser_geometry(scan.n_beams, self.flaser_fov)
        off = scan.laser_offset
        return (
            abs(scan.angle_min - amin) <= 1e-9
            and abs(scan.angle_increment - step) * max(scan.n_beams, 1) <= 1e-9
            and abs(scan.max_range - self.flaser_max_range) <= 1e-9
            # Only a forward offset fits PARAM robot_frontlaser_offset; the rest must vanish
            # at the written precision.
            and _m(abs(off[1])) == _m(0.0)
            and _rad(abs(off[2])) == _rad(0.0)
        )

    def write_scan(self, scan: LaserScan) -> None:
        """Write one scan as ``FLASER`` or ``ROBOTLASER1`` (see the module docstring)."""
        if scan.n_beams == 0:
            raise self._error("a scan needs at least one beam", "n_beams")
        for name, value in (
            ("pose", scan.pose),
            ("odom", scan.odom),
            ("laser_offset", scan.laser_offset),
            ("timestamp", scan.timestamp),
            ("logger_timestamp", scan.logger_timestamp),
            ("angle_min", scan.angle_min),
            ("angle_increment", scan.angle_increment),
        ):
            self._check_finite(name, value)
        if not (math.isfinite(scan.max_range) and scan.max_range > 0):
            raise self._error(f"max_range must be positive, got {scan.max_range}", "max_range")
        self._check_host(scan.host)
        r = np.array(scan.ranges, dtype=np.float64)
        r[~np.isfinite(r) | (r <= 0.0)] = scan.max_range
        ranges = " ".join(map(_m, r.tolist()))
        stamps = f"{_t(scan.timestamp)} {scan.host} {_t(scan.logger_timestamp)}"
        if self._is_flaser(scan):
            offset = _m(float(scan.laser_offset[0]))
            if offset != self._front:
                self.write_param("robot_frontlaser_offset", offset)
            self._emit(f"FLASER {scan.n_beams} {ranges} {_pose(scan.pose)} {_pose(scan.odom)} {stamps}")
        else:
            if self.robotlaser_pose == "strict" and _pose(scan.pose) != _pose(scan.odom):
                raise self._error(
                    "ROBOTLASER1 has no odometry field and odom differs from pose; pass "
                    "robotlaser_pose='pose' or 'odom' to choose which one to keep",
                    "odom",
                )
            robot = scan.odom if self.robotlaser_pose == "odom" else scan.pose
            laser = compose(robot, scan.laser_offset)
            fov = scan.angle_increment * (scan.n_beams - 1)
            geometry = f"{scan.angle_min:.9f} {fov:.9f} {scan.angle_increment:.9f} {_m(scan.max_range)} {_m(0.0)} 0"
            self._emit(
                f"ROBOTLASER1 0 {geometry} {scan.n_beams} {ranges} 0 {_pose(laser)} "
                f"{_pose(robot)} {_m(0.0)} {_rad(0.0)} {_m(0.0)} {_m(0.0)} {_m(0.0)} "
                f"{stamps}"
            )
        self.n_written += 1

    def write_odom(self, odom: OdometryReading) -> None:
        """Write one ``ODOM`` line."""
        for name, value in (
            ("pose", odom.pose),
            ("tv", odom.tv),
            ("rv", odom.rv),
            ("accel", odom.accel),
            ("timestamp", odom.timestamp),
            ("logger_timestamp", odom.logger_timestamp),
        ):
            self._check_finite(name, value)
        self._check_host(odom.host)
        self._emit(
            f"ODOM {_pose(odom.pose)} {_m(odom.tv)} {_rad(odom.rv)} {_m(odom.accel)} "
            f"{_t(odom.timestamp)} {odom.host} {_t(odom.logger_timestamp)}"
        )
        self.n_written += 1


def write_carmen(
    path: str | os.PathLike[str],
    records: Iterable[CarmenRecord],
    *,
    header: str | None = None,
    flaser_fov: float = math.pi,
    flaser_max_range: float = DEFAULT_FLASER_MAX_RANGE,
    robotlaser_pose: RobotlaserPose = "strict",
) -> int:
    """Write ``records`` in order to a CARMEN log (see :class:`CarmenWriter`).

    Returns
    -------
    int
        Number of records written (PARAM lines not counted).
    """
    with CarmenWriter(
        path, header=header, flaser_fov=flaser_fov, flaser_max_range=flaser_max_range, robotlaser_pose=robotlaser_pose
    ) as writer:
        for rec in records:
            writer.write(rec)
        return writer.n_written
