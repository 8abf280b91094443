"""The conventions every ``crlam`` command follows, in one place.

- **Groups**: every argument sits in a named group (``input``, ``output``, ``run control``, ...),
  so ``--help`` reads as sections; :func:`group` makes them.
- **Output**: ``-o/--out`` where a command writes something, ``--force`` (or ``--resume``) to
  replace (or continue) an existing output, ``-q/--quiet`` and ``-v/--verbose`` wherever there
  is progress output (:func:`add_output_options`).
- **Lists**: space-separated (``--functions crmi ucrmi``); the older comma form
  (``--functions crmi,ucrmi``) is still read, with a deprecation warning (:class:`ListAction`).
- **Renamed flags** keep their old spelling as a hidden alias that warns on stderr
  (:func:`deprecated_alias`).
- **Inputs**: a path that exists wins; else a dataset name of ``crlam data list`` resolves to
  its local copy (data folder, then cache); ``-`` reads standard input into a temporary file
  (:func:`input_file`, :func:`resolve_inputs`).
"""

from __future__ import annotations

import argparse
import atexit
import dataclasses
import functools
import os
import shutil
import sys
import tempfile
from collections.abc import Callable, Iterable
from pathlib import Path
from typing import Any, cast

__all__ = [
    "InputArg",
    "ListAction",
    "add_output_options",
    "check_file_output",
    "deprecated_alias",
    "group",
    "input_file",
    "list_choices",
    "map_file",
    "print_settings",
    "resolve_inputs",
    "say",
    "warn",
    "world_arg",
]


def warn(message: str) -> None:
    """One line on stderr: ``crlam: warning: MESSAGE``."""
    print(f"crlam: warning: {message}", file=sys.stderr)


def group(parser: argparse.ArgumentParser, title: str, description: str | None = None) -> argparse._ArgumentGroup:
    """The parser's argument group ``title``, made on first use (so two helpers share a section)."""
    for g in parser._action_groups:
        if g.title == title:
            return g
    return parser.add_argument_group(title, description)


def add_output_options(
    parser: argparse.ArgumentParser,
    *,
    out: str | None = "output folder",
    required: bool = True,
    default: str | None = None,
    replace: str | None = "force",
    progress: bool = True,
) -> argparse._ArgumentGroup:
    """The ``output`` group: ``-o/--out`` (help ``out``; none if ``out`` is None), ``--force``
    (``replace="force"``) or ``--resume``/``--force`` (``replace="resume"``), and ``-q/--quiet``
    with ``-v/--verbose`` (``progress``). Returns the group for the command's own output flags."""
    g = group(parser, "output")
    if out is not None:
        text = out if default is None else f"{out} (default: {default})"
        g.add_argument("-o", "--out", required=required and default is None, default=default, metavar="PATH", help=text)
    if replace == "force":
        g.add_argument(
            "--force",
            action="store_true",
            help="replace an existing output; the old one stays untouched until the new one is complete",
        )
    elif replace == "resume":
        both = g.add_mutually_exclusive_group()
        both.add_argument(
            "--resume",
            action="store_true",
            help="continue the experiment folder: finished runs are kept when it was made with the same settings (else "
            "an error lists the differences); unreadable runs are done again",
        )
        both.add_argument("--force", action="store_true", help="empty an existing experiment folder and start anew")
    if progress:
        loud = g.add_mutually_exclusive_group()
        loud.add_argument("-q", "--quiet", action="store_true", help="no progress bars or progress messages")
        loud.add_argument(
            "-v", "--verbose", action="store_true", help="more detail: the settings in force and per-step messages (stderr)"
        )
    return g


def check_file_output(args: argparse.Namespace) -> Path | None:
    """The up-front check of a command whose ``-o/--out`` is one file (a JSON summary): None
    without ``--out``; an existing file is refused unless ``--force``, an existing folder always."""
    if not args.out:
        return None
    from crlam.errors import ConfigError
    from crlam.io.run_folder import check_output

    if Path(args.out).is_dir():
        raise ConfigError(f"output {args.out} is a folder; -o/--out takes the name of a file")
    return check_output(args.out, force=args.force, what="output")


def say(args: argparse.Namespace, *lines: str) -> None:
    """Informational lines on stdout, unless ``--quiet``."""
    if not getattr(args, "quiet", False):
        for line in lines:
            print(line, flush=True)


def _plain(value: Any) -> Any:
    if dataclasses.is_dataclass(value) and not isinstance(value, type):
        return {f.name: _plain(getattr(value, f.name)) for f in dataclasses.fields(value)}
    if isinstance(value, (list, tuple)):
        return [_plain(v) for v in value]
    if isinstance(value, Path):
        return str(value)
    return value


def print_settings(args: argparse.Namespace, **resolved: Any) -> None:
    """With ``--verbose``: the command's arguments and the resolved settings (dataclasses are
    listed field by field) on stderr, one ``name = value`` per line."""
    if not getattr(args, "verbose", False):
        return
    command = " ".join(str(getattr(args, k)) for k in ("command", "experiment", "diagnostic", "data_command") if hasattr(args, k))
    print(f"crlam {command}: arguments", file=sys.stderr)
    for key, value in sorted(vars(args).items()):
        if key == "func" or key.startswith("limit_") and value is None:
            continue
        print(f"  {key} = {_plain(value)!r}", file=sys.stderr)
    for title, value in resolved.items():
        print(f"crlam {command}: {title.replace('_', ' ')}", file=sys.stderr)
        plain = _plain(value)
        items = plain.items() if isinstance(plain, dict) else [("value", plain)]
        for key, v in items:
            print(f"  {key} = {v!r}", file=sys.stderr)


# --- renamed flags ------------------------------------------------------------------------------


class _DeprecatedAlias(argparse.Action):
    """A hidden old spelling of ``target``: warns, then does what ``target`` does."""

    def __init__(self, option_strings: list[str], dest: str, *, target: argparse.Action, **kwargs: Any) -> None:
        super().__init__(
            option_strings,
            dest=target.dest,
            nargs=target.nargs,
            const=target.const,
            type=cast(Any, target.type),  # a callable; typeshed also allows registry names
            choices=target.choices,
            metavar=target.metavar,
            default=argparse.SUPPRESS,
            help=argparse.SUPPRESS,
        )
        self.target = target

    def __call__(
        self, parser: argparse.ArgumentParser, namespace: argparse.Namespace, values: Any, option_string: Any = None
    ) -> None:
        new = max(self.target.option_strings, key=len)
        warn(f"{option_string} is deprecated; use {new}")
        self.target(parser, namespace, values, new)


def deprecated_alias(parser: argparse.ArgumentParser, old: str, new: str) -> None:
    """Keep ``old`` as a hidden spelling of the option ``new`` (already added to ``parser``): it
    parses to the same destination, is left out of ``--help`` and warns on stderr."""
    target = next(a for a in parser._actions if new in a.option_strings)
    parser.add_argument(old, action=_DeprecatedAlias, target=target)


# --- lists --------------------------------------------------------------------------------------


class _ListChoices(tuple):  # type: ignore[type-arg]
    """The choices of a list option: iterates as the names (for help), and holds a list of them."""

    def __contains__(self, value: object) -> bool:
        items = value if isinstance(value, list) else [value]
        return all(tuple.__contains__(self, v) for v in items)


def list_choices(names: Iterable[str]) -> tuple[str, ...]:
    """Choices for a :class:`ListAction` option."""
    return _ListChoices(names)


def _split_items(item_type: Callable[[str], Any], text: str) -> list[Any]:
    """The items of one word of a list option: the word itself, or the items of the older comma
    form, whose empty items are dropped as they always were (``--functions ,`` is no function)."""
    parts = [p.strip() for p in text.split(",") if p.strip()] if "," in text else [text]
    return [item_type(p) for p in parts]


class ListAction(argparse.Action):
    """A space-separated list (``nargs="+"``); an item holding commas (the older form) is split,
    with a deprecation warning. ``type`` converts each item."""

    def __init__(self, option_strings: list[str], dest: str, *, type: Callable[[str], Any] = str, **kwargs: Any) -> None:
        kwargs.setdefault("nargs", "+")
        super().__init__(option_strings, dest, type=functools.partial(_split_items, type), **kwargs)

    def __call__(
        self, parser: argparse.ArgumentParser, namespace: argparse.Namespace, values: Any, option_string: Any = None
    ) -> None:
        groups: list[list[Any]] = list(values)
        if any(len(g) != 1 for g in groups):
            name = option_string or self.metavar or self.dest
            flat = " ".join(str(v) for g in groups for v in g)
            warn(f"comma-separated lists are deprecated; separate the items by spaces: {name} {flat}")
        setattr(namespace, self.dest, [v for g in groups for v in g])


# --- inputs -------------------------------------------------------------------------------------


class InputArg(str):
    """An input named on the command line, resolved by :func:`resolve_inputs` before the command
    runs: a path, a dataset name, or ``-`` for standard input (when ``stdin``)."""

    stdin: bool = True


class _MapArg(InputArg):
    stdin = False


def input_file(text: str) -> str:
    """argparse type of a file input: a path, a dataset name (``intel``, ``intel-relations``) or ``-``."""
    return InputArg(text)


def map_file(text: str) -> str:
    """argparse type of a map input: a path or a dataset name (``cave-map``); not standard input."""
    return _MapArg(text)


def _read_stdin(copied: list[str]) -> str:
    """Standard input in a temporary file (removed at exit); read once per command: a second ``-``
    of the same command line gets the same file (``copied``)."""
    if copied:
        return copied[0]
    folder = Path(tempfile.mkdtemp(prefix="crlam-stdin-"))
    atexit.register(shutil.rmtree, folder, True)
    path = folder / "stdin"
    with open(path, "wb") as fh:
        shutil.copyfileobj(sys.stdin.buffer, fh)
    if path.stat().st_size == 0:
        from crlam.errors import ConfigError

        raise ConfigError("'-' reads standard input, but standard input is empty")
    copied.append(str(path))
    return str(path)


def _known_datasets() -> list[str]:
    from crlam.io.datasets import DATASETS
    from crlam.io.fetch import REMOTE

    return list(dict.fromkeys([*REMOTE, *DATASETS]))


def resolve_input(text: str, *, stdin: bool = True, copied: list[str] | None = None) -> str:
    """A command-line input as a path: ``-`` is standard input (copied to a temporary file,
    removed at exit; compression is detected from the bytes); a path that exists is itself; a
    dataset name is its local copy (data folder, then cache).

    Raises
    ------
    DatasetNotFoundError
        For a known dataset without a local copy (the message says how to fetch it), and for a
        name that is neither a path nor a dataset (the message lists the datasets)."""
    from crlam.io.datasets import DatasetNotFoundError

    if text == "-" and stdin:
        return _read_stdin([] if copied is None else copied)
    if os.path.exists(text):
        return text
    known = _known_datasets()
    if text in known:
        from crlam.io.fetch import find_dataset

        return str(find_dataset(text))
    raise DatasetNotFoundError(
        f"{text}: no such file or folder, and not a dataset name (the datasets: {', '.join(known)}; see `crlam data list`)"
    )


def resolve_inputs(args: argparse.Namespace) -> None:
    """Replaces every :class:`InputArg` of ``args`` (or list of them) by its path."""
    copied: list[str] = []
    for key, value in vars(args).items():
        if isinstance(value, InputArg):
            setattr(args, key, resolve_input(str(value), stdin=value.stdin, copied=copied))
        elif isinstance(value, list) and any(isinstance(v, InputArg) for v in value):
            resolved = [resolve_input(str(v), stdin=v.stdin, copied=copied) if isinstance(v, InputArg) else v for v in value]
            setattr(args, key, resolved)


def world_arg(text: str) -> str:
    """argparse type of a world: a built-in name (``museum``, ``office``), else a map input."""
    from crlam.sim.worlds import WORLD_NAMES

    return text if text in WORLD_NAMES else _MapArg(text)
