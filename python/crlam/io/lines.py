"""Lines of a text log, read safely: any line ending (``\\n``, ``\\r\\n`` or a lone ``\\r``), UTF-8
with undecodable bytes replaced, and a bound on the length of a line, so that a file without line
breaks (a binary file, ``/dev/zero``) gives an error instead of being read into memory whole."""

from __future__ import annotations

import io
from collections.abc import Iterator
from typing import BinaryIO

from crlam.errors import DataFormatError

__all__ = ["MAX_LINE_CHARS", "text_lines"]

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
            except (OSError, EOFError, ValueError) as exc:
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
