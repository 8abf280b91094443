"""``crlam data``: the real datasets, where their local copies are, and their download."""

from __future__ import annotations

import argparse
import sys
import textwrap
from typing import Any

from crlam.cli.conventions import ListAction, add_output_options, group, print_settings
from crlam.errors import ConfigError

__all__ = ["add_parser", "cmd_data_fetch", "cmd_data_list"]

_WIDTH = 100


def cmd_data_list(args: argparse.Namespace) -> int:
    """Print every known dataset, whether a local copy exists and where."""
    from crlam.io.datasets import DATASETS, data_root
    from crlam.io.fetch import REMOTE, cache_dir, locate

    root = data_root()
    print(f"data folder: {root if root is not None else '(none: set CRLAM_DATA)'}")
    print(f"cache:       {cache_dir(args.cache)}\n")
    print(f"{'name':<24s} {'size':>9s}  {'status':<11s} path")
    for name in list(dict.fromkeys([*REMOTE, *DATASETS])):
        loc = locate(name, cache=args.cache)
        remote = REMOTE.get(name)
        size = f"{remote.size / 1e6:.2f} MB" if remote else "-"
        print(f"{name:<24s} {size:>9s}  {loc.source:<11s} {loc.path if loc.path is not None else '-'}")
        desc = remote.description if remote else DATASETS[name].description
        print(textwrap.fill(desc, width=_WIDTH, initial_indent=" " * 4, subsequent_indent=" " * 4))
        print(f"    source: {remote.url if remote else 'no public download (derived file)'}")
    return 0


def cmd_data_fetch(args: argparse.Namespace) -> int:
    """Download datasets into the cache, verifying their SHA-256."""
    from crlam.io.fetch import REMOTE, fetch, locate

    print_settings(args)
    names = list(REMOTE) if args.names == ["all"] else list(args.names)
    if args.url and len(names) != 1:
        raise ConfigError("--url needs exactly one dataset name")
    for name in names:
        loc = locate(name, cache=args.cache)
        if loc.source == "data folder" and not args.force:
            print(f"{name}: available in the data folder at {loc.path} (use --force to download it into the cache)")
            continue
        if args.verbose:
            remote = REMOTE.get(name)
            if remote is not None:
                print(f"{name}: {args.url or remote.url} ({remote.size:,} bytes, SHA-256 {remote.sha256})", file=sys.stderr)
        path = fetch(name, cache=args.cache, url=args.url, progress=not args.quiet, force=args.force)
        print(f"{name}: {path} (SHA-256 verified)")
    return 0


def add_parser(subparsers: Any) -> argparse.ArgumentParser:
    """Add ``data`` (``list``, ``fetch``) to ``subparsers``."""
    p: argparse.ArgumentParser = subparsers.add_parser(
        "data",
        help="list the real datasets and download them into a cache",
        description="The real 2D laser datasets (Freiburg SLAM-evaluation logs and relations, GMapping-corrected logs) "
        "are looked up in $CRLAM_DATA, then in the cache ($XDG_CACHE_HOME/crlam or ~/.cache/crlam). Every command that "
        "reads a log, a trajectory, relations or a map takes a dataset name in place of a path.",
    )
    sub = p.add_subparsers(dest="data_command", metavar="ACTION")
    sub.required = True
    q = sub.add_parser(
        "list",
        help="every dataset, whether a local copy exists and where",
        description="Every dataset, whether a local copy exists and where, its size and its source.",
    )
    group(q, "input").add_argument("--cache", help="cache folder (default: $XDG_CACHE_HOME/crlam or ~/.cache/crlam)")
    q.set_defaults(func=cmd_data_list)
    q = sub.add_parser(
        "fetch",
        help="download datasets into the cache (SHA-256 verified, atomic)",
        description="Downloads datasets into the cache, with a progress bar per file, and verifies their SHA-256.",
    )
    inp = group(q, "input")
    inp.add_argument("names", action=ListAction, metavar="NAME", help="dataset names (see crlam data list), or all")
    inp.add_argument("--url", help="download from this URL instead (mirror or file:// copy); the checksum is still verified")
    out = add_output_options(q, out=None, replace=None)
    out.add_argument("--cache", help="cache folder (default: $XDG_CACHE_HOME/crlam or ~/.cache/crlam)")
    out.add_argument("--force", action="store_true", help="download even if a local copy exists")
    q.set_defaults(func=cmd_data_fetch)
    return p
