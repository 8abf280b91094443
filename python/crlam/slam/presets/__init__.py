"""Named SLAM presets: partial :class:`crlam.slam.SlamConfig` settings kept as TOML files.

Each preset is one file in this package, ``<name>.toml``, whose ``[slam]`` table maps SlamConfig
field names to values (a line ``# name = (unset)`` sets a field to None); fields a preset does
not name keep SlamConfig's defaults, which are the paper's. The files are the only place the
presets' values are written:

- ``paper``: exactly the paper's algorithm (every field written out; equal to ``SlamConfig()``).
  It is the reference of :meth:`SlamConfig.deviations`.
- ``robust``: the most accurate setting measured on the real logs; the default of ``crlam slam``,
  ``crlam experiment real-logs`` and :meth:`SlamConfig.from_preset`.

A run folder's ``config.toml`` has the same ``[slam]`` table (every field, plus the preset name
and the derived ``sigma_hit_resolved``), so :func:`load_config_file` reads either kind of file.

The reading itself is in :mod:`crlam.slam.preset_files` (below :class:`~crlam.slam.SlamConfig`, which
it takes as an argument); this package binds it to SlamConfig.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

from crlam.slam.config import SlamConfig
from crlam.slam.preset_files import (
    DEFAULT_PRESET,
    NOT_DEVIATIONS,
    PAPER_PRESET,
    ConfigFile,
    list_presets,
    load_config_file_of,
    load_preset_of,
    paper_settings_of,
    preset_description,
    preset_path,
    resolve_preset,
)

__all__ = [
    "DEFAULT_PRESET",
    "PAPER_PRESET",
    "NOT_DEVIATIONS",
    "ConfigFile",
    "list_presets",
    "load_preset",
    "load_config_file",
    "paper_settings",
    "preset_description",
    "preset_path",
    "resolve",
]


def load_preset(name: str) -> dict[str, Any]:
    """The settings of preset ``name`` (field name -> value; tuples for arrays, None for unset).

    Raises :class:`ConfigError` naming the file and the key for an unknown preset, an unknown
    field, a value of the wrong type, or values SlamConfig rejects.
    """
    return load_preset_of(SlamConfig, name)


def paper_settings() -> dict[str, Any]:
    """Every SlamConfig field at the paper's value (the ``paper`` preset over SlamConfig's defaults)."""
    return paper_settings_of(SlamConfig)


def resolve(preset: str | None = DEFAULT_PRESET, overrides: dict[str, Any] | None = None) -> SlamConfig:
    """The SlamConfig of ``preset`` with ``overrides`` (field name -> value) on top.

    Fields neither names keep SlamConfig's defaults (the paper's). ``preset=None`` starts from those
    defaults alone. The result records the preset's name in ``SlamConfig.preset``.

    Raises
    ------
    ConfigError
        An unknown preset (naming the presets there are), an override that is not a SlamConfig
        field, or a value SlamConfig rejects (naming the field).
    """
    return resolve_preset(SlamConfig, preset, overrides)


def load_config_file(path: str | Path) -> ConfigFile:
    """Reads the ``[slam]`` settings (and ``[run] max_scans``, ``[input]``) of a run folder's ``config.toml``.

    ``preset`` names the preset the run started from; ``sigma_hit_resolved`` is derived and left
    out. Raises :class:`ConfigError` naming the file and the key for unknown keys or bad values.
    """
    return load_config_file_of(SlamConfig, path)
