"""The preset files (``crlam/slam/presets/<name>.toml``) and run folders' ``config.toml`` read as the
fields of a settings dataclass.

Everything here takes that class as an argument (``config_class``: :class:`crlam.slam.SlamConfig`
in practice), so this module sits below the class it reads settings for: ``SlamConfig.from_preset``
and ``SlamConfig.deviations`` pass their own class, and :mod:`crlam.slam.presets` binds the functions
to SlamConfig for its users. The file format is described in :mod:`crlam.slam.presets`.
"""

from __future__ import annotations

import re
import types
import typing
from dataclasses import dataclass, field, fields
from functools import cache
from pathlib import Path
from typing import Any, TypeVar

from crlam.errors import ConfigError

__all__ = [
    "DEFAULT_PRESET",
    "PAPER_PRESET",
    "NOT_DEVIATIONS",
    "ConfigFile",
    "list_presets",
    "load_preset_of",
    "load_config_file_of",
    "paper_settings_of",
    "preset_description",
    "preset_path",
    "resolve_preset",
]

#: A settings dataclass (SlamConfig): keyword construction validates, a ``preset`` field names the
#: preset its values came from.
C = TypeVar("C")

#: The preset of ``crlam slam``, ``crlam experiment real-logs`` and ``SlamConfig.from_preset()``.
DEFAULT_PRESET = "robust"
#: The preset that is the paper's algorithm: the reference of ``SlamConfig.deviations()``.
PAPER_PRESET = "paper"
#: SlamConfig fields that do not change the filter (recorded estimates, the random draws) or only
#: name where the settings came from: never reported as deviations from the paper.
NOT_DEVIATIONS = frozenset({"seed", "mode_bandwidth", "smoothing_lag", "fill", "preset"})

#: The folder of the preset files (the crlam.slam.presets package, which ships them as package data).
_DIR = Path(__file__).resolve().parent / "presets"
_SECTION = re.compile(r"^\s*\[([^\]]+)\]\s*(#.*)?$")
_UNSET = re.compile(r"^\s*#\s*(\w+)\s*=\s*\(unset\)")
#: Keys of a run folder's ``[slam]`` table that are not SlamConfig fields: derived, not settings.
_DERIVED_KEYS = frozenset({"sigma_hit_resolved"})


def list_presets() -> list[str]:
    """Names of the presets shipped with crlam, sorted."""
    return sorted(p.stem for p in _DIR.glob("*.toml"))


def preset_path(name: str) -> Path:
    """The file of preset ``name``; :class:`ConfigError` naming the known presets if there is none."""
    path = _DIR / f"{name}.toml"
    if not (isinstance(name, str) and re.fullmatch(r"[A-Za-z0-9_-]+", name) and path.is_file()):
        raise ConfigError(f"unknown preset {name!r} (no {path}); known presets: {', '.join(list_presets())}")
    return path


def _parse(path: Path) -> tuple[dict[str, Any], dict[str, set[str]]]:
    """The TOML document of ``path`` and, per section, the names of its ``# name = (unset)`` lines."""
    from crlam.io.lines import read_small_text

    try:
        text = read_small_text(path, "config file")
    except OSError as e:
        raise ConfigError(f"{path}: cannot read ({e.strerror or e})") from e
    from crlam.io.structured import load_toml_text

    doc = load_toml_text(text, str(path), lambda message: ConfigError(f"{path}: {message}"))
    unset: dict[str, set[str]] = {}
    section = ""
    for line in text.splitlines():
        if m := _SECTION.match(line):
            section = m.group(1).strip()
        elif m := _UNSET.match(line):
            unset.setdefault(section, set()).add(m.group(1))
    return doc, unset


def _field_types(config_class: type) -> dict[str, Any]:
    return typing.get_type_hints(config_class)


def _coerce(value: Any, hint: Any, where: str) -> Any:
    """``value`` (as TOML gives it) converted to the settings field type ``hint``."""
    origin, args = typing.get_origin(hint), typing.get_args(hint)
    if origin in (typing.Union, types.UnionType):
        if value is None and type(None) in args:
            return None
        inner = [a for a in args if a is not type(None)]
        if len(inner) == 1:
            return _coerce(value, inner[0], where)
        # A choice of kinds (``match_range``: a name or a number): the one the value is.
        for kind in inner:
            if (kind is str) == isinstance(value, str):
                return _coerce(value, kind, where)
        raise ConfigError(f"{where}: expected one of {', '.join(k.__name__ for k in inner)}, got {value!r}")
    if value is None:
        raise ConfigError(f"{where}: may not be unset")
    if origin is tuple:
        if not isinstance(value, (list, tuple)):
            raise ConfigError(f"{where}: expected an array of numbers, got {value!r}")
        if not (len(args) == 2 and args[1] is Ellipsis) and len(value) != len(args):
            raise ConfigError(f"{where}: expected {len(args)} numbers, got {value!r}")
        return tuple(_coerce(v, float, where) for v in value)
    if hint is float:
        if isinstance(value, bool) or not isinstance(value, (int, float)):
            raise ConfigError(f"{where}: expected a number, got {value!r}")
        return float(value)
    if hint is int:
        if isinstance(value, bool) or not isinstance(value, int):
            raise ConfigError(f"{where}: expected an integer, got {value!r}")
        return value
    if hint is bool:
        if not isinstance(value, bool):
            raise ConfigError(f"{where}: expected true or false, got {value!r}")
        return value
    if hint is str:
        if not isinstance(value, str):
            raise ConfigError(f"{where}: expected a string, got {value!r}")
        return value
    raise ConfigError(f"{where}: cannot read a value of type {hint!r}")  # pragma: no cover - a new field type


def _settings(
    path: Path, doc: dict[str, Any], unset: dict[str, set[str]], ignore: frozenset[str], config_class: type
) -> dict[str, Any]:
    """The ``[slam]`` table of a parsed file as ``config_class`` field values (checked, converted)."""
    table = doc.get("slam")
    if not isinstance(table, dict):
        raise ConfigError(f"{path}: no [slam] table of settings")
    types_ = _field_types(config_class)
    name = config_class.__name__
    known = set(types_) - {"preset"}
    out: dict[str, Any] = {}
    for key, value in table.items():
        if key in ignore:
            continue
        if key not in known:
            raise ConfigError(f"{path}: unknown setting {key!r} in [slam] ({name} fields: {', '.join(sorted(known))})")
        out[key] = _coerce(value, types_[key], f"{path}: [slam] {key}")
    for key in sorted(unset.get("slam", set()) - ignore):
        if key not in known:
            raise ConfigError(f"{path}: unknown setting {key!r} in [slam] ({name} fields: {', '.join(sorted(known))})")
        if key in out:
            raise ConfigError(f"{path}: [slam] {key} is both set and '(unset)'")
        out[key] = _coerce(None, types_[key], f"{path}: [slam] {key}")
    return out


def _check(path: Path, settings: dict[str, Any], config_class: type) -> None:
    """Raise :class:`ConfigError` naming ``path`` when the settings do not make a valid ``config_class``."""
    try:
        config_class(**settings)
    except ConfigError as e:
        raise ConfigError(f"{path}: {e}") from e


@cache
def _load_preset(name: str, config_class: type) -> tuple[tuple[str, Any], ...]:
    path = preset_path(name)
    doc, unset = _parse(path)
    extra = set(doc) - {"preset", "slam"}
    if extra:
        raise ConfigError(f"{path}: unknown table(s) {sorted(extra)} (a preset has [preset] and [slam])")
    settings = _settings(path, doc, unset, ignore=frozenset(), config_class=config_class)
    _check(path, settings, config_class)
    return tuple(settings.items())


def load_preset_of(config_class: type, name: str) -> dict[str, Any]:
    """The settings of preset ``name`` (field name -> value; tuples for arrays, None for unset).

    Raises :class:`ConfigError` naming the file and the key for an unknown preset, an unknown
    field, a value of the wrong type, or values ``config_class`` rejects.
    """
    return dict(_load_preset(name, config_class))


def preset_description(name: str) -> str:
    """The one-line ``[preset] description`` of preset ``name`` ('' if it has none)."""
    doc, _ = _parse(preset_path(name))
    return str(doc.get("preset", {}).get("description", ""))


def paper_settings_of(config_class: type) -> dict[str, Any]:
    """Every ``config_class`` field at the paper's value (the ``paper`` preset over the class's defaults)."""
    defaults = config_class()
    return {f.name: getattr(defaults, f.name) for f in fields(config_class) if f.name != "preset"} | load_preset_of(
        config_class, PAPER_PRESET
    )


def resolve_preset(config_class: type[C], preset: str | None, overrides: dict[str, Any] | None = None) -> C:
    """The ``config_class`` instance of ``preset`` with ``overrides`` (field name -> value) on top.

    Fields neither names keep the class's defaults (the paper's). ``preset=None`` starts from those
    defaults alone. The result records the preset's name in its ``preset`` field.

    Raises
    ------
    ConfigError
        An unknown preset (naming the presets there are), an override that is not a field of the
        class, or a value the class rejects (naming the field).
    """
    name = config_class.__name__
    base = load_preset_of(config_class, preset) if preset is not None else {}
    overrides = dict(overrides or {})
    known = {f.name for f in fields(config_class)} - {"preset"}  # type: ignore[arg-type]  # C is a dataclass
    unknown = sorted(set(overrides) - known)
    if unknown:
        raise ConfigError(f"unknown {name} setting(s) {unknown} (fields: {', '.join(sorted(known))})")
    settings = base | overrides
    # The class may settle what a preset's value means under the overrides (a setting that only
    # applies to a value another override replaced).
    settle = getattr(config_class, "settle_preset_settings", None)
    if settle is not None:
        settings = settle(base, overrides)
    try:
        make: Any = config_class  # a dataclass with a ``preset`` field (C is unconstrained for mypy)
        return make(**settings, preset=preset)  # type: ignore[no-any-return]
    except ConfigError as e:
        where = f"preset {preset!r} ({preset_path(preset)})" if preset is not None else f"{name} defaults"
        raise ConfigError(f"{where} with overrides {overrides}: {e}") from e


@dataclass(frozen=True)
class ConfigFile:
    """The SLAM settings of a run folder's ``config.toml`` (or of any file with a ``[slam]`` table).

    Attributes
    ----------
    path : Path
    preset : str or None
        The preset the file's settings were resolved from (``[slam] preset``), None if it names none.
    settings : dict
        The ``[slam]`` fields the file sets (field name -> value), checked and converted.
    max_scans : int or None
        ``[run] max_scans`` of a run folder (None when unset or absent).
    input : dict
        The ``[input]`` table of a run folder as written (how the log was read: a bag's topics,
        frames and laser mount, the odometry used); empty when absent.
    """

    path: Path
    preset: str | None
    settings: dict[str, Any] = field(default_factory=dict)
    max_scans: int | None = None
    input: dict[str, Any] = field(default_factory=dict)


def load_config_file_of(config_class: type, path: str | Path) -> ConfigFile:
    """Reads the ``[slam]`` settings (and ``[run] max_scans``, ``[input]``) of a run folder's ``config.toml``.

    ``preset`` names the preset the run started from; ``sigma_hit_resolved`` is derived and left
    out. Raises :class:`ConfigError` naming the file and the key for unknown keys or bad values.
    """
    p = Path(path)
    if not p.is_file():
        raise ConfigError(f"{p}: no such config file")
    doc, unset = _parse(p)
    settings = _settings(p, doc, unset, ignore=_DERIVED_KEYS | {"preset"}, config_class=config_class)
    preset = doc.get("slam", {}).get("preset")
    if preset is not None:
        if not isinstance(preset, str):
            raise ConfigError(f"{p}: [slam] preset: expected a preset name, got {preset!r}")
        preset_path(preset)  # an unknown name is an error here, not a silent fallback
    max_scans = doc.get("run", {}).get("max_scans")
    if max_scans is not None and (isinstance(max_scans, bool) or not isinstance(max_scans, int) or max_scans < 1):
        raise ConfigError(f"{p}: [run] max_scans: expected an integer >= 1, got {max_scans!r}")
    _check(p, (load_preset_of(config_class, preset) if preset else {}) | settings, config_class)
    table = doc.get("input", {})
    if not isinstance(table, dict):
        raise ConfigError(f"{p}: [input] must be a table")
    return ConfigFile(p, preset, settings, max_scans, dict(table))
