"""Lines of a text log, read safely: any line ending (``\\n``, ``\\r\\n`` or a lone ``\\r``), UTF-8
with undecodable bytes replaced, and a bound on the length of a line, so that a file without line
breaks (a binary file, ``/dev/zero``) gives an error instead of being read into memory whole."""

from __future__ import annotations

import io
import os
import zlib
from collections.abc import Iterator
from pathlib import Path
from typing import BinaryIO

from crlam.errors import DataFormatError

__all__ = ["MAX_LINE_CHARS", "MAX_SMALL_FILE_BYTES", "read_small_text", "text_lines"]

#: Longest line accepted (characters). A CARMEN ROBOTLASER1 line of 1,081 beams with remissions
#: is about 20,000 characters; nothing a text log holds comes near a million.
MAX_LINE_CHARS = 1 << 20


def text_lines(stream: BinaryIO, path: str) -> Iterator[tuple[int, str]]:
    """``(1-based line number, line)`` for every line of a binary stream (the stream is left open
    for the caller to close). Errors of the stream (a corrupt compressed file) and over-long lines
    raise :class:`DataFormatError` naming ``path`` and the line."""
    fh = io.TextIOWrapper(stream, encoding="utf-8", errors="replace", newline=None)
    number = 0
    try:
        while True:
            try:
                text = fh.readline(MAX_LINE_CHARS + 1)
            except (OSError, EOFError, ValueError, zlib.error) as exc:
                raise DataFormatError(f"corrupt or truncated (compressed?) stream ({exc})", path=path, line=number + 1) from exc
            if not text:
                return
            number += 1
            if len(text) > MAX_LINE_CHARS:
                raise DataFormatError(
                    f"line longer than {MAX_LINE_CHARS:,} characters: not a text log (a binary file?)", path=path, line=number
                )
            yield number, text
    finally:
        fh.detach()


#: Largest small text file (a map YAML, a config TOML, a result JSON) read whole (bytes).
MAX_SMALL_FILE_BYTES = 16 << 20


def read_small_text(path: str | os.PathLike[str], what: str = "file") -> str:
    """The text of a small file (YAML, TOML, JSON) read whole, refusing what is not a regular file
    (a folder, ``/dev/zero``, a pipe) and files over :data:`MAX_SMALL_FILE_BYTES`."""
    p = Path(path)
    if not p.is_file():
        if not p.exists():
            raise FileNotFoundError(f"{p}: no such {what}")
        raise DataFormatError(f"not a regular file (a folder, a device or a pipe): not a {what}", path=str(p))
    size = p.stat().st_size
    if size > MAX_SMALL_FILE_BYTES:
        raise DataFormatError(f"{size:,} bytes is too large for a {what} (at most {MAX_SMALL_FILE_BYTES:,})", path=str(p))
    return p.read_bytes().decode("utf-8", "replace")
