"""crlam: confidence-rich localization and mapping with a Rust core."""

from __future__ import annotations

from crlam.errors import ConfigError, CrlamError, DataFormatError, MapBoundsError, NumericalError

__all__ = ["CrlamError", "ConfigError", "DataFormatError", "MapBoundsError", "NumericalError", "__version__"]

try:
    from importlib.metadata import version as _version

    __version__ = _version("crlam")
except Exception:  # pragma: no cover - running from a source tree without metadata
    __version__ = "0.0.0+unknown"
