"""Which failures the ``crlam`` command reports as one line (exit status 2), and how.

Expected failures are those of the input and of the machine: crlam's own errors (bad data, bad
settings, resource limits), the operating system refusing a file or folder, undecodable bytes,
archives that are not zip files, and running out of memory. Any other exception is a bug in
crlam and keeps its traceback.
"""

from __future__ import annotations

import zipfile

from crlam.errors import CrlamError

__all__ = ["EXPECTED_FAILURES", "describe_failure"]

EXPECTED_FAILURES: tuple[type[BaseException], ...] = (
    CrlamError,
    OSError,
    ValueError,  # includes UnicodeDecodeError and json.JSONDecodeError
    OverflowError,  # a number beyond the range of the native type it is given to
    EOFError,
    MemoryError,
    zipfile.BadZipFile,
)


def describe_failure(e: BaseException) -> str:
    """The message of an expected failure: one line (crlam's own errors may list cases below it)."""
    if isinstance(e, MemoryError):
        detail = f" ({e})" if str(e) else ""
        return (
            f"out of memory{detail}; the input needs more memory than this machine has free (lower the resource limits, "
            "e.g. --max-map-cells, so that such inputs are refused up front)"
        )
    if isinstance(e, OSError) and not isinstance(e, CrlamError) and e.strerror:
        where = f": {e.filename}" if e.filename else ""
        also = f" -> {e.filename2}" if getattr(e, "filename2", None) else ""
        return f"{e.strerror}{where}{also}"
    text = str(e).strip() or type(e).__name__
    if isinstance(e, CrlamError):
        return text  # crlam's own messages are written for the user (a few list their cases)
    lines = text.splitlines()
    return lines[0] + (f" (... {len(lines) - 1} more lines)" if len(lines) > 1 else "")
