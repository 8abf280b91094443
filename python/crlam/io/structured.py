"""YAML and TOML documents parsed with a bound on their nesting.

PyYAML and ``tomllib`` parse nested collections by recursion: a document nested a few thousand
levels deep (``[[[[...]]]]`` or a ladder of indented keys) exhausts Python's stack and raises
``RecursionError``, which is no parse error of theirs. Every YAML and TOML file crlam reads
(Nav2 map YAML, ``--config`` TOML, run folders' ``config.toml``, ROS 2 ``metadata.yaml``) goes
through these functions, which turn that into the caller's error naming the file, and refuse
documents nested deeper than :data:`MAX_NESTING` even when the parser copes (no crlam file
needs more than a handful of levels; deeper ones would only make later recursive code fail).
"""

from __future__ import annotations

import sys
from collections.abc import Callable
from typing import Any

from crlam.errors import CrlamError, DataFormatError

if sys.version_info >= (3, 11):
    import tomllib
else:  # pragma: no cover
    import tomli as tomllib

__all__ = ["MAX_NESTING", "load_toml_text", "load_yaml_text", "nesting_depth"]

#: Deepest nesting of lists and mappings a YAML or TOML document may have.
MAX_NESTING = 64

ErrorFactory = Callable[[str], CrlamError]


def nesting_depth(doc: Any, stop: int = MAX_NESTING + 1) -> int:
    """The nesting depth of a parsed document (a scalar is 0, ``[1]`` is 1), found without
    recursion; stops counting at ``stop``."""
    deepest = 0
    todo: list[tuple[Any, int]] = [(doc, 0)]
    while todo:
        node, depth = todo.pop()
        if isinstance(node, dict):
            children: Any = node.values()
        elif isinstance(node, (list, tuple)):
            children = node
        else:
            continue
        depth += 1
        deepest = max(deepest, depth)
        if deepest >= stop:
            return deepest
        todo.extend((c, depth) for c in children)
    return deepest


def _data_error(where: str) -> ErrorFactory:
    return lambda message: DataFormatError(message, path=where)


def _check_depth(doc: Any, error: ErrorFactory) -> Any:
    if nesting_depth(doc) > MAX_NESTING:
        raise error(f"nested more than {MAX_NESTING} levels deep (lists and mappings); no crlam file needs that")
    return doc


def load_yaml_text(text: str, where: str, error: ErrorFactory | None = None) -> Any:
    """The document of a YAML text (PyYAML's safe loader).

    Parameters
    ----------
    text : str
        The YAML text.
    where : str
        The file it came from, for the messages.
    error : callable, optional
        Makes the error raised from a message (default: :class:`DataFormatError` naming ``where``).

    Raises
    ------
    CrlamError
        From ``error``: invalid YAML (with its line), or a document nested too deep.
    """
    import yaml

    make = error or _data_error(where)
    try:
        doc = yaml.safe_load(text)
    except yaml.YAMLError as exc:
        mark = getattr(exc, "problem_mark", None)
        reason = " ".join(str(exc).split())[:300]
        if error is None:  # the line goes to the error's own field
            raise DataFormatError(f"invalid YAML ({reason})", path=where, line=None if mark is None else mark.line + 1) from exc
        raise make(f"invalid YAML{'' if mark is None else f' at line {mark.line + 1}'} ({reason})") from exc
    except RecursionError as exc:
        raise make(f"YAML nested too deep to parse (more than {MAX_NESTING} levels are refused)") from exc
    return _check_depth(doc, make)


def load_toml_text(text: str, where: str, error: ErrorFactory | None = None) -> dict[str, Any]:
    """The document of a TOML text (``tomllib``); see :func:`load_yaml_text` for the errors."""
    make = error or _data_error(where)
    try:
        doc = tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise make(f"not valid TOML ({exc})") from exc
    except RecursionError as exc:
        raise make(f"TOML nested too deep to parse (more than {MAX_NESTING} levels are refused)") from exc
    return dict(_check_depth(doc, make))
