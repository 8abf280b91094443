"""The documentation site's generated parts: the command-line reference comes from the parser."""

from __future__ import annotations

import argparse
import importlib.util
from pathlib import Path

from crlam.cli import build_parser

ROOT = Path(__file__).resolve().parents[1]


def _hook():  # type: ignore[no-untyped-def]
    spec = importlib.util.spec_from_file_location("crlam_docs_hook", ROOT / "docs" / "hooks" / "crlam_docs.py")
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def _commands(parser: argparse.ArgumentParser, prog: str) -> list[tuple[str, argparse.ArgumentParser]]:
    out = [(prog, parser)]
    for action in parser._actions:
        if isinstance(action, argparse._SubParsersAction):
            for name, child in action.choices.items():
                out += _commands(child, f"{prog} {name}")
    return out


def test_the_cli_reference_documents_every_command_and_option() -> None:
    parser = build_parser()
    hook = _hook()
    text = hook.cli_reference(parser) + hook.renamed_options(parser)
    for prog, sub in _commands(parser, "crlam"):
        assert f"`{prog}`" in text, prog
        for action in sub._actions:
            if action.help == argparse.SUPPRESS:  # a renamed flag's old spelling: in the renames table only
                olds = action.option_strings or [f"{action.metavar} (positional)"]
                assert all(f"`{flag}`" in text for flag in olds), (prog, olds)
                continue
            for flag in action.option_strings:
                if flag not in ("-h", "--help"):
                    assert f"`{flag}" in text or f", {flag}" in text, (prog, flag)


def test_the_cli_page_holds_the_marker_the_hook_replaces() -> None:
    assert _hook().MARKER in (ROOT / "docs" / "cli.md").read_text()
