"""MkDocs hooks of the crlam documentation site.

- The command-line reference (``cli.md``) is generated at build time from the argparse parser
  that ``crlam`` itself runs (``crlam.cli.build_parser``), so it cannot drift from the program:
  the page holds the marker ``<!-- crlam-cli-reference -->`` and this hook replaces it.
- The figures of the experiment folders under ``results/`` are published with the site as
  ``figures/<folder>/<name>.png`` (:func:`on_files`), so the results pages show the committed
  figures themselves rather than copies.
- Equations (``pymdownx.arithmatex``, generic mode) are turned into MathML when the site is
  built (:func:`on_page_content`, with ``latex2mathml``), so pages show them without loading a
  script from the network.
- The docstrings' Sphinx roles (``:class:`X```, ``:func:`~a.b```) are shown as plain code in
  the API reference (:func:`on_page_content`).
- The ROS 2 nodes' topic and parameter reference is generated the same way into the page that
  holds ``<!-- crlam-ros-reference -->`` (``tutorials/ros2.md``).
- Pages that other work adds later are listed in the navigation only when their file exists
  (:data:`OPTIONAL_PAGES`), so the site builds with ``--strict`` either way.
"""

from __future__ import annotations

import argparse
import html
import re
from pathlib import Path
from typing import Any

MARKER = "<!-- crlam-cli-reference -->"
#: Replaced by the ROS 2 nodes' topic and parameter reference (:func:`crlam.ros.reference.ros_reference`).
ROS_MARKER = "<!-- crlam-ros-reference -->"

OPTIONAL_PAGES = [
    # (section title, entry title, path under docs/, entry it follows)
    ("Tutorials", "Sweeps on a cluster (Dask)", "tutorials/cluster.md", "tutorials/sweep.md"),
]


def on_config(config: Any) -> Any:
    docs = Path(config["docs_dir"])
    for section, title, path, after in OPTIONAL_PAGES:
        if not (docs / path).is_file():
            continue
        for entry in config["nav"]:
            if isinstance(entry, dict) and section in entry:
                items = entry[section]
                index = next((i for i, it in enumerate(items) if after in it.values()), len(items) - 1)
                if not any(path in it.values() for it in items):
                    items.insert(index + 1, {title: path})
    return config


def on_files(files: Any, config: Any) -> Any:
    from mkdocs.structure.files import File

    root = Path(config["config_file_path"]).parent
    for png in sorted((root / "results").rglob("*.png")):
        rel = png.relative_to(root / "results").as_posix()
        files.append(File.generated(config, f"figures/{rel}", abs_src_path=str(png)))
    return files


def on_page_markdown(markdown: str, page: Any, config: Any, files: Any) -> str:
    if ROS_MARKER in markdown:
        from crlam.ros.reference import ros_reference

        return markdown.replace(ROS_MARKER, ros_reference())
    if page.file.src_uri != "cli.md" or MARKER not in markdown:
        return markdown
    from crlam.cli import build_parser

    parser = build_parser()
    return markdown.replace(MARKER, cli_reference(parser) + "\n" + renamed_options(parser))


_MATH = re.compile(r'<(span|div) class="arithmatex">\\[(\[](.*?)\\[)\]]</\1>', re.S)


_ROLE = re.compile(r":(?:class|func|meth|mod|data|attr|exc|obj|ref):(?=<code>)")


def on_page_content(content: str, page: Any, config: Any, files: Any) -> str:
    from latex2mathml.converter import convert

    def mathml(m: re.Match[str]) -> str:
        tex = html.unescape(m.group(2))
        return convert(tex, display="block" if m.group(1) == "div" else "inline")

    content = _ROLE.sub("", _MATH.sub(mathml, content))
    return content.replace("<code>~", "<code>")


def _cell(text: str) -> str:
    """Text for a Markdown table cell: one line, pipes escaped, HTML special characters kept as text."""
    return html.escape(" ".join(text.split()), quote=False).replace("|", "\\|")


def _subparsers(parser: argparse.ArgumentParser) -> argparse._SubParsersAction | None:  # type: ignore[type-arg]
    for action in parser._actions:
        if isinstance(action, argparse._SubParsersAction):
            return action
    return None


def _argument(parser: argparse.ArgumentParser, action: argparse.Action) -> tuple[str, str]:
    formatter = parser._get_formatter()
    if action.option_strings:
        names = ", ".join(action.option_strings)
        if action.nargs != 0:
            names += " " + formatter._format_args(action, action.dest.upper())
    else:
        names = formatter._format_args(action, action.dest)
    help_text = formatter._expand_help(action) if action.help else ""
    if action.choices is not None and not isinstance(action, argparse._SubParsersAction) and "{" not in names:
        help_text += f" (one of: {', '.join(map(str, action.choices))})"
    if action.required and action.option_strings:
        help_text = "required; " + help_text
    return f"`{names}`", _cell(help_text)


def cli_reference(parser: argparse.ArgumentParser, prog: str | None = None, level: int = 2) -> str:
    """Markdown for ``parser`` and every subcommand below it: usage, description and one table of
    arguments per argument group."""
    prog = prog or parser.prog
    out = [f"{'#' * level} `{prog}`", ""]
    if parser.description:
        out += [html.escape(parser.description, quote=False), ""]
    out += ["```text", parser.format_usage().strip().removeprefix("usage: "), "```", ""]
    for group in parser._action_groups:
        actions = [
            a
            for a in group._group_actions
            if not isinstance(a, (argparse._HelpAction, argparse._SubParsersAction)) and a.help != argparse.SUPPRESS
        ]
        if not actions:
            continue
        out += [f"**{(group.title or 'arguments').capitalize()}**", "", "| argument | meaning |", "|---|---|"]
        out += [f"| {name} | {text} |" for name, text in (_argument(parser, a) for a in actions)]
        out.append("")
    sub = _subparsers(parser)
    if sub is not None:
        helps = {a.dest: a.help for a in sub._choices_actions}
        out += ["| command | what it does |", "|---|---|"]
        out += [f"| `{prog} {name}` | {_cell(helps.get(name) or '')} |" for name in sub.choices]
        out.append("")
        for name, child in sub.choices.items():
            out.append(cli_reference(child, f"{prog} {name}", min(level + 1, 4)))
    return "\n".join(out)


def renamed_options(parser: argparse.ArgumentParser, prog: str | None = None) -> str:
    """Markdown table of the renamed flags: the old spellings (hidden from ``--help``, still read
    with a warning) and the names to use, per command."""
    rows: list[tuple[str, str, str]] = []

    def walk(p: argparse.ArgumentParser, name: str) -> None:
        for action in p._actions:
            target = getattr(action, "target", None)
            if action.help == argparse.SUPPRESS and target is not None:
                olds = action.option_strings or [f"{action.metavar or action.dest.upper()} (positional)"]
                rows.extend((name, old, max(target.option_strings, key=len)) for old in olds)
        sub = _subparsers(p)
        if sub is not None:
            for child_name, child in sub.choices.items():
                walk(child, f"{name} {child_name}")

    walk(parser, prog or parser.prog)
    if not rows:
        return ""
    out = [
        "## Renamed options",
        "",
        "These older spellings still work, with a one-line warning on standard error; use the new names.",
        "",
        "| command | old | new |",
        "|---|---|---|",
    ]
    out += [f"| `{cmd}` | `{old}` | `{new}` |" for cmd, old, new in rows]
    return "\n".join(out) + "\n"
