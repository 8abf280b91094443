"""Ground-truth relations files of the SLAM benchmark of Kuemmerle et al. (2009).

Each line is ``t1 t2 x y z roll pitch yaw``: the reference pose of the scan stamped ``t2``
expressed in the frame of the scan stamped ``t1`` (metres, radians). The benchmark is planar,
so ``z``, ``roll`` and ``pitch`` must be (close to) zero. ``t1`` and ``t2`` are the exact
``ipc_timestamp`` of FLASER lines of the raw log, so they are kept as parsed floats and must be
matched to scan stamps by equality of the parsed values, never by nearest neighbour.
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

__all__ = ["Relations", "read_relations", "write_relations"]

FloatArray = NDArray[np.float64]

_FIELDS = ("t1", "t2", "x", "y", "z", "roll", "pitch", "yaw")


@dataclass(eq=False)
class Relations:
    """Relative-pose constraints between pairs of scan stamps.

    Attributes
    ----------
    t1, t2 : ndarray, shape (n,), float64
        Stamps (s) of the reference and the target scan.
    delta : ndarray, shape (n, 3), float64
        ``(x, y, yaw)`` of the ``t2`` pose in the ``t1`` frame (m, m, rad), as in the file.
    """

    t1: FloatArray
    t2: FloatArray
    delta: FloatArray

    def __post_init__(self) -> None:
        self.t1 = np.asarray(self.t1, dtype=np.float64).reshape(-1)
        self.t2 = np.asarray(self.t2, dtype=np.float64).reshape(-1)
        self.delta = np.asarray(self.delta, dtype=np.float64)
        n = self.t1.shape[0]
        if self.t2.shape != (n,) or self.delta.shape != (n, 3):
            raise DataFormatError(
                f"t1 {self.t1.shape}, t2 {self.t2.shape} and delta {self.delta.shape} disagree (want (n,), (n,), (n, 3))",
                field="delta",
            )

    def __len__(self) -> int:
        return int(self.t1.shape[0])


def read_relations(path: str | os.PathLike[str], *, planar_tol: float = 1e-6) -> Relations:
    """Read a ``.relations`` file.

    Parameters
    ----------
    path : str or PathLike
        The file; ``#`` comments and blank lines are ignored.
    planar_tol : float
        Largest ``|z|`` (m), ``|roll|`` and ``|pitch|`` (rad) accepted.

    Raises
    ------
    DataFormatError
        Naming the line and the field, on a wrong field count, a non-numeric or non-finite
        value or a non-planar relation; also when the file holds no relation.
    """
    name = str(path)
    rows: list[list[float]] = []
    with open(path, "rb") as fh:
        for number, text in text_lines(fh, name):
            tokens = text.split()
            if not tokens or tokens[0].startswith("#"):
                continue
            if len(tokens) != 8:
                missing = _FIELDS[len(tokens)] if len(tokens) < 8 else "n_fields"
                raise DataFormatError(f"expected 8 fields, found {len(tokens)}", path=name, line=number, field=missing)
            vals: list[float] = []
            for tok, fname in zip(tokens, _FIELDS):
                try:
                    v = float(tok)
                except ValueError:
                    raise DataFormatError(f"not a number: {tok[:32]!r}", path=name, line=number, field=fname) from None
                if not math.isfinite(v):
                    raise DataFormatError(f"non-finite value {tok!r}", path=name, line=number, field=fname)
                vals.append(v)
            for k in (4, 5, 6):
                if abs(vals[k]) > planar_tol:
                    raise DataFormatError(
                        f"non-planar relation ({_FIELDS[k]} = {vals[k]})", path=name, line=number, field=_FIELDS[k]
                    )
            rows.append(vals)
    if not rows:
        raise DataFormatError("no relations in file", path=name)
    a = np.array(rows, dtype=np.float64)
    return Relations(t1=a[:, 0], t2=a[:, 1], delta=a[:, [2, 3, 7]])


def write_relations(path: str | os.PathLike[str], t1: ArrayLike, t2: ArrayLike, delta: ArrayLike) -> None:
    """Write relations (stamps ``%.6f`` s as in the benchmark files, x y ``%.6f`` m, yaw
    ``%.6f`` rad; z, roll and pitch zero).

    Parameters
    ----------
    t1, t2 : array_like, shape (n,)
    delta : array_like, shape (n, 3)
    """
    rel = Relations(t1=np.asarray(t1), t2=np.asarray(t2), delta=np.asarray(delta))
    if not all(np.all(np.isfinite(a)) for a in (rel.t1, rel.t2, rel.delta)):
        raise DataFormatError("non-finite values", path=str(path), field="delta")
    text = "".join(
        f"{a:.6f} {b:.6f} {x:.6f} {y:.6f} 0.000000 0.000000 0.000000 {yaw:.6f}\n"
        for a, b, (x, y, yaw) in zip(rel.t1.tolist(), rel.t2.tolist(), rel.delta.tolist())
    )
    Path(path).write_text(text, encoding="utf-8")
