"""Opening ROS bags safely: what is checked before the bag library reads a byte, and how its
failures reach the user.

Before reading
--------------
* The input must be a regular file (``.bag``, ``.mcap``) or a folder: a FIFO would block the
  reader forever, a device (``/dev/zero``) feed it without end, a socket fail obscurely; they are
  refused at once (:func:`check_bag_input`).
* A ROS 2 bag folder's ``metadata.yaml`` is read by crlam first (at most 1 MB, nesting bounded:
  :mod:`crlam.io.structured`) and must be a mapping with ``rosbag2_bagfile_information``
  holding a ``version`` from 1 to 9, a ``storage_identifier`` of ``sqlite3`` or ``mcap``, a
  compression of none or ``zstd``, and ``relative_file_paths``: a list of names of regular files
  inside the folder. A path that is absolute, climbs out with ``..``, or is a symlink that
  resolves outside the folder is refused: a bag never makes crlam read outside its own folder.

While reading
-------------
:func:`bag_errors` turns what the bag library and the libraries under it raise on damaged or
foreign input (rosbags' reader errors, the MCAP and ROS 1 parsers, zstd, sqlite3, YAML, a
recursion or a buffer that a damaged length field asks for) into a
:class:`~crlam.errors.DataFormatError` naming the bag, the topic and message where known, and
the cause in words.
"""

from __future__ import annotations

import os
import stat
import struct
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path, PurePath
from typing import Any

from crlam.errors import CrlamError, DataFormatError

__all__ = ["STORAGE_IDS", "bag_errors", "check_bag_input", "check_metadata", "library_errors", "open_any_reader"]

#: The ROS 2 storage plugins the reader has.
STORAGE_IDS = ("sqlite3", "mcap")
#: The newest rosbag2 metadata version the reader knows.
MAX_METADATA_VERSION = 9
#: Largest metadata.yaml read (bytes).
MAX_METADATA_BYTES = 1_000_000


def _kind(mode: int) -> str:
    if stat.S_ISFIFO(mode):
        return "a FIFO (named pipe)"
    if stat.S_ISCHR(mode) or stat.S_ISBLK(mode):
        return "a device"
    if stat.S_ISSOCK(mode):
        return "a socket"
    return "not a regular file"


def check_bag_input(path: str | os.PathLike[str]) -> Path:
    """The bag path, checked to be a regular file or a folder (``os.stat`` does not open it, so
    a FIFO is refused without blocking).

    Raises
    ------
    FileNotFoundError
        When nothing is there.
    DataFormatError
        For a FIFO, a device or a socket; for a bag folder whose ``metadata.yaml`` fails
        :func:`check_metadata`.
    """
    p = Path(path)
    try:
        mode = os.stat(p).st_mode
    except FileNotFoundError:
        raise FileNotFoundError(f"ROS bag not found: {p}") from None
    if stat.S_ISDIR(mode):
        check_metadata(p)
        return p
    if not stat.S_ISREG(mode):
        raise DataFormatError(f"{_kind(mode)}, not a ROS bag file: crlam reads bags from regular files only", path=str(p))
    return p


def _inside(folder: Path, name: Any, where: str) -> Path:
    """The file ``name`` of a bag folder, refused when it leaves the folder or is no regular file."""
    if not isinstance(name, str) or not name:
        raise DataFormatError(f"relative_file_paths holds {name!r}, not a file name", path=where)
    pure = PurePath(name)
    if pure.is_absolute() or ".." in pure.parts:
        raise DataFormatError(
            f"relative_file_paths names {name!r}, outside the bag's folder: a bag may only name files in its own folder",
            path=where,
        )
    # rosbags opens the name alone in the folder (PurePath(name).name); that file is checked.
    target = folder / pure.name
    real_folder = folder.resolve()
    try:
        real = target.resolve(strict=True)
    except (FileNotFoundError, RuntimeError):
        raise DataFormatError(f"the bag's file {pure.name} (relative_file_paths) is missing", path=where) from None
    if real_folder not in real.parents:
        raise DataFormatError(f"the bag's file {pure.name} is a link to {real}, outside the bag's folder: refused", path=where)
    mode = os.stat(real).st_mode
    if not stat.S_ISREG(mode):
        raise DataFormatError(f"the bag's file {pure.name} is {_kind(mode)}", path=where)
    return target


def check_metadata(folder: Path) -> dict[str, Any]:
    """The ``rosbag2_bagfile_information`` of a ROS 2 bag folder, checked (see the module
    documentation); raises :class:`DataFormatError` naming ``metadata.yaml`` and the field."""
    from crlam.io.lines import read_small_text
    from crlam.io.structured import load_yaml_text

    meta = folder / "metadata.yaml"
    where = str(meta)
    if not meta.exists():
        raise DataFormatError("a ROS 2 bag folder needs a metadata.yaml (this folder has none)", path=where)
    if meta.stat().st_size > MAX_METADATA_BYTES:
        raise DataFormatError(f"larger than {MAX_METADATA_BYTES:,} bytes: not a bag's metadata", path=where)
    doc = load_yaml_text(read_small_text(meta, "ROS 2 bag metadata"), where)
    info = doc.get("rosbag2_bagfile_information") if isinstance(doc, dict) else None
    if not isinstance(info, dict):
        raise DataFormatError("not a ROS 2 bag's metadata: no rosbag2_bagfile_information mapping", path=where)

    def bad(field: str, message: str) -> DataFormatError:
        return DataFormatError(message, path=where, field=f"rosbag2_bagfile_information.{field}")

    version = info.get("version")
    if isinstance(version, bool) or not isinstance(version, int) or not 1 <= version <= MAX_METADATA_VERSION:
        raise bad("version", f"{version!r} is not a rosbag2 metadata version this reader knows (1..{MAX_METADATA_VERSION})")
    storage = info.get("storage_identifier")
    if storage not in STORAGE_IDS:
        raise bad("storage_identifier", f"storage {storage!r} is not one crlam reads ({', '.join(STORAGE_IDS)})")
    fmt = info.get("compression_format") or ""
    mode = str(info.get("compression_mode") or "").lower()
    if fmt not in ("", "zstd") or mode not in ("", "none", "file", "message"):
        raise bad(
            "compression_format", f"compression {fmt!r} ({mode or 'no mode'}) is not one crlam reads (zstd by file or message)"
        )
    if mode not in ("", "none") and fmt != "zstd":
        raise bad("compression_format", f"compression mode {mode!r} without the zstd format")
    files = info.get("relative_file_paths")
    if not isinstance(files, list) or not files:
        raise bad("relative_file_paths", "must list the bag's files")
    for name in files:
        _inside(folder, name, where)
    topics = info.get("topics_with_message_count", [])
    if not isinstance(topics, list):
        raise bad("topics_with_message_count", f"must be a list, got {type(topics).__name__}")
    return info


def library_errors() -> tuple[type[BaseException], ...]:
    """What the bag library and the libraries under it raise on damaged or foreign input."""
    import sqlite3

    # MemoryError / OverflowError: a damaged length field asks for an absurd buffer; TypeError and
    # AttributeError: the MCAP parser on a truncated record, a ROS 1 bag whose damaged message
    # definition gives a known type other fields; RecursionError: deeply nested YAML in rosbags'
    # own metadata parser; UnicodeError (a ValueError): names that are not UTF-8.
    errors: list[type[BaseException]] = [
        KeyError,
        IndexError,
        ValueError,
        EOFError,
        OSError,
        struct.error,
        AssertionError,
        MemoryError,
        TypeError,
        ArithmeticError,
        AttributeError,
        RecursionError,
        sqlite3.Error,
    ]
    for module, name in (
        ("rosbags.highlevel", "AnyReaderError"),
        ("rosbags.rosbag1", "ReaderError"),
        ("rosbags.rosbag2", "ReaderError"),
        ("rosbags.serde", "SerdeError"),
        ("rosbags.typesys", "TypesysError"),
        ("apsw", "Error"),  # rosbags' sqlite3 storage reads through apsw
        ("backports.zstd", "ZstdError"),
        ("compression.zstd", "ZstdError"),
        ("zstandard", "ZstdError"),
        ("ruamel.yaml", "YAMLError"),
        ("yaml", "YAMLError"),
    ):
        try:
            mod = __import__(module, fromlist=[name])
        except ImportError:
            continue
        cls = getattr(mod, name, None)
        if isinstance(cls, type) and issubclass(cls, BaseException):
            errors.append(cls)
    return tuple(errors)


def _cause(exc: BaseException) -> str:
    """The cause of a library error in words, with the library's own message."""
    name = type(exc).__name__
    reason = " ".join(str(exc).split())[:300]
    if isinstance(exc, RecursionError):
        return "nested too deep to parse"
    if isinstance(exc, MemoryError):
        return "a damaged size field asks for more memory than there is"
    if "Zstd" in name:
        return f"a zstd-compressed part does not decompress ({reason})"
    if isinstance(exc, UnicodeDecodeError):
        return f"text that is not UTF-8 where the format has names ({reason})"
    if type(exc).__module__.startswith(("sqlite3", "apsw")):
        return f"the sqlite3 database is damaged or not a database ({reason})"
    return f"{name}: {reason}" if reason else name


@contextmanager
def bag_errors(path: str | os.PathLike[str], where: str = "") -> Iterator[None]:
    """Turn the bag library's failures inside the block into a :class:`DataFormatError` naming
    the bag and ``where`` (a topic and message, e.g. ``"/scan message 17"``). crlam's own
    errors pass through unchanged."""
    try:
        yield
    except CrlamError:
        raise
    except FileNotFoundError as exc:
        raise DataFormatError(f"a file of the bag is missing ({exc})", path=str(path)) from exc
    except library_errors() as exc:
        at = f" in {where}" if where else ""
        raise DataFormatError(f"damaged or unreadable ROS bag{at}: {_cause(exc)}", path=str(path)) from exc


def open_any_reader(path: str | os.PathLike[str], typestore: Any = None) -> Any:
    """rosbags' ``AnyReader`` over one checked bag, opened (use it as a context manager)."""
    try:
        from rosbags.highlevel import AnyReader
        from rosbags.typesys import Stores, get_typestore
    except ImportError as exc:  # pragma: no cover - rosbags is a dependency
        from crlam.errors import ConfigError

        raise ConfigError("reading ROS bags needs the 'rosbags' package (pip install rosbags)") from exc
    p = check_bag_input(path)
    with bag_errors(p, "the bag's header and index"):
        return AnyReader([p], default_typestore=typestore or get_typestore(Stores.ROS2_HUMBLE))
