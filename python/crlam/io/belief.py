"""Lossless archive of a confidence-rich map (CRM) belief: ``belief.npz``.

A CRM keeps, per cell, a probability mass function over ``K`` occupancy-density levels. The
archive is a compressed ``.npz`` (``np.savez_compressed``, read without pickle) holding:

==================  ================  ==============================================
key                 dtype / shape     meaning
==================  ================  ==============================================
``format``          str               ``"crlam-belief"``
``format_version``  int64, ()         :data:`FORMAT_VERSION`
``beliefs``         float32 (ny,nx,K) pmf per cell, ``[iy, ix]``, iy = 0 at min y
``levels``          float64 (K,)      density level of each pmf bin
``origin``          float64 (2,)      world (x, y) of the lower-left corner of [0, 0] (m)
``resolution``      float64 ()        cell size (m)
``metadata``        str               JSON object of str / int / float / bool values
``estimate``        float64 (3,)      optional (version 2): the run's final pose estimate
``estimate_cov``    float64 (3, 3)    optional (version 2): its covariance (m², rad²)
==================  ================  ==============================================

Version 2 added the estimate: what ``crlam slam --continue`` starts from. A version-1 archive
reads as before, without it; an archive of a later version than this crlam knows is refused
with the version found and the versions read.

:func:`save_belief_bands` writes the same file from bands of rows (the pmfs of a large map are
never all in memory: ``crlam slam`` streams them from the filter's tiles), validating each band
as it comes and removing a partial file on error. Arrays round-trip bit for bit. Both
:func:`save_belief` and :func:`load_belief` validate the content (shapes, ``K`` matches
``levels``, finite, non-negative pmfs summing to 1 within :data:`PMF_TOLERANCE`), so an invalid
archive is never written nor accepted.
"""

from __future__ import annotations

import json
import math
import os
import zipfile
import zlib
from collections.abc import Callable, Iterable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from crlam.errors import DataFormatError
from crlam.io.npz_check import check_npz
from crlam.limits import check_limit

__all__ = ["FORMAT_VERSION", "PMF_TOLERANCE", "BeliefArchive", "load_belief", "save_belief", "save_belief_bands"]

FORMAT_NAME = "crlam-belief"
FORMAT_VERSION = 2
PMF_TOLERANCE = 1e-4
"""Largest accepted ``|sum(pmf) - 1|`` per cell (float32 sums of K terms drift by ~K * 6e-8)."""

MetaValue = str | int | float


@dataclass(eq=False)
class BeliefArchive:
    """A CRM belief grid with its level grid and georeference.

    Attributes
    ----------
    beliefs : ndarray, shape (ny, nx, K), float32
        Per-cell pmf over ``levels``; converted to float32 if given otherwise.
    levels : ndarray, shape (K,), float64
        Occupancy-density value of each bin.
    origin : ndarray, shape (2,), float64
        World ``(x, y)`` (m) of the lower-left corner of cell ``[0, 0]``.
    resolution : float
        Cell size (m).
    metadata : dict[str, str | int | float]
        Free-form description (sensor model, ``n_levels``, levels mode, floor, ...).
    estimate : ndarray, shape (3,), float64, or None
        The final pose estimate (x m, y m, θ rad) of the run that built the map.
    estimate_cov : ndarray, shape (3, 3), float64, or None
        Its covariance (symmetric, positive semidefinite); present with ``estimate``.
    """

    beliefs: NDArray[np.float32]
    levels: NDArray[np.float64]
    origin: NDArray[np.float64]
    resolution: float
    metadata: dict[str, MetaValue] = field(default_factory=dict)
    estimate: NDArray[np.float64] | None = None
    estimate_cov: NDArray[np.float64] | None = None

    def __post_init__(self) -> None:
        self.beliefs = np.ascontiguousarray(self.beliefs, dtype=np.float32)
        self.levels = np.asarray(self.levels, dtype=np.float64)
        self.origin = np.asarray(self.origin, dtype=np.float64)
        self.resolution = float(self.resolution)
        self.metadata = dict(self.metadata)
        if self.estimate is not None:
            self.estimate = np.asarray(self.estimate, dtype=np.float64)
        if self.estimate_cov is not None:
            self.estimate_cov = np.asarray(self.estimate_cov, dtype=np.float64)

    @property
    def shape(self) -> tuple[int, int]:
        """Grid shape ``(ny, nx)``."""
        return int(self.beliefs.shape[0]), int(self.beliefs.shape[1])

    @property
    def n_levels(self) -> int:
        """Number of levels ``K``."""
        return int(self.levels.shape[0])

    def validate(self, path: str | os.PathLike[str] | None = None) -> None:
        """Raise :class:`DataFormatError` (naming ``path`` and the field) unless consistent."""
        where = None if path is None else str(path)

        def fail(message: str, name: str) -> DataFormatError:
            return DataFormatError(message, path=where, field=name)

        b = self.beliefs
        if b.ndim != 3 or min(b.shape) == 0:
            raise fail(f"must have shape (ny, nx, K) with no empty axis, got {b.shape}", "beliefs")
        _validate_header(self.levels, self.origin, self.resolution, self.metadata, b.shape[2], fail)
        _validate_pmfs(b, 0, fail)
        _validate_estimate(self.estimate, self.estimate_cov, fail)


def _validate_header(
    levels: NDArray[np.float64],
    origin: NDArray[np.float64],
    resolution: float,
    metadata: dict[str, MetaValue],
    n_levels: int,
    fail: Callable[[str, str], DataFormatError],
) -> None:
    """Everything of an archive but its pmfs and estimate: ``levels`` (K,), ``origin`` (2,),
    ``resolution`` and ``metadata``."""
    if levels.shape != (n_levels,):
        raise fail(f"shape {levels.shape} does not match K = {n_levels} of beliefs", "levels")
    if not np.all(np.isfinite(levels)):
        raise fail("non-finite level", "levels")
    if origin.shape != (2,) or not np.all(np.isfinite(origin)):
        raise fail(f"must be 2 finite numbers, got {origin!r}", "origin")
    if not (math.isfinite(resolution) and resolution > 0):
        raise fail(f"must be positive, got {resolution}", "resolution")
    for key, value in metadata.items():
        if not isinstance(key, str) or not isinstance(value, (str, int, float)):
            raise fail(f"entry {key!r}: {value!r} is not str/int/float", "metadata")
        if isinstance(value, float) and not math.isfinite(value):
            raise fail(f"entry {key!r} is not finite", "metadata")


def _validate_pmfs(band: NDArray[np.float32], iy0: int, fail: Callable[[str, str], DataFormatError]) -> None:
    """Every cell of ``band`` (h, nx, K), rows ``iy0..iy0+h`` of the grid, a finite, non-negative
    pmf summing to 1 within :data:`PMF_TOLERANCE` (the error names the first bad cell)."""
    bad = ~np.isfinite(band).all(axis=2) | (band < 0).any(axis=2)
    sums = band.sum(axis=2, dtype=np.float64)
    bad |= np.abs(sums - 1.0) > PMF_TOLERANCE
    if bad.any():
        iy, ix = (int(v) for v in np.argwhere(bad)[0])
        raise fail(
            f"{int(bad.sum())} cells are not pmfs (first: sum {sums[iy, ix]!r}, min {float(band[iy, ix].min())!r})",
            f"beliefs[{iy0 + iy},{ix}]",
        )


def _validate_estimate(
    estimate: NDArray[np.float64] | None, cov: NDArray[np.float64] | None, fail: Callable[[str, str], DataFormatError]
) -> None:
    if (estimate is None) != (cov is None):
        raise fail("an estimate needs its covariance and the covariance its estimate", "estimate")
    if estimate is None or cov is None:
        return
    if estimate.shape != (3,) or not np.all(np.isfinite(estimate)):
        raise fail(f"must be 3 finite numbers (x, y, theta), got {estimate!r}", "estimate")
    if cov.shape != (3, 3) or not np.all(np.isfinite(cov)):
        raise fail(f"must be a finite 3 x 3 matrix, got shape {cov.shape}", "estimate_cov")
    if not np.allclose(cov, cov.T, rtol=1e-9, atol=1e-12) or np.linalg.eigvalsh(0.5 * (cov + cov.T)).min() < -1e-9:
        raise fail("must be symmetric and positive semidefinite", "estimate_cov")


def save_belief(path: str | os.PathLike[str], archive: BeliefArchive) -> None:
    """Validate ``archive`` and write it to ``path`` (exactly that name; no suffix added), in
    bands of rows as :func:`save_belief_bands` (each band validated as it is written)."""
    b = archive.beliefs
    if b.ndim != 3 or min(b.shape) == 0:
        raise DataFormatError(f"must have shape (ny, nx, K) with no empty axis, got {b.shape}", path=str(path), field="beliefs")
    if archive.levels.shape != (b.shape[2],):
        raise DataFormatError(
            f"shape {archive.levels.shape} does not match K = {b.shape[2]} of beliefs", path=str(path), field="levels"
        )
    ny, nx = archive.shape
    rows = max(1, BAND_BYTES // max(1, archive.beliefs[0].nbytes))
    save_belief_bands(
        path,
        shape=(ny, nx),
        levels=archive.levels,
        origin=archive.origin,
        resolution=archive.resolution,
        metadata=archive.metadata,
        bands=(archive.beliefs[i : i + rows] for i in range(0, ny, rows)),
        estimate=archive.estimate,
        estimate_cov=archive.estimate_cov,
    )


BAND_BYTES = 4 * 2**20
"""Bytes of pmfs a band of rows holds at most (at least one row) when an archive is written."""


def save_belief_bands(
    path: str | os.PathLike[str],
    *,
    shape: tuple[int, int],
    levels: NDArray[np.float64],
    origin: NDArray[np.float64],
    resolution: float,
    metadata: dict[str, MetaValue],
    bands: Iterable[NDArray[np.float32]],
    estimate: NDArray[np.float64] | None = None,
    estimate_cov: NDArray[np.float64] | None = None,
) -> None:
    """Writes a belief archive whose pmfs arrive as bands of rows, never all in memory at once.

    The file is the one :func:`save_belief` writes (the same members, dtypes and format version;
    :func:`load_belief` reads it): ``beliefs`` is streamed into its compressed ``.npy`` member band
    by band, and each band is validated as it comes. Memory: one band, whatever the grid's size.

    Parameters
    ----------
    shape : (int, int)
        ``(ny, nx)`` of the whole grid.
    levels, origin, resolution, metadata, estimate, estimate_cov
        As the fields of :class:`BeliefArchive`.
    bands : iterable of ndarray, shape (h, nx, K)
        The pmfs, rows ``0..ny`` in order (row 0 at the minimum y), in bands of any height;
        converted to float32.

    Raises
    ------
    DataFormatError
        If the header or a band is invalid or the bands do not add up to ``ny`` rows; the
        partial file is removed.
    """
    where = str(path)

    def fail(message: str, name: str) -> DataFormatError:
        return DataFormatError(message, path=where, field=name)

    lv = np.asarray(levels, dtype=np.float64)
    org = np.asarray(origin, dtype=np.float64)
    est = None if estimate is None else np.asarray(estimate, dtype=np.float64)
    cov = None if estimate_cov is None else np.asarray(estimate_cov, dtype=np.float64)
    ny, nx = (int(v) for v in shape)
    k = int(lv.shape[0]) if lv.ndim == 1 else -1
    if ny <= 0 or nx <= 0 or k <= 0:
        raise fail(f"must have shape (ny, nx, K) with no empty axis, got {(ny, nx, k)}", "beliefs")
    _validate_header(lv, org, float(resolution), dict(metadata), k, fail)
    _validate_estimate(est, cov, fail)
    small: dict[str, NDArray[Any]] = {
        "format": np.array(FORMAT_NAME),
        "format_version": np.array(FORMAT_VERSION, dtype=np.int64),
    }
    after: dict[str, NDArray[Any]] = {
        "levels": lv,
        "origin": org,
        "resolution": np.array(float(resolution), dtype=np.float64),
        "metadata": np.array(json.dumps(dict(metadata), sort_keys=True, allow_nan=False)),
    }
    if est is not None and cov is not None:
        after |= {"estimate": est, "estimate_cov": cov}
    try:
        # The members and their order are np.savez_compressed's (deflate, zip64 entries).
        with open(path, "wb") as fh, zipfile.ZipFile(fh, mode="w", compression=zipfile.ZIP_DEFLATED, allowZip64=True) as zf:
            for name, value in small.items():
                with zf.open(f"{name}.npy", "w", force_zip64=True) as member:
                    np.lib.format.write_array(member, value, allow_pickle=False)
            with zf.open("beliefs.npy", "w", force_zip64=True) as member:
                header = {
                    "descr": np.lib.format.dtype_to_descr(np.dtype(np.float32)),
                    "fortran_order": False,
                    "shape": (ny, nx, k),
                }
                np.lib.format.write_array_header_1_0(member, header)
                row = 0
                for band in bands:
                    b = np.ascontiguousarray(band, dtype=np.float32)
                    if b.ndim != 3 or b.shape[1:] != (nx, k) or row + b.shape[0] > ny:
                        raise fail(f"band of shape {b.shape} at row {row} does not fit the grid {(ny, nx, k)}", "beliefs")
                    _validate_pmfs(b, row, fail)
                    member.write(b.data)
                    row += b.shape[0]
                if row != ny:
                    raise fail(f"the bands hold {row} rows, the grid {ny}", "beliefs")
            for name, value in after.items():
                with zf.open(f"{name}.npy", "w", force_zip64=True) as member:
                    np.lib.format.write_array(member, value, allow_pickle=False)
    except BaseException:
        Path(path).unlink(missing_ok=True)
        raise


def _check_before_loading(path: str | os.PathLike[str]) -> None:
    """Refuses, before anything is decompressed, an archive over the ``archive_bytes`` limit or
    whose belief grid exceeds the ``map_cells`` limit (:mod:`crlam.limits`)."""
    members = check_npz(path, "belief archive")
    beliefs = members.get("beliefs")
    if beliefs is not None and len(beliefs.shape) == 3:
        ny, nx, _ = beliefs.shape
        check_limit("map_cells", ny * nx, f"belief archive {path} ({ny} x {nx} cells)")


def load_belief(path: str | os.PathLike[str]) -> BeliefArchive:
    """Read and validate a belief archive written by :func:`save_belief`.

    Raises
    ------
    DataFormatError
        If the file is not such an archive, has a newer format version, misses a key, or
        holds inconsistent arrays (the message names the field).
    ResourceLimitError
        If its content exceeds the ``archive_bytes`` or ``map_cells`` limit (checked before
        anything is decompressed).
    """
    where = str(path)
    _check_before_loading(path)
    try:
        with np.load(Path(path), allow_pickle=False) as npz:
            arrays = {k: npz[k] for k in npz.files}
    except (zipfile.BadZipFile, ValueError, EOFError, OSError, zlib.error) as exc:
        if isinstance(exc, FileNotFoundError):
            raise
        raise DataFormatError(f"not a belief archive ({exc})", path=where) from exc
    for key in ("format", "format_version", "beliefs", "levels", "origin", "resolution", "metadata"):
        if key not in arrays:
            raise DataFormatError("missing key", path=where, field=key)
    if str(arrays["format"]) != FORMAT_NAME:
        raise DataFormatError(f"format is {str(arrays['format'])!r}, not {FORMAT_NAME!r}", path=where, field="format")
    version = arrays["format_version"]
    if version.shape != () or not np.issubdtype(version.dtype, np.integer) or int(version) < 1:
        raise DataFormatError(f"invalid format version {version!r}", path=where, field="format_version")
    if int(version) > FORMAT_VERSION:
        raise DataFormatError(
            f"format version {int(version)} was written by a newer crlam; this crlam (format {FORMAT_VERSION}) reads versions "
            f"1..{FORMAT_VERSION}: upgrade crlam to read it",
            path=where,
            field="format_version",
        )
    for key, dtype in (("beliefs", np.float32), ("levels", np.float64), ("origin", np.float64), ("resolution", np.float64)):
        if arrays[key].dtype != dtype:
            raise DataFormatError(f"dtype {arrays[key].dtype}, want {np.dtype(dtype)}", path=where, field=key)
    if arrays["resolution"].shape != ():
        raise DataFormatError("must be a scalar", path=where, field="resolution")
    try:
        metadata = json.loads(str(arrays["metadata"]))
    except json.JSONDecodeError as exc:
        raise DataFormatError(f"invalid JSON ({exc})", path=where, field="metadata") from exc
    if not isinstance(metadata, dict):
        raise DataFormatError("must be a JSON object", path=where, field="metadata")
    estimate = estimate_cov = None
    if int(version) >= 2 and "estimate" in arrays:
        if "estimate_cov" not in arrays:
            raise DataFormatError("missing key (an estimate needs its covariance)", path=where, field="estimate_cov")
        for key in ("estimate", "estimate_cov"):
            if arrays[key].dtype != np.float64:
                raise DataFormatError(f"dtype {arrays[key].dtype}, want float64", path=where, field=key)
        estimate, estimate_cov = arrays["estimate"], arrays["estimate_cov"]
    archive = BeliefArchive(
        beliefs=arrays["beliefs"],
        levels=arrays["levels"],
        origin=arrays["origin"],
        resolution=float(arrays["resolution"]),
        metadata=metadata,
        estimate=estimate,
        estimate_cov=estimate_cov,
    )
    archive.validate(path)
    return archive
