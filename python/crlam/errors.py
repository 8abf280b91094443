"""Exception hierarchy of crlam.

Every error raised on purpose by crlam derives from :class:`CrlamError`, so callers can catch the
whole family at once. The concrete classes also derive from the matching built-in exception, so
``except ValueError`` keeps working for code that does not know crlam.
"""

from __future__ import annotations

__all__ = ["CrlamError", "ConfigError", "DataFormatError", "MapBoundsError", "NumericalError"]


class CrlamError(Exception):
    """Base class of every error raised by crlam."""


class ConfigError(CrlamError, ValueError):
    """A configuration value is out of range, of the wrong type, or inconsistent with another."""


class MapBoundsError(CrlamError, ValueError):
    """A pose or cell lies outside a map whose extent is fixed."""


class NumericalError(CrlamError, ArithmeticError):
    """A computation produced a non-finite value that cannot be skipped safely."""


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
        where = []
        if path is not None:
            where.append(str(path))
        if line is not None:
            where.append(f"line {line}")
        if field is not None:
            where.append(f"field {field}")
        prefix = ":".join(where[:2]) if where else ""
        if field is not None:
            prefix = f"{prefix} ({where[-1]})" if len(where) > 1 else where[-1]
        super().__init__(f"{prefix}: {message}" if prefix else message)
