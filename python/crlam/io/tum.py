"""TUM RGB-D trajectory files (the format ``evo`` reads with ``evo_ape tum ...``).

One pose per line: ``timestamp x y z qx qy qz qw`` (seconds, metres, unit quaternion with the
scalar last). crlam trajectories are planar, so they are written with ``z = 0`` and a rotation
about the z axis (``qx = qy = 0``, ``qz = sin(theta / 2)``, ``qw = cos(theta / 2)``), and read
back by taking the yaw of the quaternion; a rotation tilted out of the plane is an error.
Lines starting with ``#`` and blank lines are ignored. Poses keep the file order.
"""

from __future__ import annotations

import math
import os
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from numpy.typing import ArrayLike, NDArray

from crlam.errors import DataFormatError
from crlam.io.lines import text_lines
from crlam.pose import wrap_angle

__all__ = ["Trajectory", "read_tum", "write_tum"]

FloatArray = NDArray[np.float64]

_FIELDS = ("timestamp", "x", "y", "z", "qx", "qy", "qz", "qw")


@dataclass(eq=False)
class Trajectory:
    """A timed planar trajectory.

    Attributes
    ----------
    timestamps : ndarray, shape (n,), float64
        Seconds, in file order (not necessarily sorted).
    poses : ndarray, shape (n, 3), float64
        ``(x, y, theta)`` in metres and radians, theta in ``(-pi, pi]``.
    """

    timestamps: FloatArray
    poses: FloatArray

    def __post_init__(self) -> None:
        self.timestamps = np.asarray(self.timestamps, dtype=np.float64).reshape(-1)
        self.poses = np.asarray(self.poses, dtype=np.float64)
        if self.poses.shape != (self.timestamps.shape[0], 3):
            raise DataFormatError(f"poses must have shape ({self.timestamps.shape[0]}, 3), got {self.poses.shape}", field="poses")

    def __len__(self) -> int:
        return int(self.timestamps.shape[0])


def write_tum(
    path: str | os.PathLike[str],
    timestamps: ArrayLike,
    poses: ArrayLike,
    *,
    header: str | None = None,
) -> None:
    """Write a planar trajectory as a TUM file.

    Parameters
    ----------
    path : str or PathLike
        Output file, overwritten.
    timestamps : array_like, shape (n,)
        Seconds; written with ``%.9f``.
    poses : array_like, shape (n, 3)
        ``(x, y, theta)`` in metres and radians; x, y and the quaternion use ``%.9f``, so
        positions round-trip to 5e-10 m and headings to about 1e-9 rad.
    header : str, optional
        Comment text written first, every line prefixed with ``"# "``.
    """
    t = np.asarray(timestamps, dtype=np.float64).reshape(-1)
    p = np.asarray(poses, dtype=np.float64)
    if p.shape != (t.shape[0], 3):
        raise DataFormatError(f"poses must have shape ({t.shape[0]}, 3), got {p.shape}", path=str(path), field="poses")
    for name, arr in (("timestamps", t), ("poses", p)):
        if not np.all(np.isfinite(arr)):
            raise DataFormatError("non-finite values", path=str(path), field=name)
    half = 0.5 * p[:, 2]
    lines = [] if header is None else [f"# {h}".rstrip() for h in header.splitlines()]
    lines += [
        f"{ti:.9f} {x:.9f} {y:.9f} 0.000000000 0.000000000 0.000000000 {qz:.9f} {qw:.9f}"
        for ti, x, y, qz, qw in zip(t.tolist(), p[:, 0].tolist(), p[:, 1].tolist(), np.sin(half).tolist(), np.cos(half).tolist())
    ]
    Path(path).write_text("".join(line + "\n" for line in lines), encoding="utf-8")


def read_tum(path: str | os.PathLike[str], *, max_tilt: float = 1e-3) -> Trajectory:
    """Read a TUM trajectory file as a planar :class:`Trajectory`.

    Parameters
    ----------
    path : str or PathLike
        TUM file (``timestamp x y z qx qy qz qw`` per line).
    max_tilt : float
        Largest angle (rad) between the rotated z axis and the world z axis accepted as planar.

    Returns
    -------
    Trajectory
        ``z`` is dropped; ``theta`` is the yaw of the (normalised) quaternion.

    Raises
    ------
    DataFormatError
        On a line with the wrong number of fields, a non-numeric or non-finite value, a
        quaternion far from unit norm (field ``quaternion``) or tilted by more than
        ``max_tilt`` (field ``quaternion``); also if the file holds no pose.
    """
    name = str(path)
    stamps: list[float] = []
    rows: list[tuple[float, float, float]] = []
    with open(path, "rb") as fh:
        for number, text in text_lines(fh, name):
            tokens = text.split()
            if not tokens or tokens[0].startswith("#"):
                continue
            if len(tokens) != 8:
                missing = _FIELDS[len(tokens)] if len(tokens) < 8 else "n_fields"
                raise DataFormatError(f"expected 8 fields, found {len(tokens)}", path=name, line=number, field=missing)
            vals = []
            for tok, fname in zip(tokens, _FIELDS):
                try:
                    v = float(tok)
                except ValueError:
                    raise DataFormatError(f"not a number: {tok[:32]!r}", path=name, line=number, field=fname) from None
                if not math.isfinite(v):
                    raise DataFormatError(f"non-finite value {tok!r}", path=name, line=number, field=fname)
                vals.append(v)
            ts, x, y, _z, qx, qy, qz, qw = vals
            norm = math.sqrt(qx * qx + qy * qy + qz * qz + qw * qw)
            if abs(norm - 1.0) > 1e-3:
                raise DataFormatError(f"quaternion norm {norm:.6g} is not 1", path=name, line=number, field="quaternion")
            qx, qy, qz, qw = qx / norm, qy / norm, qz / norm, qw / norm
            # R[2,2] = 1 - 2(qx^2 + qy^2) is the cosine of the tilt of the rotated z axis.
            cos_tilt = min(1.0, max(-1.0, 1.0 - 2.0 * (qx * qx + qy * qy)))
            if math.acos(cos_tilt) > max_tilt:
                raise DataFormatError(
                    f"rotation is not planar (tilt {math.degrees(math.acos(cos_tilt)):.4g} deg)",
                    path=name,
                    line=number,
                    field="quaternion",
                )
            yaw = math.atan2(2.0 * (qw * qz + qx * qy), 1.0 - 2.0 * (qy * qy + qz * qz))
            stamps.append(ts)
            rows.append((x, y, yaw))
    if not rows:
        raise DataFormatError("no poses in TUM file", path=name)
    poses = np.array(rows, dtype=np.float64)
    poses[:, 2] = wrap_angle(poses[:, 2])
    return Trajectory(timestamps=np.array(stamps, dtype=np.float64), poses=poses)
