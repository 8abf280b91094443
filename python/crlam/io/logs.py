"""One entry point for every recorded input: CARMEN logs and ROS bags.

:func:`open_log` chooses the reader by path: a folder holding ``metadata.yaml`` (a ROS 2 bag), a
``.bag`` (ROS 1) or a ``.mcap`` file is read by :class:`~crlam.io.rosbag.RosbagReader`, anything
else by :class:`~crlam.io.carmen.CarmenReader`. Both readers yield the same records
(:class:`~crlam.io.carmen_types.LaserScan` and :class:`~crlam.io.carmen_types.OdometryReading`)
and fill a ``stats`` attribute (a :class:`~crlam.io.carmen_types.CarmenStats`).
"""

from __future__ import annotations

import os
from collections.abc import Iterator, Sequence
from pathlib import Path
from typing import Any, Literal

from crlam.errors import ConfigError, CrlamError
from crlam.io.carmen import CarmenReader, open_binary
from crlam.io.carmen_types import LaserScan, LogRecord
from crlam.io.rosbag import RosbagReader, is_bag

__all__ = ["BAG_OPTIONS", "LogReader", "count_scans", "input_description", "open_log", "read_records", "read_scans_any"]

#: The keyword options only a bag takes (see :class:`~crlam.io.rosbag.RosbagReader`).
BAG_OPTIONS = (
    "scan_topic",
    "odom_topic",
    "base_frame",
    "odom_frame",
    "laser_mount",
    "upside_down",
    "odom_tolerance",
    "echo",
    "odometry",
    "imu",
    "imu_topic",
)

LogReader = CarmenReader | RosbagReader


def open_log(
    path: str | os.PathLike[str],
    *,
    on_error: Literal["raise", "skip"] = "raise",
    scan_topic: str | None = None,
    odom_topic: str | None = None,
    base_frame: str | None = None,
    laser_mount: Sequence[float] | None = None,
    upside_down: bool = False,
    **bag_options: Any,
) -> LogReader:
    """A reader for ``path``: a ROS bag (folder with ``metadata.yaml``, ``.bag``, ``.mcap``) or a
    CARMEN log (plain, ``.gz`` or ``.bz2``).

    The bag options (``scan_topic``, ``odom_topic``, ``base_frame``, ``laser_mount``,
    ``upside_down`` and the other keywords of :class:`~crlam.io.rosbag.RosbagReader`) are only
    for bags: giving one for a CARMEN log raises :class:`~crlam.errors.ConfigError`. ``on_error``
    is the CARMEN reader's malformed-line policy (bags have no lines to skip).
    """
    p = Path(path)
    if not p.exists():
        raise FileNotFoundError(f"log not found: {p}")
    unknown = set(bag_options) - set(BAG_OPTIONS)
    if unknown:
        raise TypeError(f"unknown option(s) {', '.join(sorted(unknown))}")
    if is_bag(p):
        return RosbagReader(
            p,
            scan_topic=scan_topic,
            odom_topic=odom_topic,
            base_frame=base_frame,
            laser_mount=laser_mount,
            upside_down=upside_down,
            **bag_options,
        )
    if p.is_dir():
        raise FileNotFoundError(f"{p} is a folder without metadata.yaml: neither a ROS 2 bag nor a CARMEN log")
    given = {
        "scan_topic": scan_topic,
        "odom_topic": odom_topic,
        "base_frame": base_frame,
        "laser_mount": laser_mount,
        "upside_down": upside_down or None,
        **bag_options,
    }
    used = sorted(k for k, v in given.items() if v is not None)
    if used:
        raise ConfigError(f"{', '.join(used)}: options for ROS bags, but {p.name} is read as a CARMEN log")
    return CarmenReader(p, on_error=on_error)


def read_records(path: str | os.PathLike[str], **options: Any) -> Iterator[LogRecord]:
    """Stream the records (scans and odometry) of a CARMEN log or a ROS bag (see :func:`open_log`)."""
    return iter(open_log(path, **options))


def read_scans_any(path: str | os.PathLike[str], **options: Any) -> Iterator[LaserScan]:
    """Stream only the laser scans of a CARMEN log or a ROS bag (see :func:`open_log`)."""
    for rec in open_log(path, **options):
        if isinstance(rec, LaserScan):
            yield rec


#: The CARMEN messages the reader yields as laser scans (RAWLASER* only on request, so not counted).
_CARMEN_SCAN_LINES = (b"FLASER ", b"RLASER ", b"ROBOTLASER1 ", b"ROBOTLASER2 ")


def count_scans(
    path: str | os.PathLike[str], max_scans: int | None = None, *, bag_options: dict[str, Any] | None = None
) -> int | None:
    """The number of laser scans in ``path``, for a progress bar's total (and its ETA), at most
    ``max_scans``: a CARMEN log's scan lines, counted in one pass over the (decompressed) bytes
    without parsing them; a ROS bag's messages on the scan topic that ``bag_options`` (as for
    :func:`open_log`) pick, from the bag's index. None for anything that cannot be read (the
    reader reports that). Malformed lines and messages that a run skips are counted, so it is an
    upper bound."""
    p = Path(path)
    if max_scans is not None and max_scans <= 0:
        return 0
    if is_bag(p):
        try:
            reader = open_log(p, **(bag_options or {}))
            n = reader.scan_count() if isinstance(reader, RosbagReader) else None
        except CrlamError:  # a total is optional: the run itself reports the bag's problem
            return None
        return n if n is None or max_scans is None else min(n, max_scans)
    try:
        if not p.is_file():
            return None
        n = 0
        with open_binary(p) as fh:
            for line in fh:
                if line.startswith(_CARMEN_SCAN_LINES):
                    n += 1
                    if max_scans is not None and n >= max_scans:
                        break
        return n
    except (OSError, EOFError, ValueError):
        return None


def input_description(reader: LogReader) -> dict[str, Any]:
    """What a finished reader read, for a run's ``config.toml``: the format and, for a bag, the
    topics, frames and laser mount used."""
    if isinstance(reader, RosbagReader):
        return {"format": "rosbag", **reader.stats.describe()}
    return {"format": "carmen"}
