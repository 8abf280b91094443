"""The ``crlam`` command line (also ``python -m crlam`` and ``python -m crlam.cli``).

One module per command (:data:`COMMANDS`): each has ``add_parser(subparsers)``, which registers
its subcommand (with ``func``, the function that runs it), and that function. The shared parts
are :mod:`crlam.cli.options` (argument types, SLAM flags, bag options, resource limits),
:mod:`crlam.cli.conventions` (groups, output flags, lists, renamed flags, inputs),
:mod:`crlam.cli.executor` and :mod:`crlam.cli.failures`. Commands import those, never each
other; this module imports the commands. Adding a command: write ``cli/NAME.py`` with
``add_parser`` and add its name to :data:`COMMANDS`.
"""

from __future__ import annotations

import argparse
import importlib
import os
import sys
from collections.abc import Sequence

from crlam import __version__
from crlam.cli.conventions import resolve_inputs
from crlam.cli.failures import EXPECTED_FAILURES, describe_failure
from crlam.cli.options import add_limit_options_everywhere, apply_limit_options
from crlam.cli.slam import slam_config_of

__all__ = ["COMMANDS", "build_parser", "main", "slam_config_of"]

#: The command modules under ``crlam.cli``, in the order ``crlam --help`` lists them.
COMMANDS = (
    "demo",
    "simulate",
    "semireal",
    "map",
    "slam",
    "localize",
    "eval",
    "data",
    "info",
    "explore",
    "diagnose",
    "convert",
    "experiment",
    "bench",
    "ros",
)


def build_parser() -> argparse.ArgumentParser:
    """The ``crlam`` parser: every command of :data:`COMMANDS`, with the resource-limit flags on
    every leaf subcommand."""
    parser = argparse.ArgumentParser(
        prog="crlam",
        description="Confidence-rich localization and mapping: CRM, RBPF-CLAM and information functions.",
    )
    parser.add_argument("--version", action="version", version=f"crlam {__version__}")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND")
    sub.required = True
    for name in COMMANDS:
        importlib.import_module(f"crlam.cli.{name}").add_parser(sub)
    add_limit_options_everywhere(parser)
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    try:
        apply_limit_options(args)
        resolve_inputs(args)
        status = int(args.func(args))
        sys.stdout.flush()
        return status
    except BrokenPipeError:
        # The reader of our output went away (`crlam slam ... | head`): stop without a traceback,
        # with the status a process killed by SIGPIPE has, and keep Python's exit-time flush of
        # stdout from raising again.
        devnull = os.open(os.devnull, os.O_WRONLY)
        os.dup2(devnull, sys.stdout.fileno())
        return 141
    except EXPECTED_FAILURES as e:
        # Expected failures (bad input, a file system refusing, a limit, memory) are one line;
        # CRLAM_TRACEBACK=1 shows the traceback. Other exceptions are bugs and keep theirs.
        if os.environ.get("CRLAM_TRACEBACK"):
            raise
        print(f"crlam {args.command}: error: {describe_failure(e)}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print(f"crlam {args.command}: interrupted", file=sys.stderr)
        return 130


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
