"""crlam: confidence-rich localization and mapping with a Rust core."""

from __future__ import annotations

from crlam.errors import (
    ConfigError,
    CrlamError,
    DataFormatError,
    InternalError,
    MapBoundsError,
    NumericalError,
    ResourceLimitError,
)

__all__ = [
    "CrlamError",
    "ConfigError",
    "DataFormatError",
    "InternalError",
    "MapBoundsError",
    "NumericalError",
    "ResourceLimitError",
    "__version__",
]

try:
    from importlib.metadata import version as _version

    __version__ = _version("crlam")
except Exception:  # pragma: no cover - running from a source tree without metadata
    __version__ = "0.0.0+unknown"

# The resource limits (crlam.limits) reach the Rust core as soon as crlam is imported, so that the
# CRLAM_MAX_* environment variables hold for every user of crlam._native.
from crlam import limits as _limits  # noqa: E402,F401
