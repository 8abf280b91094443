"""CARMEN log reader (streaming); also re-exports the records and the writer.

Supported message types
-----------------------
``FLASER`` / ``RLASER``
    ``FLASER n r_1..r_n x y theta odom_x odom_y odom_theta ipc_timestamp host logger_timestamp``.
    The geometry is implicit: a field of view of ``flaser_fov`` (default pi) starting at
    ``-flaser_fov / 2``; the increment is ``fov / n`` for even ``n`` (180 beams -> 1 deg,
    360 -> 0.5 deg) and ``fov / (n - 1)`` for odd ``n`` (181 beams span -90..+90 deg inclusive,
    as a SICK in 1-deg mode does). The maximum range is not logged: ``flaser_max_range``
    (default 81 m) is used. ``pose`` is the logged ``x y theta`` field (the laser pose), ``odom``
    the ``odom_*`` field. ``laser_offset`` comes from the last ``PARAM robot_frontlaser_offset``
    (forward offset, metres) for FLASER and ``PARAM robot_rearlaser_offset`` for RLASER (the rear
    laser looks backwards: offset ``(-d, 0, pi)``).
``ROBOTLASER1`` / ``ROBOTLASER2``
    Explicit geometry (start angle, angular resolution, max range) and remissions (ignored).
    ``pose`` and ``odom`` are both the logged robot pose (the format has no separate odometry),
    ``laser_offset`` is the logged laser pose expressed in the robot frame.
``RAWLASER1..4``
    Same geometry fields, no pose. Only yielded with ``include_raw=True``, and then with
    ``pose`` and ``odom`` set to NaN; otherwise counted in ``stats.ignored``.
``ODOM``
    ``ODOM x y theta tv rv accel ipc_timestamp host logger_timestamp``.

``PARAM`` lines (other than the laser offsets), ``NEFF``, ``SYNC``, ``TRUEPOS``, ``#`` comments
and blank lines are skipped and counted; unknown message types are counted in
``stats.unknown_kinds``. Records come out in file order: CARMEN logs are not always time sorted
(Intel is not), so the reader never sorts.

Error policy
------------
A malformed line (truncated, wrong beam count, non-numeric field, non-finite pose or
timestamp) raises :class:`~crlam.errors.DataFormatError` naming the file, the 1-based line and
the field (``range[17]`` is the 18th range, indices are 0-based). With ``on_error="skip"`` the
line is skipped and counted instead. A NaN, infinite or non-positive *range* is not an error:
it becomes a no-return (set to the scan's ``max_range``) and is counted. A file without a
single record raises ``DataFormatError`` ("no records").
"""

from __future__ import annotations

import bz2
import gzip
import math
import os
from collections.abc import Iterator
from pathlib import Path
from typing import BinaryIO, Literal

import numpy as np

from crlam.errors import DataFormatError
from crlam.io.carmen_types import (
    DEFAULT_FLASER_MAX_RANGE,
    CarmenLog,
    CarmenRecord,
    CarmenStats,
    FloatArray,
    LaserScan,
    OdometryReading,
    flaser_geometry,
)
from crlam.io.carmen_writer import CarmenWriter, write_carmen
from crlam.io.lines import text_lines
from crlam.pose import between

__all__ = [
    "DEFAULT_FLASER_MAX_RANGE",
    "CarmenLog",
    "CarmenReader",
    "CarmenRecord",
    "CarmenStats",
    "CarmenWriter",
    "LaserScan",
    "OdometryReading",
    "flaser_geometry",
    "load_log",
    "open_binary",
    "read_carmen",
    "read_scans",
    "write_carmen",
]

OnError = Literal["raise", "skip"]

MAX_EXAMPLES = 5
# Bounded so that a garbage file with millions of distinct first tokens cannot grow the stats.
_MAX_DISTINCT_KEYS = 200

_FLASER_TAIL = ("x", "y", "theta", "odom_x", "odom_y", "odom_theta")
_STAMP_TAIL = ("ipc_timestamp", "host", "logger_timestamp")
_RL_HEAD = ("laser_type", "start_angle", "fov", "angular_res", "max_range", "accuracy", "remission_mode", "n_beams")
_RL_POSES = (
    "laser_x",
    "laser_y",
    "laser_theta",
    "robot_x",
    "robot_y",
    "robot_theta",
    "tv",
    "rv",
    "fwd_safety",
    "side_safety",
    "turn_axis",
)
_ODOM_FIELDS = ("x", "y", "theta", "tv", "rv", "accel")
_IGNORED_KINDS = frozenset({"NEFF", "SYNC", "TRUEPOS", "NMEA-GGA", "NMEA-RMC", "GPS"})
# A line layout for error messages: tuples of field names and ``(prefix, count)`` blocks.
_Segments = tuple[tuple[str, ...] | tuple[str, int], ...]


def _bump(counts: dict[str, int], key: str) -> None:
    if key not in counts and len(counts) >= _MAX_DISTINCT_KEYS:
        key = "<other>"
    counts[key] = counts.get(key, 0) + 1


def open_binary(path: str | os.PathLike[str]) -> BinaryIO:
    """Open ``path`` for binary reading, decompressing gzip or bzip2 transparently.

    The compression is sniffed from the magic bytes (``1f 8b`` gzip, ``BZh`` bzip2), so a
    misnamed file still opens; plain files are read as they are.
    """
    with open(path, "rb") as probe:
        magic = probe.read(3)
    if magic[:2] == b"\x1f\x8b":
        return gzip.open(path, "rb")  # type: ignore[return-value]
    if magic == b"BZh":
        return bz2.open(path, "rb")  # type: ignore[return-value]
    return open(path, "rb")


def _short(tok: str) -> str:
    return repr(tok if len(tok) <= 32 else tok[:29] + "...")


def _is_float(tok: str) -> bool:
    try:
        float(tok)
    except ValueError:
        return False
    return True


def _name_at(segments: _Segments, index: int) -> str:
    """Name of the field at token ``index`` of a layout made of name tuples and
    ``(prefix, count)`` repeated blocks (only used to word error messages)."""
    for seg in segments:
        if len(seg) == 2 and isinstance(seg[1], int):
            prefix, count = seg
            if index < count:
                return f"{prefix}[{index}]"
            index -= count
        else:
            if index < len(seg):
                return str(seg[index])
            index -= len(seg)
    return "end of line"


class _Line:
    """Parsing context of one line: knows where it is, so every error names file/line/field."""

    __slots__ = ("number", "path", "tokens")

    def __init__(self, path: str, number: int, tokens: list[str]) -> None:
        self.path = path
        self.number = number
        self.tokens = tokens

    def error(self, message: str, field_name: str | None) -> DataFormatError:
        return DataFormatError(message, path=self.path, line=self.number, field=field_name)

    def num(self, i: int, name: str, *, finite: bool = True) -> float:
        tok = self.tokens[i]
        try:
            v = float(tok)
        except ValueError:
            raise self.error(f"not a number: {_short(tok)}", name) from None
        if finite and not math.isfinite(v):
            raise self.error(f"non-finite value {_short(tok)}", name)
        return v

    def integer(self, i: int, name: str, minimum: int = 0) -> int:
        tok = self.tokens[i]
        try:
            v = int(tok)
        except ValueError:
            raise self.error(f"not an integer: {_short(tok)}", name) from None
        if v < minimum:
            raise self.error(f"must be >= {minimum}, got {v}", name)
        return v

    def nums(self, start: int, names: tuple[str, ...]) -> list[float]:
        return [self.num(start + k, nm) for k, nm in enumerate(names)]

    def check_count(self, segments: _Segments, expected: int, count_field: str) -> None:
        """Raise unless the line has exactly ``expected`` tokens.

        A line that still ends like a complete record (``... stamp host stamp``) has a wrong
        count field; otherwise it was cut off and the first missing field is named.
        """
        got = len(self.tokens)
        if got == expected:
            return
        t = self.tokens
        complete = got >= 3 and _is_float(t[-1]) and _is_float(t[-3]) and not _is_float(t[-2])
        if got > expected or complete:
            raise self.error(f"line has {got} fields but {count_field} implies {expected} (wrong beam/field count)", count_field)
        missing = _name_at(segments, got)
        raise self.error(f"truncated line: {got} of {expected} fields, {missing} is missing", missing)


class CarmenReader:
    """Streaming CARMEN log reader; iterate it to get :data:`CarmenRecord` s in file order.

    Parameters
    ----------
    path : str or PathLike
        Plain, ``.gz`` or ``.bz2`` log (compression sniffed from the magic bytes).
    on_error : {"raise", "skip"}
        What to do with a malformed line (see the module docstring).
    flaser_fov : float
        Implicit field of view of FLASER/RLASER scans (rad).
    flaser_max_range : float
        Maximum range given to FLASER/RLASER scans (m); their format does not log it.
    include_raw : bool
        Yield RAWLASER1..4 scans (with NaN poses) instead of ignoring them.

    Notes
    -----
    Every iteration re-opens the file, resets :attr:`stats` and fills it while records are
    produced; it is complete once the iteration is exhausted. Run one iteration at a time.
    Only the current line is held in memory.
    """

    def __init__(
        self,
        path: str | os.PathLike[str],
        *,
        on_error: OnError = "raise",
        flaser_fov: float = math.pi,
        flaser_max_range: float = DEFAULT_FLASER_MAX_RANGE,
        include_raw: bool = False,
    ) -> None:
        if on_error not in ("raise", "skip"):
            raise ValueError(f"on_error must be 'raise' or 'skip', got {on_error!r}")
        if not (math.isfinite(flaser_fov) and flaser_fov > 0):
            raise ValueError(f"flaser_fov must be a positive angle, got {flaser_fov}")
        if not (math.isfinite(flaser_max_range) and flaser_max_range > 0):
            raise ValueError(f"flaser_max_range must be positive, got {flaser_max_range}")
        self.path = Path(path)
        if not self.path.is_file():
            if self.path.exists():
                raise DataFormatError("not a regular file (a folder, a device or a pipe)", path=str(self.path))
            raise FileNotFoundError(f"CARMEN log not found: {self.path}")
        self.on_error: OnError = on_error
        self.flaser_fov = float(flaser_fov)
        self.flaser_max_range = float(flaser_max_range)
        self.include_raw = include_raw
        self.stats = CarmenStats()
        self._front = np.zeros(3)
        self._rear = np.array([0.0, 0.0, math.pi])

    @property
    def lines_read(self) -> int:
        """Lines consumed so far by the current iteration."""
        return self.stats.n_lines

    def __iter__(self) -> Iterator[CarmenRecord]:
        return self._records()

    def _records(self) -> Iterator[CarmenRecord]:
        self.stats = stats = CarmenStats()
        self._front = np.zeros(3)
        self._rear = np.array([0.0, 0.0, math.pi])
        path = str(self.path)
        with open_binary(self.path) as fh:
            for number, text in text_lines(fh, path):
                stats.n_lines = number
                tokens = text.split()
                if not tokens:
                    _bump(stats.ignored, "blank")
                    continue
                if tokens[0].startswith("#"):
                    _bump(stats.ignored, "comment")
                    continue
                try:
                    rec = self._parse(_Line(path, number, tokens))
                except DataFormatError as exc:
                    if self.on_error == "raise":
                        raise
                    stats.skipped_malformed += 1
                    if len(stats.malformed_examples) < MAX_EXAMPLES:
                        stats.malformed_examples.append((number, str(exc)))
                    continue
                if rec is not None:
                    _bump(stats.records, tokens[0])
                    yield rec
        if stats.n_records == 0:
            why = f" ({stats.skipped_malformed} malformed lines skipped)" if stats.skipped_malformed else ""
            raise DataFormatError(f"no records (FLASER, ROBOTLASER1, ODOM, ...) found{why}", path=path)

    def _parse(self, ln: _Line) -> CarmenRecord | None:
        kind = ln.tokens[0]
        if kind in ("FLASER", "RLASER"):
            return self._flaser(ln)
        if kind == "ODOM":
            return self._odom(ln)
        if kind in ("ROBOTLASER1", "ROBOTLASER2"):
            return self._laser_v2(ln, with_poses=True)
        if kind.startswith("RAWLASER") and kind[8:] in ("1", "2", "3", "4"):
            if self.include_raw:
                return self._laser_v2(ln, with_poses=False)
            _bump(self.stats.ignored, kind)
            return None
        if kind == "PARAM":
            self._param(ln)
            _bump(self.stats.ignored, "PARAM")
            return None
        _bump(self.stats.ignored if kind in _IGNORED_KINDS else self.stats.unknown_kinds, kind)
        return None

    def _ranges(self, ln: _Line, start: int, n: int, max_range: float) -> FloatArray:
        seg = ln.tokens[start : start + n]
        try:
            r = np.array(seg, dtype=np.float64)
        except (ValueError, TypeError, OverflowError):
            for i in range(n):
                ln.num(start + i, f"range[{i}]", finite=False)
            raise ln.error("unparsable range values", "ranges") from None
        nonfinite = ~np.isfinite(r)
        nonpositive = r <= 0.0  # NaN compares False, so the two masks are disjoint
        n_nf, n_np = int(nonfinite.sum()), int(nonpositive.sum())
        if n_nf or n_np:
            r[nonfinite | nonpositive] = max_range
            self.stats.n_nonfinite_ranges += n_nf
            self.stats.n_nonpositive_ranges += n_np
        self.stats.n_no_return_ranges += int(np.count_nonzero(r >= max_range))
        return r

    def _flaser(self, ln: _Line) -> LaserScan:
        kind = ln.tokens[0]
        if len(ln.tokens) < 2:
            raise ln.error("truncated line: n_beams is missing", "n_beams")
        n = ln.integer(1, "n_beams", minimum=1)
        segments = ((kind, "n_beams"), ("range", n), _FLASER_TAIL + _STAMP_TAIL)
        ln.check_count(segments, n + 11, "n_beams")
        ranges = self._ranges(ln, 2, n, self.flaser_max_range)
        x, y, th, ox, oy, oth, stamp = ln.nums(2 + n, _FLASER_TAIL + ("ipc_timestamp",))
        angle_min, step = flaser_geometry(n, self.flaser_fov)
        return LaserScan(
            ranges=ranges,
            angle_min=angle_min,
            angle_increment=step,
            max_range=self.flaser_max_range,
            pose=np.array([x, y, th]),
            odom=np.array([ox, oy, oth]),
            laser_offset=(self._front if kind == "FLASER" else self._rear).copy(),
            timestamp=stamp,
            host=ln.tokens[n + 9],
            logger_timestamp=ln.num(n + 10, "logger_timestamp"),
            line=ln.number,
            kind=kind,
        )

    def _laser_v2(self, ln: _Line, *, with_poses: bool) -> LaserScan:
        """ROBOTLASER1/2 (``with_poses``) and RAWLASER1..4, which share the geometry header."""
        t, kind = ln.tokens, ln.tokens[0]
        tail = (_RL_POSES if with_poses else ()) + _STAMP_TAIL
        head = (kind,) + _RL_HEAD
        if len(t) < len(head):
            ln.check_count((head,), len(head) + 1 + len(tail), "n_beams")
        ln.integer(1, "laser_type")
        start, _fov, res, max_range, _acc = ln.nums(2, _RL_HEAD[1:6])
        ln.integer(7, "remission_mode")
        n = ln.integer(8, "n_beams", minimum=1)
        if max_range <= 0:
            raise ln.error(f"must be positive, got {max_range}", "max_range")
        m_idx = 9 + n
        m = 0
        if len(t) > m_idx:
            try:
                m = ln.integer(m_idx, "n_remissions")
            except DataFormatError:
                ln.check_count((head, ("range", n), ("n_remissions",)), m_idx + 1 + len(tail), "n_beams")
                raise
        segments = (head, ("range", n), ("n_remissions",), ("remission", m), tail)
        ln.check_count(segments, m_idx + 1 + m + len(tail), "n_beams")
        ranges = self._ranges(ln, 9, n, max_range)
        for i in range(m):
            ln.num(m_idx + 1 + i, f"remission[{i}]", finite=False)
        k = m_idx + 1 + m
        if with_poses:
            laser = np.array(ln.nums(k, _RL_POSES[0:3]))
            robot = np.array(ln.nums(k + 3, _RL_POSES[3:6]))
            ln.nums(k + 6, _RL_POSES[6:8])
            for j, nm in enumerate(_RL_POSES[8:]):
                ln.num(k + 8 + j, nm, finite=False)
            k += len(_RL_POSES)
            pose, odom, offset = robot, robot.copy(), between(robot, laser)
        else:
            pose, odom, offset = np.full(3, np.nan), np.full(3, np.nan), np.zeros(3)
        return LaserScan(
            ranges=ranges,
            angle_min=start,
            angle_increment=res,
            max_range=max_range,
            pose=pose,
            odom=odom,
            laser_offset=offset,
            timestamp=ln.num(k, "ipc_timestamp"),
            host=t[k + 1],
            logger_timestamp=ln.num(k + 2, "logger_timestamp"),
            line=ln.number,
            kind=kind,
        )

    def _odom(self, ln: _Line) -> OdometryReading:
        segments = (("ODOM",), _ODOM_FIELDS + _STAMP_TAIL)
        ln.check_count(segments, 10, "n_fields")
        x, y, th, tv, rv, acc, stamp = ln.nums(1, _ODOM_FIELDS + ("ipc_timestamp",))
        return OdometryReading(
            pose=np.array([x, y, th]),
            tv=tv,
            rv=rv,
            accel=acc,
            timestamp=stamp,
            host=ln.tokens[8],
            logger_timestamp=ln.num(9, "logger_timestamp"),
            line=ln.number,
        )

    def _param(self, ln: _Line) -> None:
        t = ln.tokens
        if len(t) < 3:
            raise ln.error("PARAM needs a name and a value", "param_name" if len(t) < 2 else "param_value")
        name = t[1]
        if name in ("robot_frontlaser_offset", "robot_rearlaser_offset"):
            d = ln.num(2, name)
            if name == "robot_frontlaser_offset":
                self._front = np.array([d, 0.0, 0.0])
            else:
                self._rear = np.array([-d, 0.0, math.pi])
        if name in self.stats.params or len(self.stats.params) < _MAX_DISTINCT_KEYS:
            self.stats.params[name] = t[2]


def read_carmen(
    path: str | os.PathLike[str],
    *,
    on_error: OnError = "raise",
    flaser_fov: float = math.pi,
    flaser_max_range: float = DEFAULT_FLASER_MAX_RANGE,
    include_raw: bool = False,
) -> Iterator[CarmenRecord]:
    """Stream the records of a CARMEN log in file order (see :class:`CarmenReader`).

    Use :class:`CarmenReader` directly to get the :class:`CarmenStats`.
    """
    return iter(
        CarmenReader(path, on_error=on_error, flaser_fov=flaser_fov, flaser_max_range=flaser_max_range, include_raw=include_raw)
    )


def read_scans(
    path: str | os.PathLike[str],
    *,
    on_error: OnError = "raise",
    flaser_fov: float = math.pi,
    flaser_max_range: float = DEFAULT_FLASER_MAX_RANGE,
    include_raw: bool = False,
) -> Iterator[LaserScan]:
    """Stream only the :class:`LaserScan` records of a CARMEN log, in file order."""
    for rec in read_carmen(
        path, on_error=on_error, flaser_fov=flaser_fov, flaser_max_range=flaser_max_range, include_raw=include_raw
    ):
        if isinstance(rec, LaserScan):
            yield rec


def load_log(
    path: str | os.PathLike[str],
    *,
    on_error: OnError = "raise",
    flaser_fov: float = math.pi,
    flaser_max_range: float = DEFAULT_FLASER_MAX_RANGE,
    include_raw: bool = False,
) -> CarmenLog:
    """Read a whole CARMEN log into a :class:`CarmenLog` (scans and odometry, file order)."""
    reader = CarmenReader(
        path, on_error=on_error, flaser_fov=flaser_fov, flaser_max_range=flaser_max_range, include_raw=include_raw
    )
    scans: list[LaserScan] = []
    odometry: list[OdometryReading] = []
    for rec in reader:
        (scans if isinstance(rec, LaserScan) else odometry).append(rec)  # type: ignore[arg-type]
    return CarmenLog(scans=scans, odometry=odometry, stats=reader.stats, path=Path(path))
