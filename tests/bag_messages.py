"""Synthetic bags with edited messages, for the reliability tests and the damaged-bag corpus
(``tests/damaged_bags``): the messages of ``test_io_rosbag``'s :class:`BagSpec`, passed through
an edit before they are serialised."""

from __future__ import annotations

import shutil
import tempfile
from collections.abc import Callable
from pathlib import Path
from typing import Any

from rosbags.rosbag2 import StoragePlugin
from rosbags.rosbag2 import Writer as Writer2
from rosbags.typesys import Stores, get_typestore

from test_io_rosbag import BagSpec, _messages

__all__ = ["messages", "write_mutated"]

Edit = Callable[[str, Any], Any]


def messages(spec: BagSpec, ts: Any) -> list[tuple[str, str, float, Any]]:
    """(topic, type, receive time, message) of a :class:`BagSpec`, in time order."""
    return _messages(spec, ts)


def write_mutated(
    path: Path,
    spec: BagSpec,
    edit: Edit | None = None,
    *,
    storage: str = "mcap",
    folder: bool = False,
    until: float | None = None,
    zstd: bool = False,
) -> Path:
    """A bag of the spec's messages, each passed through ``edit(topic, message)`` (which changes
    it in place or returns another): a plain ``.mcap`` file at ``path``, or with ``folder`` a
    ROS 2 bag folder (``storage`` ``"mcap"`` or ``"sqlite3"``, ``zstd`` compressing its file).
    ``until`` leaves out the messages received after that time (s), for small files."""
    from rosbags.rosbag2 import CompressionFormat, CompressionMode

    ts = get_typestore(Stores.ROS2_HUMBLE)
    work = Path(tempfile.mkdtemp(prefix="crlam-bag-"))
    plugin = StoragePlugin.MCAP if storage == "mcap" else StoragePlugin.SQLITE3
    try:
        writer = Writer2(work / "bag", version=9, storage_plugin=plugin)
        if zstd:
            writer.set_compression(CompressionMode.FILE, CompressionFormat.ZSTD)
        with writer as w:
            conns: dict[str, Any] = {}
            for topic, typ, t, msg in messages(spec, ts):
                if until is not None and t > until:
                    continue
                msg = edit(topic, msg) if edit is not None else msg
                if topic not in conns:
                    conns[topic] = w.add_connection(topic, typ, typestore=ts)
                w.write(conns[topic], int(t * 1e9), ts.serialize_cdr(msg, typ))
        if folder:
            shutil.move(str(work / "bag"), path)
        else:
            (mcap,) = (work / "bag").glob("*.mcap")
            shutil.move(str(mcap), path)
    finally:
        shutil.rmtree(work, ignore_errors=True)
    return path
