"""Checks of an ``.npz`` archive made *before* it is decompressed (zip-bomb guard).

``np.load`` allocates each array at the size its ``.npy`` header declares and only then reads the
data, and a zip member may inflate far beyond its compressed size. :func:`check_npz` reads only
the zip directory and the few bytes of each array header, and refuses an archive whose declared
content exceeds the ``archive_bytes`` limit (:mod:`crlam.limits`), whose array headers claim more
bytes than their member holds, or which holds object arrays.
"""

from __future__ import annotations

import math
import os
import tokenize
import zipfile
import zlib
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from crlam.errors import CrlamError, DataFormatError
from crlam.limits import check_limit

__all__ = ["NpzMember", "check_npz"]


@dataclass(frozen=True)
class NpzMember:
    """An array of an archive, as its header declares it."""

    shape: tuple[int, ...]
    dtype: np.dtype
    nbytes: int


def _read_header(fh: object, where: str, name: str) -> tuple[tuple[int, ...], np.dtype]:
    fmt = np.lib.format
    try:
        version = fmt.read_magic(fh)  # type: ignore[arg-type]
        if version == (1, 0):
            shape, _, dtype = fmt.read_array_header_1_0(fh)  # type: ignore[arg-type]
        elif version == (2, 0):
            shape, _, dtype = fmt.read_array_header_2_0(fh)  # type: ignore[arg-type]
        else:
            raise DataFormatError(f"unsupported .npy format version {version}", path=where, field=name)
    except (ValueError, EOFError, OSError, SyntaxError, tokenize.TokenError) as exc:
        raise DataFormatError(f"invalid array header ({exc})", path=where, field=name) from exc
    return tuple(int(n) for n in shape), np.dtype(dtype)


def check_npz(path: str | os.PathLike[str], what: str = "archive") -> dict[str, NpzMember]:
    """The arrays of an ``.npz`` file as declared, after checking that loading it is safe.

    Raises
    ------
    ResourceLimitError
        When the members' declared uncompressed size exceeds the ``archive_bytes`` limit.
    DataFormatError
        When the file is not a zip of ``.npy`` members, a header is invalid, an array holds
        Python objects or claims more bytes than its member holds.
    FileNotFoundError
        When the file does not exist.
    """
    if not isinstance(path, (str, os.PathLike)):
        raise TypeError(f"path must be a str or os.PathLike, got {type(path).__name__}")
    where = str(path)
    p = Path(path)
    if not p.is_file():
        if not p.exists():
            raise FileNotFoundError(f"{p}: no such {what}")
        raise DataFormatError(f"not a regular file (a folder, a device or a pipe): not a {what}", path=where)
    try:
        return _members(path, where, what)
    except (zipfile.BadZipFile, EOFError, ValueError, NotImplementedError, RuntimeError, zlib.error) as exc:
        if isinstance(exc, CrlamError):
            raise
        raise DataFormatError(f"not a {what} ({type(exc).__name__}: {exc})", path=where) from exc
    except OSError as exc:
        if isinstance(exc, (FileNotFoundError, CrlamError)):
            raise
        raise DataFormatError(f"not a {what} (unreadable zip: {exc})", path=where) from exc


def _members(path: str | os.PathLike[str], where: str, what: str) -> dict[str, NpzMember]:
    out: dict[str, NpzMember] = {}
    with zipfile.ZipFile(path) as zf:
        infos = zf.infolist()
        total = sum(i.file_size for i in infos)
        check_limit("archive_bytes", total, f"{what} {where} ({len(infos)} members, uncompressed)")
        for info in infos:
            name = info.filename[:-4] if info.filename.endswith(".npy") else info.filename
            with zf.open(info) as fh:
                shape, dtype = _read_header(fh, where, name)
            if dtype.hasobject:
                raise DataFormatError("holds Python objects (not allowed)", path=where, field=name)
            nbytes = math.prod(shape) * dtype.itemsize
            if nbytes > info.file_size:
                raise DataFormatError(
                    f"header declares {shape} {dtype} ({nbytes:,} bytes) but the member holds {info.file_size:,}",
                    path=where,
                    field=name,
                )
            out[name] = NpzMember(shape, dtype, nbytes)
    return out
