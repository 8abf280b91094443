"""Exception hierarchy of crlam.

Every error raised on purpose by crlam derives from :class:`CrlamError`, so callers can catch the
whole family at once. The concrete classes also derive from the matching built-in exception, so
``except ValueError`` keeps working for code that does not know crlam.
"""

from __future__ import annotations

__all__ = [
    "CrlamError",
    "ConfigError",
    "DataFormatError",
    "InternalError",
    "MapBoundsError",
    "NumericalError",
    "ResourceLimitError",
]


class CrlamError(Exception):
    """Base class of every error raised by crlam."""


class ConfigError(CrlamError, ValueError):
    """A configuration value is out of range, of the wrong type, or inconsistent with another."""


class MapBoundsError(CrlamError, ValueError):
    """A pose or cell lies outside a map whose extent is fixed."""


class NumericalError(CrlamError, ArithmeticError):
    """A computation produced a non-finite value that cannot be skipped safely."""


class ResourceLimitError(CrlamError, ValueError):
    """An input asks for more memory than a resource limit allows (map cells, particles, image
    pixels, archive bytes, download bytes), or a buffer sized by the data could not be allocated.

    The message names the input, the limit and how to raise it (see :mod:`crlam.limits`).
    """


class InternalError(CrlamError, RuntimeError):
    """A bug in crlam: the Rust core panicked. The message says where; please report it."""


class DataFormatError(CrlamError, ValueError):
    """Malformed input data; the message names the file, the line and the field.

    Parameters
    ----------
    message:
        What is wrong, in words.
    path:
        File the data came from (``None`` for in-memory data).
    line:
        1-based line number, when the format is line oriented.
    field:
        Name of the offending field (e.g. ``"range[17]"``, ``"ipc_timestamp"``).
    """

    def __init__(
        self,
        message: str,
        path: str | None = None,
        line: int | None = None,
        field: str | None = None,
    ) -> None:
        self.path = path
        self.line = line
        self.field = field
        where = [str(path)] if path is not None else []
        if line is not None:
            where.append(f"line {line}")
        prefix = ":".join(where)
        if field is not None:
            prefix = f"{prefix} (field {field})" if prefix else f"field {field}"
        super().__init__(f"{prefix}: {message}" if prefix else message)
