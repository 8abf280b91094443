"""Resource limits: how much memory an input may make crlam use.

Every allocation whose size an input decides (the cells of a map, the particles of a filter, the
pixels of an image, the uncompressed bytes of an archive, the bytes of a download, the readings
of a simulated log) is checked
against one of these limits *before* it is made; an input over a limit raises
:class:`~crlam.errors.ResourceLimitError` naming the input, the limit and how to raise it, instead
of exhausting the machine.

=================  ============  ==============================  ====================================
limit              default       command-line flag               environment variable
=================  ============  ==============================  ====================================
``map_cells``      16,000,000    ``--max-map-cells N``           ``CRLAM_MAX_MAP_CELLS``
``particles``      100,000       ``--max-particles N``           ``CRLAM_MAX_PARTICLES``
``image_pixels``   16,000,000    ``--max-image-pixels N``        ``CRLAM_MAX_IMAGE_PIXELS``
``archive_bytes``  1 GiB         ``--max-archive-bytes N``       ``CRLAM_MAX_ARCHIVE_BYTES``
``download_bytes`` 1 GiB         ``--max-download-bytes N``      ``CRLAM_MAX_DOWNLOAD_BYTES``
``readings``       100,000,000   ``--max-readings N``            ``CRLAM_MAX_READINGS``
=================  ============  ==============================  ====================================

16 million cells is a 4,000 x 4,000 grid (an 800 m square at 0.2 m, 200 m at 0.05 m); writing a
map folder of that size takes about 2 GB. ``readings`` bounds the range readings a simulated log
holds in memory (scans x beams, 8 bytes each: 100 million is about 92,000 scans of the paper's
1079-beam LIDAR, 800 MB). The environment variables are read when crlam is imported;
:func:`set_limits` changes the limits of this process and of the worker processes it starts
afterwards (they inherit the environment). The Rust core enforces ``map_cells`` and ``particles``
itself; the others are checked in Python, before the file is decoded or the log simulated.
"""

from __future__ import annotations

import math
import os
from dataclasses import dataclass, fields, replace

from crlam.errors import ConfigError, ResourceLimitError

__all__ = ["Limits", "DEFAULTS", "check_limit", "limits", "parse_limit", "set_limits"]


@dataclass(frozen=True)
class Limits:
    """The limits in force (see the module docstring); every value is a positive integer."""

    map_cells: int = 16_000_000
    particles: int = 100_000
    image_pixels: int = 16_000_000
    archive_bytes: int = 1 << 30
    download_bytes: int = 1 << 30
    readings: int = 100_000_000


DEFAULTS = Limits()

_UNITS = {
    "map_cells": "map cells",
    "particles": "particles",
    "image_pixels": "pixels",
    "archive_bytes": "bytes",
    "download_bytes": "bytes",
    "readings": "range readings",
}


def env_name(setting: str) -> str:
    """The environment variable of a limit (``CRLAM_MAX_MAP_CELLS`` for ``map_cells``)."""
    return f"CRLAM_MAX_{setting.upper()}"


def flag_name(setting: str) -> str:
    """The command-line flag of a limit (``--max-map-cells`` for ``map_cells``)."""
    return "--max-" + setting.replace("_", "-")


def parse_limit(text: str | int | float, setting: str = "limit") -> int:
    """A limit value: a positive integer, also written as ``1e8`` or ``16_000_000``."""
    try:
        value = float(str(text).replace("_", "")) if not isinstance(text, int) else text
    except ValueError:
        raise ConfigError(f"{setting}: not a number: {text!r}") from None
    if isinstance(value, float) and not (math.isfinite(value) and value == int(value)):
        raise ConfigError(f"{setting}: must be a whole number, got {text!r}")
    n = int(value)
    if n < 1:
        raise ConfigError(f"{setting}: must be >= 1, got {text!r}")
    return n


def _from_environment() -> Limits:
    values = {}
    for f in fields(Limits):
        raw = os.environ.get(env_name(f.name))
        if raw not in (None, ""):
            values[f.name] = parse_limit(raw, env_name(f.name))
    return replace(DEFAULTS, **values)


_current = _from_environment()


def limits() -> Limits:
    """The limits in force in this process."""
    return _current


def _push_to_core(lim: Limits) -> None:
    from crlam import _native

    _native.set_limits(map_cells=lim.map_cells, particles=lim.particles)


def set_limits(**changes: int | str) -> Limits:
    """Changes some limits (``set_limits(map_cells=10**8)``) in this process, in its Rust core
    and, through the environment, in the worker processes it starts later; returns the limits now
    in force."""
    global _current
    unknown = set(changes) - {f.name for f in fields(Limits)}
    if unknown:
        raise ConfigError(f"unknown limits {sorted(unknown)}; known: {[f.name for f in fields(Limits)]}")
    new = replace(_current, **{k: parse_limit(v, k) for k, v in changes.items()})
    _push_to_core(new)
    for k in changes:
        os.environ[env_name(k)] = str(getattr(new, k))
    _current = new
    return new


def check_limit(setting: str, needed: float, what: str) -> None:
    """Raises :class:`ResourceLimitError` when ``needed`` exceeds the limit ``setting``;
    ``what`` names the input that asks for it (e.g. ``"image map.png (9000 x 9000 pixels)"``)."""
    limit = getattr(_current, setting)
    if not needed <= limit:  # also refuses NaN
        raise ResourceLimitError(
            f"{what} needs {needed:,.0f} {_UNITS[setting]}, more than the limit of {limit:,} "
            f"(raise it with {flag_name(setting)} N or the environment variable {env_name(setting)}=N)"
        )


_push_to_core(_current)
