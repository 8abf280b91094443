"""The lidar checks of ``crlam slam`` before the filter runs: body beams and the laser mount.

:func:`check_lidar` reads the first records of the log once (up to :data:`SCANS_READ` records, keeping
up to :data:`SCANS_KEPT` with motion: the odometry moved 2 cm or turned 0.02 rad since the last one
kept) and applies

* :func:`crlam.preflight.body_mask.find_body_beams` (``SlamConfig.body_mask = "auto"``), and
* :func:`crlam.preflight.laser_mount.estimate_mount` (``laser_mount = "auto"``, the default when neither
  ``--laser-mount X Y YAW`` nor ``--upside-down`` is given).

Mount rule
----------
The estimate is relative to the bearings as the data gives them (a bag's ``/tf_static`` mount,
with its upside-down mirroring, or a CARMEN line's laser pose). When it is decided and
differs from the data (a flip, a yaw more than 10 deg away, or an offset more than 10 cm away
when the offset is observable) the estimate replaces the data's mount for the whole run, and
stderr says so; each part (flip, yaw, offset) is replaced only where it differs by more than
that tolerance (a stated offset is more precise than one fitted from the first scans). When it
cannot decide, the data's mount is kept and stderr warns that the mount is unchecked
(``laser mount UNCHECKED``). ``laser_mount = "data"`` uses the data's mount without a check. ``metrics.json``
records all of it under ``lidar``.
"""

from __future__ import annotations

import itertools
import math
import sys
from collections.abc import Iterable, Iterator
from dataclasses import dataclass, replace
from typing import Any

import numpy as np
from numpy.typing import NDArray

from crlam.io.carmen_types import LaserScan
from crlam.io.readings import ReadingStats
from crlam.preflight.body_mask import BodyMask, find_body_beams
from crlam.preflight.laser_mount import MountEstimate, estimate_mount

__all__ = ["MOUNT_MODES", "SCANS_KEPT", "SCANS_READ", "LidarSetup", "check_lidar", "check_lidar_of_log"]

MOUNT_MODES = ("auto", "data", "given")
SCANS_READ = 4000
SCANS_KEPT = 300
_YAW_TOLERANCE = math.radians(10.0)
_OFFSET_TOLERANCE = 0.10


@dataclass
class LidarSetup:
    """What the checks found and how the run's scans are corrected."""

    mount_mode: str
    body: BodyMask | None = None
    mount: MountEstimate | None = None
    data_mount: tuple[float, float, float] | None = None
    data_states_mount: bool = True
    #: The correction applied to every scan: (flip, yaw, x, y), or None for the data's mount.
    correction: tuple[bool, float, float, float] | None = None
    notes: tuple[str, ...] = ()
    #: What the run's no-return policy and body mask did (set after the run).
    readings: ReadingStats | None = None

    def correct(self, scan: LaserScan) -> LaserScan:
        """``scan`` with the corrected mount: bearings mirrored when flipped, laser offset
        replaced by the estimated one."""
        if self.correction is None:
            return scan
        flip, yaw, x, y = self.correction
        ranges, amin = scan.ranges, scan.angle_min
        if flip:
            ranges = ranges[::-1].copy()
            amin = -(scan.angle_min + scan.angle_increment * (scan.n_beams - 1))
        return replace(scan, ranges=ranges, angle_min=amin, laser_offset=np.array([x, y, yaw]))

    def corrected(self, records: Iterable[Any]) -> Iterator[Any]:
        """``records`` with every scan :meth:`correct`-ed (other records as they are)."""
        for rec in records:
            yield self.correct(rec) if isinstance(rec, LaserScan) else rec

    def body_mask_for_scans(self) -> NDArray[np.bool_] | None:
        """The body mask in the beam order of the corrected scans."""
        if self.body is None or self.body.mask is None or not self.body.mask.any():
            return None
        flip = self.correction is not None and self.correction[0]
        return self.body.mask[::-1].copy() if flip else self.body.mask

    def record(self) -> dict[str, Any]:
        """The ``lidar`` entry of metrics.json."""
        corr = self.correction
        return {
            "laser_mount": self.mount_mode,
            "data_mount": None if self.data_mount is None else list(self.data_mount),
            "data_states_mount": self.data_states_mount,
            "mount_estimate": None if self.mount is None else self.mount.record(),
            "mount_used": None
            if corr is None
            else {"upside_down_against_data": corr[0], "x": corr[2], "y": corr[3], "yaw_deg": math.degrees(corr[1])},
            "body_mask": None if self.body is None else self.body.record(),
            "readings": None if self.readings is None else self.readings.to_dict(),
            "notes": list(self.notes),
        }


def _differs(est: MountEstimate, data: tuple[float, float, float]) -> bool:
    assert est.yaw is not None
    if est.flip:
        return True
    if abs(math.remainder(est.yaw - data[2], math.tau)) > _YAW_TOLERANCE:
        return True
    return est.offset is not None and math.hypot(est.offset[0] - data[0], est.offset[1] - data[1]) > _OFFSET_TOLERANCE


def check_lidar(
    records: Any, mount_mode: str, body_mask: str, *, data_states_mount: bool = True, warn: bool = True
) -> LidarSetup:
    """Reads the first scans of ``records`` (an iterable of log records) and decides the body
    mask (``body_mask = "auto"``) and the mount (``mount_mode = "auto"``); see the module
    docstring. ``data_states_mount`` is False for a bag whose transforms give no mount. Notes go
    to stderr when ``warn``."""
    setup = LidarSetup(mount_mode=mount_mode, data_states_mount=data_states_mount)
    if mount_mode != "auto" and body_mask != "auto":
        return setup
    scans: list[LaserScan] = []
    last: NDArray[np.float64] | None = None
    for k, rec in enumerate(records):
        if k >= SCANS_READ or len(scans) >= SCANS_KEPT:
            break
        if not isinstance(rec, LaserScan):
            continue
        if not np.all(np.isfinite(rec.odom)):
            continue
        if last is not None:
            d = rec.odom - last
            if math.hypot(d[0], d[1]) < 0.02 and abs(math.remainder(d[2], math.tau)) < 0.02:
                continue
        scans.append(rec)
        last = rec.odom
    notes: list[str] = []
    if scans:
        setup.data_mount = tuple(float(v) for v in scans[0].laser_offset)  # type: ignore[assignment]
    if body_mask == "auto":
        if scans:
            setup.body = find_body_beams(
                [s.ranges for s in scans], [s.max_range for s in scans], np.array([s.odom for s in scans]), scans[0].angles
            )
        else:
            setup.body = BodyMask(None, False, "no scans with odometry")
        if setup.body.n_masked:
            notes.append(f"body mask: {setup.body.reason}; left out of every scan")
    if mount_mode == "auto":
        keep = None if setup.body is None or setup.body.mask is None else ~setup.body.mask
        n0 = scans[0].n_beams if scans else 0
        same = [s for s in scans if s.n_beams == n0]
        setup.mount = est = estimate_mount(
            [s.angles if keep is None else s.angles[keep] for s in same],
            [s.ranges if keep is None else s.ranges[keep] for s in same],
            [s.max_range for s in same],
            np.array([s.odom for s in same]).reshape(-1, 3),
        )
        data = setup.data_mount or (0.0, 0.0, 0.0)
        if est.decided and _differs(est, data):
            assert est.yaw is not None
            # Each part of the data's mount is replaced only where the estimate differs from it by
            # more than the tolerance: the estimate's offset is less precise than a stated one.
            x, y = data[0], data[1]
            if est.offset is not None and math.hypot(est.offset[0] - x, est.offset[1] - y) > _OFFSET_TOLERANCE:
                x, y = float(est.offset[0]), float(est.offset[1])
            yaw = data[2] if abs(math.remainder(est.yaw - data[2], math.tau)) <= _YAW_TOLERANCE else est.yaw
            setup.correction = (bool(est.flip), float(yaw), x, y)
            notes.append(
                f"laser mount: the scans move against the odometry under the data's mount {data}; using the "
                f"estimate: {est.reason}"
            )
        elif not est.decided:
            what = (
                "the data states no mount, so the scans are used as read" if not data_states_mount else "the data's mount is kept"
            )
            notes.append(f"laser mount UNCHECKED: {est.reason}; {what}")
    setup.notes = tuple(notes)
    if warn:
        for note in notes:
            print(f"crlam: {note}", file=sys.stderr)
    return setup


def check_lidar_of_log(
    log_path: Any, bag_options: dict[str, Any] | None, laser_mount: str, body_mask: str, *, wheel: bool = True
) -> LidarSetup:
    """:func:`check_lidar` on a log file (its own pass over the first scans). A mount given in
    ``bag_options`` (``laser_mount`` or ``upside_down``) makes the mode ``given`` (no check);
    without wheel odometry (scan-matching odometry) nothing can be checked against it."""
    from crlam.errors import ConfigError
    from crlam.io.logs import open_log

    if laser_mount not in MOUNT_MODES:
        raise ConfigError(f"laser_mount: must be one of {MOUNT_MODES} (got {laser_mount!r})")
    options = bag_options or {}
    if "laser_mount" in options or options.get("upside_down"):
        laser_mount = "given"
    if not wheel:
        setup = LidarSetup(mount_mode=laser_mount, notes=("no wheel odometry: mount and body beams not checked",))
        if laser_mount == "auto":
            print("crlam: laser mount UNCHECKED: no wheel odometry to check it against", file=sys.stderr)
        return setup
    if laser_mount != "auto" and body_mask != "auto":
        return LidarSetup(mount_mode=laser_mount)
    reader = open_log(log_path, **options)
    states = True
    if laser_mount == "auto":
        # A bag's reader knows whether its transforms gave the mount once it has started.
        records = iter(reader)
        first = next(records, None)
        source = str(getattr(getattr(reader, "stats", None), "mount_source", "data"))
        states = not source.startswith("none")
        return check_lidar(
            itertools.chain([first] if first is not None else [], records), laser_mount, body_mask, data_states_mount=states
        )
    return check_lidar(reader, laser_mount, body_mask, data_states_mount=states)
